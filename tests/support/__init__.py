"""What tests share: the CLI helpers (``cli``), a MAVLink ground station (``mavlink_gcs``), a UDP
relay with faults (``udp_relay``) and flights through it (``relay_flight``), MAVSDK apps
(``mavsdk_apps``), a MAVProxy console (``mavproxy_console``), a hovering SITL (``sitl_hover``) and
MAVLink fuzzing strategies (``mavlink_fuzz``). Imported as ``support.X`` (pytest puts tests/ on the
path; benchmarks that use them put it there themselves)."""
