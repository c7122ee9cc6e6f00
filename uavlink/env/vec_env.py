"""Stable-Baselines3 ``VecEnv`` face of the batched core, for training.

Follows SB3's contract: on the last frame of an episode the env is reset automatically, the returned
observation is the new episode's first, and ``info["terminal_observation"]`` holds the last one,
with ``TimeLimit.truncated`` so PPO bootstraps the value of the cut-off state. ``info["episode"]``
carries the episode return and length (as SB3's Monitor would) plus the mean UE throughput.
A fleet of D UAVs flattens N episodes x D UAVs into N D rows (the core's agent rows), so one
parameter-shared policy acts for every UAV; each row's return is its env's team return.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from stable_baselines3.common.vec_env.base_vec_env import (
    VecEnv,
    VecEnvIndices,
    VecEnvStepReturn,
)

from uavlink.config import EnvConfig
from uavlink.env.core import BatchedUavEnv, GroundTruth
from uavlink.seeding import FLEET_SIZES


class UavVecEnv(VecEnv):
    """``n_envs`` episodes of ``cfg``'s world as one SB3 ``VecEnv`` of ``num_envs`` = N D agent rows.

    SB3's VecEnv is a list of separate envs; this one is a single batched core (``self.core``,
    :class:`~uavlink.env.core.BatchedUavEnv`) stepped as arrays, which is what makes training
    fast. Stepping, resetting and seeding act on the whole batch (the episodes have one length,
    so they start and end together). So do the per-env accessors: ``get_attr`` and ``env_method``
    answer one entry per index (SB3's ``indices``), each the whole batch's value (e.g. a
    ``GroundTruth`` of every env: row i of its per-row arrays is VecEnv index i, and env i // D's
    world), and ``set_attr`` sets a value for the whole batch, so it takes only indices that cover
    every row.
    """

    def __init__(
        self, cfg: EnvConfig, n_envs: int, seed: int | np.random.SeedSequence | None = None
    ) -> None:
        self.core = BatchedUavEnv(cfg, n_envs=n_envs, seed=seed)
        obs_space = gym.spaces.Box(*self.core.layout.bounds(), dtype=np.float32)
        act_space = gym.spaces.Box(-1.0, 1.0, (2,), np.float32)
        self.render_mode = None
        super().__init__(self.core.n_rows, obs_space, act_space)
        self._actions: np.ndarray | None = None
        self._next_seed: int | np.random.SeedSequence | None = seed
        self._start = time.time()
        self._returns = np.zeros(self.core.n_rows)
        self._rate_sums = np.zeros(n_envs)
        # The last frame's ground truth, kept at each episode's end before the batch resets: a
        # wrapper that widens the observations (uavlink/learn/privileged.py) widens
        # ``terminal_observation`` from it. Never part of an observation.
        self.terminal_truth: GroundTruth | None = None

    def reset(self) -> np.ndarray:
        """Restart every episode (with the seed ``seed()`` set, once); observations (N D, obs)."""
        obs = self.core.reset(self._next_seed)
        self._next_seed = None
        self._returns[:] = 0.0
        self._rate_sums[:] = 0.0
        return obs

    def step_async(self, actions: np.ndarray) -> None:
        """Keep the actions (N D, 2) for ``step_wait``: the batch steps synchronously."""
        self._actions = actions

    def step_wait(self) -> VecEnvStepReturn:
        """Step every row; at an episode's end, reset and report as the module docstring says."""
        assert self._actions is not None  # SB3's step() calls step_async() first
        result = self.core.step(self._actions)
        self._returns += result.reward
        self._rate_sums += result.mean_rate_mbps
        dones = result.truncated | result.terminated
        infos: list[dict[str, Any]] = [{} for _ in range(self.num_envs)]
        obs = result.observation
        if dones.any():  # fixed-length episodes: the whole batch ends together
            frames = self.core.frame
            self.terminal_truth = self.core.ground_truth()
            for i, info in enumerate(infos):
                info["terminal_observation"] = obs[i]
                info["TimeLimit.truncated"] = bool(result.truncated[i] and not result.terminated[i])
                info["episode"] = {
                    "r": float(self._returns[i]),
                    "l": frames,
                    "t": round(time.time() - self._start, 6),
                    "mean_rate_mbps": float(self._rate_sums[i // self.core.n_uavs] / frames),
                }
            obs = self.reset()
        return obs, result.reward.astype(np.float32), dones, infos

    def close(self) -> None:
        """Nothing to release: the batch holds no processes or files."""

    def seed(self, seed: int | np.random.SeedSequence | None = None) -> Sequence[Any]:
        """Seed the next ``reset`` of the whole batch (one seed; the core draws every env's streams
        from it), so every row reports the same ``seed``."""
        self._next_seed = seed
        return [seed] * self.num_envs

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        """The core's attribute (or this VecEnv's, e.g. ``render_mode``), the batch's value once
        per index (see the class docstring)."""
        owner = self.core if hasattr(self.core, attr_name) else self  # e.g. render_mode lives here
        return [getattr(owner, attr_name)] * self._count(indices)

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        """Set the core's attribute for the whole batch; ``indices`` must cover every row (one value
        is shared by all of them), else ValueError."""
        if set(self._get_indices(indices)) != set(range(self.num_envs)):
            raise ValueError(
                f"{attr_name!r} is one value for the whole batch of {self.num_envs} rows; "
                "set it for all of them (indices=None)"
            )
        setattr(self.core, attr_name, value)

    def env_method(
        self, method_name: str, *method_args, indices: VecEnvIndices = None, **method_kwargs
    ) -> list[Any]:
        """Call the core's method once, on the whole batch, and return its result once per index
        (see the class docstring); a method that changes state changes every env."""
        result = getattr(self.core, method_name)(*method_args, **method_kwargs)
        return [result] * self._count(indices)

    def _count(self, indices: VecEnvIndices) -> int:
        """How many entries ``indices`` names (SB3's ``_get_indices``: a range, a list or the
        given indices)."""
        return len(list(self._get_indices(indices)))

    def env_is_wrapped(
        self, wrapper_class: type[gym.Wrapper], indices: VecEnvIndices = None
    ) -> list[bool]:
        """False for every index: the batch is no gymnasium env, so no gymnasium wrapper (e.g. SB3's
        ``Monitor``, which is why SB3's ``VecMonitor`` and ``evaluate_policy`` ask) wraps it; the
        ``info["episode"]`` it would add is written by ``step_wait``."""
        return [False] * self._count(indices)


class FleetSizesVecEnv(VecEnv):
    """Several fleet sizes trained together: one ``UavVecEnv`` (or a wrapper of one) per size, their
    rows side by side (``parts[0]``'s first). An any-size layout (``EnvConfig.fleet_slots``) gives
    every size the same observation, so one parameter-shared policy learns them all in each rollout.
    The parts' episodes have one length and start together, so they end together."""

    @classmethod
    def for_sizes(
        cls, cfg: EnvConfig, sizes: Sequence[int], n_envs: int, seed: int | None = None
    ) -> FleetSizesVecEnv:
        """``n_envs`` episodes of each fleet size in ``sizes`` (``cfg`` with its n_uavs replaced)."""
        parts = [
            UavVecEnv(cfg.replace(n_uavs=size).validate(), n_envs, _size_seed(seed, k))
            for k, size in enumerate(sizes)
        ]
        return cls(parts)

    def __init__(self, parts: Sequence[VecEnv]) -> None:
        self.parts = list(parts)
        first = self.parts[0]
        if any(part.observation_space != first.observation_space for part in self.parts):
            raise ValueError("every fleet size must give the same observation (fleet_slots > 0)")
        self._edges = np.cumsum([0] + [part.num_envs for part in self.parts])
        self.render_mode = None
        super().__init__(int(self._edges[-1]), first.observation_space, first.action_space)

    def _split(self, rows: np.ndarray) -> list[np.ndarray]:
        return [rows[a:b] for a, b in zip(self._edges[:-1], self._edges[1:], strict=True)]

    def reset(self) -> np.ndarray:
        return np.concatenate([part.reset() for part in self.parts])

    def step_async(self, actions: np.ndarray) -> None:
        for part, rows in zip(self.parts, self._split(actions), strict=True):
            part.step_async(rows)

    def step_wait(self) -> VecEnvStepReturn:
        results = [part.step_wait() for part in self.parts]
        obs, rewards, dones, infos = zip(*results, strict=True)
        return (
            np.concatenate(obs),
            np.concatenate(rewards),
            np.concatenate(dones),
            [info for part in infos for info in part],
        )

    def close(self) -> None:
        for part in self.parts:
            part.close()

    def seed(self, seed: int | None = None) -> Sequence[Any]:
        """Seed every size's next reset, each from its own chunk of ``FLEET_SIZES``."""
        return [
            s
            for k, part in enumerate(self.parts)
            for s in part.seed(_size_seed(seed, k))  # type: ignore[arg-type]  # UavVecEnv's take one
        ]

    def _part_of(self, indices: VecEnvIndices) -> list[tuple[VecEnv, int]]:
        """(part, its own index) for each of ``indices``."""
        out = []
        for i in self._get_indices(indices):
            k = int(np.searchsorted(self._edges, i, side="right")) - 1
            out.append((self.parts[k], i - int(self._edges[k])))
        return out

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        return [part.get_attr(attr_name, [i])[0] for part, i in self._part_of(indices)]

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        if indices is not None:
            raise ValueError(f"{attr_name!r} is set for every fleet size at once (indices=None)")
        for part in self.parts:
            part.set_attr(attr_name, value)

    def env_method(
        self, method_name: str, *method_args, indices: VecEnvIndices = None, **method_kwargs
    ) -> list[Any]:
        return [
            part.env_method(method_name, *method_args, indices=[i], **method_kwargs)[0]
            for part, i in self._part_of(indices)
        ]

    def env_is_wrapped(
        self, wrapper_class: type[gym.Wrapper], indices: VecEnvIndices = None
    ) -> list[bool]:
        return [False] * len(list(self._get_indices(indices)))


def _size_seed(seed: int | None, k: int) -> np.random.SeedSequence | None:
    return None if seed is None else FLEET_SIZES.seed(seed, k)
