"""What every part of the SITL vehicle reads or fills (PX4's uORB topics, lib/parameters, dataman):
``params`` (the parameter set and its encoding), ``vehicle_state`` (the immutable snapshot and request
outcomes), ``modes`` (flight modes, landed states), ``mission_store`` (mission, fence and rally lists),
``geo`` (the global origin).

May import: nothing else of ``sitl_stub``; of uavlink only ``uavlink.mavlink`` (frames, PX4 modes, geo)
and ``uavlink.config`` (the position loop's PX4 defaults, shared with the env).
"""
