"""PX4's multicopter position loop (mc_pos_control) as ``sitl_stub`` flies it: the constants the SITL
vehicle (``sitl_stub.flight.pos_control``) and the env's PX4 motion (``uavlink.mobility.uav_motion``)
share, declared once, since a lockstep flight equals its evaluation only to the bit. The speed and
acceleration limits are the vehicle's parameters (MPC_XY_VEL_MAX, MPC_ACC_HOR_MAX): their defaults
here are the vehicle's parameter defaults and the env's."""

POS_GAIN_PER_S = 1.0  # MPC_XY_P / MPC_Z_P (PX4's defaults: 0.95 and 1)
BRAKE_FRACTION = 0.9  # braking curves use 90 % of the acceleration limit
MPC_XY_VEL_MAX_MPS = 12.0  # PX4's default maximum horizontal speed
MPC_ACC_HOR_MAX_MPS2 = 5.0  # PX4's default maximum horizontal acceleration
SUBSTEP_S = 0.02  # the vehicle's integration step: step(dt) subdivides dt into these
