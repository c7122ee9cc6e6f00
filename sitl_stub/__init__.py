"""A lightweight PX4-style SITL vehicle with a radio payload.

Four packages, split as PX4 splits the same work, and the composition root here:

- ``core``: what every part reads or fills: parameters, the ``VehicleState`` snapshot, flight modes,
  the stored plans (mission, fence, rally), the global origin (PX4's uORB topics, lib/parameters,
  dataman). Imports nothing else of ``sitl_stub``; of uavlink only ``uavlink.mavlink`` (frames, modes).
- ``flight``: the autopilot without MAVLink: the vehicle (commander), its navigator modes, position
  control, offboard, RTL, geofence and its failsafe, failures. Imports only ``core`` (and
  ``uavlink.config``).
- ``sim``: the world around the vehicle: clock, battery, the payload hook and the radio payload (PX4's
  simulation/). Imports only ``core`` (and uavlink's config, env and mavlink codec for the radio world).
- ``mavlink``: the vehicle's MAVLink side: server, links, message handler, commands, setpoints, the
  mission, parameter and FTP protocols, streams and telemetry (PX4's src/modules/mavlink). May import
  ``core``, ``flight`` and ``sim``; the only package here that speaks the dialect.
- this package's own modules: ``__main__`` (``python -m sitl_stub`` / ``sitl-stub``), ``fleet`` (D
  vehicles in one process around one radio world) and ``launcher`` (the vehicle as a child process, what
  ``uavlink fly`` starts; it imports neither package). They may import all four.

The allowed imports are checked by tests/test_layering.py.
"""
