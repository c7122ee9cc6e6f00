"""The simulated world around the SITL vehicle (PX4's simulation/): ``clock`` (simulated time at a
speed factor), ``battery``, ``payload`` (the hook for extra MAVLink components ticked per frame) and
``radio_payload`` (the base station: uavlink's radio world as a payload component), ``radio_episodes``
(a fresh episode per flight), ``lockstep`` (a frame that waits for its decision), ``ue_truth``, and
``background`` (the vehicle's loop in a thread, for code that runs it in its own process).

May import: ``sitl_stub.core``; of uavlink ``config``, ``env`` (the radio world) and ``mavlink`` (the
radio codec).
"""
