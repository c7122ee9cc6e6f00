"""The baselines by name: one UAV's rules (``uavlink.policies.baselines``) and a fleet's
(``uavlink.policies.fleet_baselines``). This module imports both families so that neither imports the
other's; callers that pick a baseline by name (the CLI, the loader, the teachers, the reports) import
it from here or from ``uavlink.policies``."""

from __future__ import annotations

from functools import cache

from uavlink.config import BASELINE_NAMES, EnvConfig
from uavlink.errors import UserError
from uavlink.policies.baselines import AoaPolicy, OraclePolicy, StaticPolicy
from uavlink.policies.explore import ExplorePolicy, explore_env
from uavlink.policies.fleet_baselines import FleetAoaPolicy, FleetOraclePolicy, KMeansPolicy
from uavlink.policies.genie import REFERENCES, GeniePolicy
from uavlink.policies.kriging import KrigingPolicy, kriging_env

# The warm start's teachers are declared in config; the genie is for evaluation only (it plans on the
# episode's future: uavlink.policies.genie), so no policy learns from it by accident.
BASELINES = (*BASELINE_NAMES, "genie")


def baseline_env(name: str, cfg: EnvConfig) -> EnvConfig:
    """The env the baseline ``name`` flies in ``cfg``'s world: ``cfg``, except that ``explore``
    gets a memory of place when ``cfg`` has none (``uavlink.policies.explore.explore_env``),
    ``kriging`` the model of the field (``uavlink.policies.kriging.kriging_env``), and the
    genie moves at once: its plan is over instant moves of up to r_max, which every path PX4's
    position loop flies (``uav_motion="px4"``) also keeps to, so on the same episodes it still bounds them."""
    if name == "genie":
        return cfg.replace(uav_motion="instant").validate()
    if name == "kriging":
        return kriging_env(cfg)
    return explore_env(cfg) if name == "explore" else cfg


def make_baseline(name: str, cfg: EnvConfig):
    """The baseline ``name`` for ``cfg``: a fleet (``n_uavs`` > 1) gets the fleet versions of the
    rules (``uavlink.policies.fleet_baselines``); ``static`` hovers every UAV at its start;
    ``genie`` plans on the episode's future, for any D, a fleet from the best of its references;
    ``explore`` is built for ``baseline_env(name, cfg)``, and flies in that env."""
    fleet = cfg.n_uavs > 1
    if name == "explore":
        return ExplorePolicy(baseline_env(name, cfg))
    if name == "kriging":
        return KrigingPolicy(baseline_env(name, cfg))
    if name == "static":
        return StaticPolicy(cfg)
    if name == "aoa":
        return FleetAoaPolicy(cfg) if fleet else AoaPolicy(cfg)
    if name == "oracle":
        return FleetOraclePolicy(cfg) if fleet else OraclePolicy(cfg)
    if name == "kmeans":
        return KMeansPolicy(cfg)
    if name == "genie":
        cfg = baseline_env(name, cfg)
        return GeniePolicy(cfg, [make_baseline(reference, cfg) for reference in REFERENCES])
    raise UserError(f"unknown baseline {name!r}; choose from {', '.join(BASELINES)}")


@cache
def flying_baselines() -> tuple[str, ...]:
    """The baselines ``uavlink fly`` can fly: those that read nothing but the observation. Asked of
    the policies themselves (``needs_truth``, what ``fly`` refuses on), so the list in its help and
    its refusals cannot drift from what flies."""
    cfg = EnvConfig()
    return tuple(name for name in BASELINES if not make_baseline(name, cfg).needs_truth)
