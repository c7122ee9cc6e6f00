"""What tests share: the CLI helpers (``cli``), a MAVLink ground station (``mavlink_gcs``), a UDP
relay with faults (``udp_relay``) and flights through it (``relay_flight``), MAVSDK apps
(``mavsdk_apps``), a MAVProxy console (``mavproxy_console``), a hovering SITL (``sitl_hover``),
MAVLink fuzzing strategies (``mavlink_fuzz``) and a benchmark's or tool's main run in this process
(``scripts``). Imported as ``support.X`` (pytest puts tests/ on the path; research scripts that use
them put it there themselves)."""
