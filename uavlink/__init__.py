"""uavlink: fly an aerial cellular base station with a learned PPO policy, over MAVLink.

Importing this package registers the Gymnasium env ``uavlink/UavBs-v0`` and nothing heavier:
torch, stable-baselines3, pymavlink, onnxruntime and matplotlib are imported only by the modules
that need them.
"""

from uavlink.config import AreaConfig, EnvConfig, RadioConfig
from uavlink.env.registration import ENV_ID, register_envs

__version__ = "0.1.0"
__all__ = ["ENV_ID", "AreaConfig", "EnvConfig", "RadioConfig", "__version__"]

register_envs()
