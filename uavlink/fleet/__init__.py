"""A fleet of D UAV base stations as a multi-agent env (SPEC "A fleet").

``parallel_env(scenario=..., n_uavs=..., **overrides)`` gives a PettingZoo ``ParallelEnv`` with
agents ``uav_0`` ... ``uav_{D-1}`` over the batched core. PettingZoo is an optional dependency
(``pip install 'uavlink[fleet]'``): it is imported only when ``parallel_env`` is called or
``uavlink.fleet.parallel`` is imported, so ``import uavlink.fleet`` stays light.

May import: ``config``, ``errors``, ``env``.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from uavlink.errors import require

if TYPE_CHECKING:
    from uavlink.config import EnvConfig
    from uavlink.fleet.parallel import FleetParallelEnv

__all__ = ["FleetParallelEnv", "parallel_env"]


def _parallel_module() -> Any:
    require("pettingzoo")  # else a UserError with its install line
    return importlib.import_module("uavlink.fleet.parallel")


def parallel_env(
    scenario: str | None = None,
    n_uavs: int | None = None,
    config: EnvConfig | None = None,
    **overrides: Any,
) -> FleetParallelEnv:
    """The fleet as a PettingZoo ``ParallelEnv`` (defaults: ``circular``, 2 UAVs; see
    :class:`uavlink.fleet.parallel.FleetParallelEnv`)."""
    return _parallel_module().FleetParallelEnv(scenario, n_uavs, config=config, **overrides)


def __getattr__(name: str) -> Any:
    if name == "FleetParallelEnv":
        return _parallel_module().FleetParallelEnv
    raise AttributeError(f"module 'uavlink.fleet' has no attribute {name!r}")
