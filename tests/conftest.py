"""The suite's settings and the tiny trained models, built once per test session.

Two lanes: ``pytest -m "not slow"`` runs the units in about a minute; plain ``pytest`` (``make
test``) adds every test marked ``slow`` (SITL, MAVSDK, MAVProxy, Dask, training, anything over
~1.5 s); the research scripts' tests are a lane of their own, research/tests/ (``make
research-test``). Helpers are plain functions in ``tests/support`` (``from support.cli import
run_uavlink``) so that a test reads as what it checks; the models are session fixtures so the whole
suite trains each of them once.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from hypothesis import settings
from support.cli import TINY_TRAINING

# Property tests check behaviour, not speed: hypothesis's 200 ms per-example deadline fails them on a
# loaded 2-core machine (a geofence example took 275 ms at load 19), so the suite has none.
settings.register_profile("uavlink", deadline=None)
settings.load_profile("uavlink")


@pytest.fixture(scope="session")
def tiny_policy_zip(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """PPO on `straight` for 96 episodes (12k env steps, default env): long enough to learn to follow
    the UEs. Shared by the whole session, so treat it as read-only (copy it before changing it)."""
    from uavlink.config import EnvConfig, TrainConfig
    from uavlink.learn.training import train

    out = tmp_path_factory.mktemp("tiny_policy") / "straight.zip"
    train(EnvConfig(scenario="straight"), TrainConfig(**TINY_TRAINING), out, None, progress=False)
    return out
