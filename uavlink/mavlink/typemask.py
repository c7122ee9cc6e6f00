"""SET_POSITION_TARGET_*'s type mask (MAVLink common.xml, POSITION_TARGET_TYPEMASK): a set bit tells
the vehicle to ignore that field. Both ends read these: ``uavlink fly`` builds its position-only
setpoints with them and ``sitl_stub`` decodes what a ground station asks of it."""

from uavlink.mavlink.dialect import mavlink

_M = mavlink
IGNORE_POSITION = (
    _M.POSITION_TARGET_TYPEMASK_X_IGNORE,
    _M.POSITION_TARGET_TYPEMASK_Y_IGNORE,
    _M.POSITION_TARGET_TYPEMASK_Z_IGNORE,
)
IGNORE_VELOCITY = (
    _M.POSITION_TARGET_TYPEMASK_VX_IGNORE,
    _M.POSITION_TARGET_TYPEMASK_VY_IGNORE,
    _M.POSITION_TARGET_TYPEMASK_VZ_IGNORE,
)
IGNORE_ACCELERATION = (
    _M.POSITION_TARGET_TYPEMASK_AX_IGNORE,
    _M.POSITION_TARGET_TYPEMASK_AY_IGNORE,
    _M.POSITION_TARGET_TYPEMASK_AZ_IGNORE,
)
IGNORE_YAW = _M.POSITION_TARGET_TYPEMASK_YAW_IGNORE
IGNORE_YAW_RATE = _M.POSITION_TARGET_TYPEMASK_YAW_RATE_IGNORE
# a position setpoint and nothing else (0x0DF8): what `uavlink fly` sends each frame
POSITION_ONLY = sum(IGNORE_VELOCITY) | sum(IGNORE_ACCELERATION) | IGNORE_YAW | IGNORE_YAW_RATE
