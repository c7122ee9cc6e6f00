"""The simulated world around the SITL vehicle (PX4's simulation/): ``clock`` (simulated time at a
speed factor), ``battery``, ``payload`` (the hook for extra MAVLink components ticked per frame) and
``radio_payload`` (the base station: uavlink's radio world as a payload component).

May import: ``sitl_stub.core``; of uavlink ``config``, ``env`` (the radio world) and ``mavlink`` (the
radio codec).
"""
