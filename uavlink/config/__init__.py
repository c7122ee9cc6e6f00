"""Typed configuration, one dataclass per thing: the env (area, radio, learning problem) and the
training (PPO, budget, warm start). Imports nothing heavy and nothing from the layers above.

May import: ``errors``.
"""

from uavlink.config.env import (
    MIXED,
    SCENARIO_NAMES,
    SCENARIOS,
    SHADOWING_MODELS,
    AreaConfig,
    EnvConfig,
    RadioConfig,
    changed_settings,
    fleet_sizes_of,
    parse_settings,
)
from uavlink.config.fields import SEED_MAX, check_seed
from uavlink.config.train import (
    BASELINE_NAMES,
    CRITIC_ACTOR,
    CRITIC_PRIVILEGED,
    CRITICS,
    PAPER_HYPERPARAMETERS,
    TrainConfig,
    WarmStartConfig,
)

__all__ = [
    "BASELINE_NAMES",
    "CRITICS",
    "CRITIC_ACTOR",
    "CRITIC_PRIVILEGED",
    "MIXED",
    "PAPER_HYPERPARAMETERS",
    "SCENARIO_NAMES",
    "SCENARIOS",
    "SEED_MAX",
    "SHADOWING_MODELS",
    "AreaConfig",
    "EnvConfig",
    "RadioConfig",
    "TrainConfig",
    "WarmStartConfig",
    "changed_settings",
    "check_seed",
    "fleet_sizes_of",
    "parse_settings",
]
