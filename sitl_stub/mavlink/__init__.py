"""The SITL vehicle's MAVLink side (PX4's src/modules/mavlink): ``server`` (the endpoint and its loop),
``links`` (PX4 SITL's UDP port pairs), ``message_handler`` (what each received message does),
``commands`` and ``guided_commands`` (COMMAND_LONG/INT as the commander and navigator read them),
``setpoints`` (offboard type masks), ``mission_protocol``, ``param_protocol``, ``ftp``, ``streams``
(which message is due) and ``telemetry`` (messages built from the ``VehicleState`` snapshot).

May import: ``sitl_stub.core``, ``sitl_stub.flight``, ``sitl_stub.sim``; of uavlink ``config`` and
``mavlink`` (the dialect, signing, rejects, codecs).
"""
