"""PettingZoo face of the batched core: one fleet episode, agents ``uav_0`` ... ``uav_{D-1}``.

A thin face over ``BatchedUavEnv(n_envs=1)``: agent ``uav_d`` is the core's agent row d, so its
observation is the per-UAV layout its config declares (``ObservationLayout.for_config``: v1 for
D = 1, v2 for a fleet of its size, v6 for any size with ``fleet_slots``) and one parameter-shared
policy serves every agent. Every agent gets the team reward (the normalised R_fair of all UEs); no
state is terminal; every agent is truncated at frame ``episode_frames`` and ``agents`` is emptied then,
as PettingZoo's Parallel API asks (https://pettingzoo.farama.org/api/parallel/ and pettingzoo
1.27's ``ParallelEnv`` and ``pettingzoo.test.parallel_api_test``). Seeding follows the
Gymnasium face (``uavlink.env.gym_env.UavBsEnv``): ``reset(seed=S)`` replays the same episode,
the first unseeded reset draws a seed, later ones continue the streams. With D = 1 the
observations equal ``UavBsEnv``'s for the same seed and actions.

Every live agent must act in every step: a missing (or unknown) agent is a ``UserError`` naming
it, not a silent hover, because a fleet policy that drops a UAV is a bug worth seeing. To hold a
UAV, send ``env.core.actions.from_polar(0.0, 0.0)`` (the zero vector with the default cartesian
mapping).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium import spaces
from pettingzoo import ParallelEnv

from uavlink.config import EnvConfig
from uavlink.env.core import BatchedUavEnv
from uavlink.env.gym_env import config_with
from uavlink.errors import UserError

AgentID = str
Infos = dict[AgentID, dict[str, Any]]


def agent_names(n_uavs: int) -> list[AgentID]:
    """The agents of a fleet of ``n_uavs``, in the core's row order: ``uav_0`` ... ``uav_{D-1}``."""
    return [f"uav_{d}" for d in range(n_uavs)]


def fleet_config(
    scenario: str | None = None,
    n_uavs: int | None = None,
    config: EnvConfig | None = None,
    **overrides: Any,
) -> EnvConfig:
    """The env's config: ``config`` (default: the SPEC defaults with ``circular`` and 2 UAVs) with
    ``scenario``, ``n_uavs`` and ``overrides`` (``radio.x`` or plain field names) applied."""
    base = config if config is not None else EnvConfig(n_uavs=2)
    return config_with(base, {"scenario": scenario, "n_uavs": n_uavs}, overrides)


class FleetParallelEnv(ParallelEnv[AgentID, np.ndarray, np.ndarray]):
    """D UAV base stations stepped together; spaces as the single-UAV env's, per agent.

    ``observation_space(agent)`` is the layout's float32 Box, ``action_space(agent)``
    Box(-1, 1, (2,)); ``infos`` after a step carry the frame's ``mean_rate_mbps`` and
    ``fair_rate``; ``state()`` is the agents' observations concatenated in agent order (what the
    fleet knows together, GPS-free), for centralised critics.
    """

    metadata = {"name": "uavlink_fleet_v0", "render_modes": []}

    def __init__(
        self,
        scenario: str | None = None,
        n_uavs: int | None = None,
        *,
        config: EnvConfig | None = None,
        render_mode: str | None = None,
        **overrides: Any,
    ) -> None:
        if render_mode is not None:
            raise UserError(
                f"render_mode {render_mode!r} is not supported; the fleet env renders nothing"
            )
        self.render_mode = None
        self.core = BatchedUavEnv(fleet_config(scenario, n_uavs, config, **overrides), n_envs=1)
        self.config = self.core.cfg
        self.layout = self.core.layout
        self.possible_agents = agent_names(self.core.n_uavs)
        self.agents: list[AgentID] = []
        low, high = self.layout.bounds()
        self.observation_spaces = {
            a: spaces.Box(low, high, dtype=np.float32) for a in self.possible_agents
        }
        self.action_spaces = {
            a: spaces.Box(-1.0, 1.0, (2,), np.float32) for a in self.possible_agents
        }
        n = len(self.possible_agents)
        self.state_space = spaces.Box(np.tile(low, n), np.tile(high, n), dtype=np.float32)
        self._observation: np.ndarray | None = None  # (D, obs), the core's rows
        self._seeded = False

    def observation_space(self, agent: AgentID) -> spaces.Box:
        return self.observation_spaces[self._known(agent)]

    def action_space(self, agent: AgentID) -> spaces.Box:
        return self.action_spaces[self._known(agent)]

    def _known(self, agent: AgentID) -> AgentID:
        if agent not in self.observation_spaces:
            raise UserError(f"no agent {agent!r}: this fleet's agents are {self.possible_agents}")
        return agent

    def reset(
        self, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[AgentID, np.ndarray], Infos]:
        """Start an episode (UAVs at their start positions); ``options`` are accepted and unused."""
        if seed is None and not self._seeded:
            seed = int(
                np.random.default_rng().integers(2**63 - 1)
            )  # unseeded: draw one, as Gymnasium does
        self._seeded = True
        self._observation = self.core.reset(seed)
        self.agents = list(self.possible_agents)
        return self._per_agent(self._observation), {agent: {} for agent in self.agents}

    def step(
        self, actions: dict[AgentID, Any]
    ) -> tuple[
        dict[AgentID, np.ndarray],
        dict[AgentID, float],
        dict[AgentID, bool],
        dict[AgentID, bool],
        Infos,
    ]:
        """Move every UAV by its action (one per live agent, each in [-1, 1]^2) and advance a frame."""
        if not self.agents:
            raise RuntimeError("no live agents: call reset() to start an episode")
        if not isinstance(actions, dict):
            raise UserError(
                f"actions must be a dict of agent -> action, e.g. {{{self.agents[0]!r}: "
                f"np.zeros(2)}}, got {type(actions).__name__}"
            )
        missing = [agent for agent in self.agents if agent not in actions]
        unknown = sorted(set(actions) - set(self.agents))
        if missing or unknown:
            raise UserError(f"every live agent must act: missing {missing}, unknown {unknown}")
        moves = [np.asarray(actions[agent], dtype=float) for agent in self.agents]
        wrong = [
            f"{a} {m.shape}" for a, m in zip(self.agents, moves, strict=True) if m.shape != (2,)
        ]
        if wrong:
            raise UserError(f"each agent's action has shape (2,): got {', '.join(wrong)}")
        result = self.core.step(np.stack(moves))
        self._observation = result.observation
        info = {
            "mean_rate_mbps": float(result.mean_rate_mbps[0]),
            "fair_rate": float(result.fair_rate[0]),
        }
        out = (
            self._per_agent(result.observation),
            {agent: float(result.reward[d]) for d, agent in enumerate(self.agents)},
            {agent: bool(result.terminated[d]) for d, agent in enumerate(self.agents)},
            {agent: bool(result.truncated[d]) for d, agent in enumerate(self.agents)},
            {agent: dict(info) for agent in self.agents},
        )
        if result.truncated.any() or result.terminated.any():
            self.agents = []
        return out

    def state(self) -> np.ndarray:
        """Every agent's observation, concatenated in agent order (float32, ``state_space``)."""
        if self._observation is None:
            raise RuntimeError("call reset() before state()")
        return self._observation.reshape(-1).copy()

    def render(self) -> None:
        """No render modes (``metadata["render_modes"]`` is empty)."""
        return None

    def close(self) -> None:
        """Nothing to release."""

    def _per_agent(self, observation: np.ndarray) -> dict[AgentID, np.ndarray]:
        return {agent: observation[d] for d, agent in enumerate(self.possible_agents)}
