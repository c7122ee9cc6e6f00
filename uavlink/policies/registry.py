"""The baselines by name: one UAV's rules (``uavlink.policies.baselines``) and a fleet's
(``uavlink.policies.fleet_baselines``). This module imports both families so that neither imports the
other's; callers that pick a baseline by name (the CLI, the loader, the teachers, the reports) import
it from here or from ``uavlink.policies``."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import cache

from uavlink.config import EnvConfig
from uavlink.config.env import MOTION_INSTANT
from uavlink.errors import UserError
from uavlink.policies.base import Policy
from uavlink.policies.baselines import AoaPolicy, OraclePolicy, StaticPolicy
from uavlink.policies.explore import ExplorePolicy, explore_env
from uavlink.policies.fleet_baselines import FleetAoaPolicy, FleetOraclePolicy, KMeansPolicy
from uavlink.policies.genie import REFERENCES, GeniePolicy
from uavlink.policies.kriging import KrigingPolicy, kriging_env


@dataclass(frozen=True)
class Baseline:
    """A baseline by name: the env it flies in a world's env (``env``; the world's own by default),
    and how it is built for that env (``build``)."""

    build: Callable[[EnvConfig], Policy]
    env: Callable[[EnvConfig], EnvConfig] = lambda cfg: cfg


def _genie(cfg: EnvConfig) -> Policy:
    """The genie plans on the episode's future, for any D, a fleet from the best of its references."""
    return GeniePolicy(cfg, [make_baseline(reference, cfg) for reference in REFERENCES])


def _instant(cfg: EnvConfig) -> EnvConfig:
    """The genie moves at once: its plan is over instant moves of up to r_max, which every path PX4's
    position loop flies (``uav_motion="px4"``) also keeps to, so on the same episodes it still bounds them."""
    return cfg.replace(uav_motion=MOTION_INSTANT).validate()


# Every baseline, in the order the CLI lists them: the warm start's teachers (config's BASELINE_NAMES,
# so that config can name them without importing policies), then the genie, for evaluation only (it
# plans on the episode's future), so no policy learns from it by accident. A fleet (n_uavs > 1) gets
# the fleet versions of the rules; static hovers every UAV at its start; explore gets a memory of
# place and kriging the model of the field when the world's env has none.
REGISTRY: dict[str, Baseline] = {
    "static": Baseline(StaticPolicy),
    "oracle": Baseline(lambda cfg: FleetOraclePolicy(cfg) if cfg.n_uavs > 1 else OraclePolicy(cfg)),
    "aoa": Baseline(lambda cfg: FleetAoaPolicy(cfg) if cfg.n_uavs > 1 else AoaPolicy(cfg)),
    "kmeans": Baseline(KMeansPolicy),
    "explore": Baseline(ExplorePolicy, explore_env),
    "kriging": Baseline(KrigingPolicy, kriging_env),
    "genie": Baseline(_genie, _instant),
}
BASELINES = tuple(REGISTRY)


def baseline_env(name: str, cfg: EnvConfig) -> EnvConfig:
    """The env the baseline ``name`` flies in ``cfg``'s world (``REGISTRY[name].env``)."""
    return REGISTRY[name].env(cfg) if name in REGISTRY else cfg


def make_baseline(name: str, cfg: EnvConfig) -> Policy:
    """The baseline ``name`` for ``cfg``'s world, built for the env it flies there (``baseline_env``)."""
    if name not in REGISTRY:
        raise UserError(f"unknown baseline {name!r}; choose from {', '.join(BASELINES)}")
    baseline = REGISTRY[name]
    return baseline.build(baseline.env(cfg))


@cache
def flying_baselines() -> tuple[str, ...]:
    """The baselines ``uavlink fly`` can fly: those that read nothing but the observation. Asked of
    the policies themselves (``needs_truth``, what ``fly`` refuses on), so the list in its help and
    its refusals cannot drift from what flies."""
    cfg = EnvConfig()
    return tuple(name for name in BASELINES if not make_baseline(name, cfg).needs_truth)
