"""The SB3 VecEnv face (uavlink/env/vec_env.py): SB3's per-env accessors answer one entry per index,
each the whole batch's value, and set only what the whole batch shares."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

from uavlink.config import EnvConfig
from uavlink.env.vec_env import UavVecEnv


def test_accessors_answer_each_index_with_the_batchs_value():
    venv = UavVecEnv(EnvConfig(n_uavs=2), n_envs=3, seed=1)  # rows: env 0 = 0, 1; env 1 = 2, 3; ...
    venv.reset()
    truths = venv.env_method("ground_truth", indices=[3, 0])
    assert len(truths) == 2 and truths[0] is truths[1]
    np.testing.assert_array_equal(truths[0].uav_xy_m, venv.core.uav_xy_m)  # row i: VecEnv index i
    assert venv.get_attr("frame", [0, 5]) == [0, 0]
    assert venv.get_attr("render_mode") == [None] * 6
    assert venv.env_is_wrapped(gym.Wrapper, indices=[1, 2]) == [False, False]
    with pytest.raises(AttributeError):
        venv.get_attr("nope")


def test_set_attr_sets_only_what_the_whole_batch_shares():
    venv = UavVecEnv(EnvConfig(), n_envs=3, seed=1)
    venv.reset()
    with pytest.raises(ValueError, match="'frame' is one value for the whole batch of 3 rows"):
        venv.set_attr("frame", 7, indices=[0, 1])
    venv.set_attr("frame", 7)
    assert venv.core.frame == 7
    venv.set_attr("frame", 8, indices=range(3))
    assert venv.get_attr("frame", 0) == [8]
