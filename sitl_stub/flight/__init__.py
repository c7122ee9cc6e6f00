"""The SITL autopilot, no MAVLink and no sockets (PX4's commander, navigator and mc_pos_control):
``vehicle`` (arming, modes and the facade over the rest, stepped in simulated time),
``pos_control`` (position controller and plant), ``guidance`` (velocity, orbit and speed setpoints), ``offboard``, ``rtl``,
``mission_executor``, ``geofence`` (detection), ``failsafe`` (the reactions), ``land_detector``, ``failures``.

May import: ``sitl_stub.core``; of uavlink only ``uavlink.config``.
"""
