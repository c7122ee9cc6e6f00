"""A trained SB3 PPO policy (zip) behind the Policy interface. Imports torch and SB3.

Decisions are SB3's deterministic action (the Gaussian mean clipped to the action box), computed in
float64 from the float32 weights (which widen exactly) and rounded to float32 at the end.
``uavlink export`` writes this same module to ONNX, so torch and onnxruntime return bit-identical
actions: in float32 their sums run in different orders and differ by ~1e-7, which a trained policy
magnifies over a 128-frame closed loop into a different trajectory in a few episodes; in float64 the
difference is ~1e-16 and vanishes in the final rounding. Against SB3's own float32 ``predict`` the
actions agree to ~1e-6. (SB3's ``predict`` itself cannot run in float64: its preprocessing casts
observations to float32.)

A policy trained with a privileged critic (``TrainConfig.critic``, uavlink/learn/privileged.py) is a
``PrivilegedCriticPolicy``: its SB3 input is the actor's observation plus columns only the training
env has, of which its actor reads the first ``layout.size`` alone. Here, as in its ONNX export, it
acts from the actor's observation through the actor's own modules, so nothing else is ever needed.
"""

from __future__ import annotations

import copy
import functools
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from uavlink.env.core import GroundTruth
from uavlink.env.observation import ObservationLayout
from uavlink.policies.manifest import PolicyFileError, read_zip_manifest


@functools.cache
def privileged_critic_policy() -> type:
    """SB3's ``ActorCriticPolicy`` with an actor that reads only the first ``actor_obs_size`` columns
    of its input (the actor's observation) and a critic that reads all of them (that plus the
    privileged columns): ``PrivilegedCriticPolicy``. Each has its own features extractor and MLP
    (``net_arch``'s pi and vf); the names of the weights are ``MlpPolicy``'s. Built on first use: it
    subclasses SB3's class, so defining it imports torch and SB3. A policy zip's pickled
    ``policy_class`` names it ``uavlink.policies.sb3_policy.PrivilegedCriticPolicy``, which this
    module's ``__getattr__`` answers with this same class."""
    from stable_baselines3.common.policies import ActorCriticPolicy
    from stable_baselines3.common.torch_layers import BaseFeaturesExtractor, MlpExtractor

    class ActorColumns(BaseFeaturesExtractor):
        """The actor's features: the first ``columns`` values of each (flat) input."""

        def __init__(self, observation_space: Any, columns: int) -> None:
            super().__init__(observation_space, columns)
            self.columns = columns

        def forward(self, observations: Any) -> Any:
            return observations.flatten(1)[:, : self.columns]

    class PrivilegedCriticPolicy(ActorCriticPolicy):
        def __init__(self, *args: Any, actor_obs_size: int, **kwargs: Any) -> None:
            self.actor_obs_size = int(actor_obs_size)
            super().__init__(*args, **{**kwargs, "share_features_extractor": False})

        def _build_mlp_extractor(self) -> None:
            # Called by SB3's _build once both extractors exist (flattening every column): the
            # actor's becomes the actor's columns, and each MLP gets its own input width.
            self.features_extractor = self.pi_features_extractor = ActorColumns(
                self.observation_space, self.actor_obs_size
            )
            arch = self.net_arch
            pi, vf = (
                (arch.get("pi", []), arch.get("vf", [])) if isinstance(arch, dict) else (arch, arch)
            )
            act, device = self.activation_fn, self.device
            self.mlp_extractor = MlpExtractor(self.actor_obs_size, {"pi": pi}, act, device)
            critic = MlpExtractor(self.features_dim, {"vf": vf}, act, device)
            self.mlp_extractor.value_net = critic.value_net
            self.mlp_extractor.latent_dim_vf = critic.latent_dim_vf

        def _get_constructor_parameters(self) -> dict[str, Any]:
            return {**super()._get_constructor_parameters(), "actor_obs_size": self.actor_obs_size}

    PrivilegedCriticPolicy.__qualname__ = "PrivilegedCriticPolicy"  # where pickle finds it
    return PrivilegedCriticPolicy


if not TYPE_CHECKING:  # a module attribute built on demand; type checkers see the factory only

    def __getattr__(name: str) -> Any:
        if name == "PrivilegedCriticPolicy":
            return privileged_critic_policy()
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def deterministic_actor(policy: Any):
    """A torch module: obs float32 (N, obs) -> SB3's deterministic action float32 (N, 2), computed in
    float64 on a copy of the actor (``policy`` is left as it is)."""
    import torch
    from gymnasium import spaces
    from stable_baselines3.common.distributions import (
        DiagGaussianDistribution,
        StateDependentNoiseDistribution,
    )
    from stable_baselines3.common.torch_layers import FlattenExtractor

    space = policy.action_space
    if (
        not isinstance(space, spaces.Box)
        or space.shape != (2,)
        or np.ptp(space.low)
        or np.ptp(space.high)
    ):
        raise PolicyFileError(
            f"action space {space} is not a Box(low, high, (2,)) with scalar bounds"
        )
    if (
        policy.squash_output
        # gSDE (a policy in training, uavlink/learn/held_exploration.py) has the same mean action
        or not isinstance(
            policy.action_dist, (DiagGaussianDistribution, StateDependentNoiseDistribution)
        )
        or not (
            isinstance(policy, privileged_critic_policy())
            or isinstance(policy.pi_features_extractor, FlattenExtractor)
        )
    ):
        raise PolicyFileError(
            "only PPO MlpPolicy (or its privileged critic's variant) with a diagonal Gaussian and "
            "squash_output=False is supported"
        )
    low, high = float(space.low[0]), float(space.high[0])

    class DeterministicActor(torch.nn.Module):
        def __init__(self) -> None:
            super().__init__()
            # SB3's features extractor flattens, a no-op on (N, obs): left out. (A privileged
            # critic's policy's actor takes the first layout.size columns: all of the actor's obs.)
            self.latent = copy.deepcopy(policy.mlp_extractor.policy_net).double()
            self.mean = copy.deepcopy(policy.action_net).double()

        def forward(self, obs: torch.Tensor) -> torch.Tensor:
            mean = self.mean(self.latent(obs.to(torch.float64)))
            return torch.clamp(mean, low, high).to(torch.float32)  # SB3: np.clip(action, low, high)

    return DeterministicActor().eval()


class _NoOptimizer:
    """Stands in for the policy's Adam when it is only run: building a torch optimizer imports
    torch._dynamo (``torch._disable_dynamo``), about 3 s of every ``fly`` and ``evaluate`` start."""

    def __init__(self, params: Any, **kwargs: Any) -> None:
        pass


class ActorPolicy:
    """An SB3 PPO policy's deterministic actor behind the Policy interface, as ``SB3Policy`` decides:
    also for a policy in memory (training's validation episodes, ``uavlink.learn.selection``). The
    actor is a copy, so later updates of ``sb3_policy`` do not reach it."""

    needs_truth = False

    def __init__(self, sb3_policy: Any, layout: ObservationLayout, name: str) -> None:
        import torch

        self._torch, self.layout, self.name = torch, layout, name
        self.actor = deterministic_actor(sb3_policy)

    def act(self, obs: np.ndarray, truth: GroundTruth | None = None) -> np.ndarray:
        """Actions (N, 2) float32 in the box for observations (N, obs); a single (obs,) is N=1.
        SB3's ``predict(obs, deterministic=True)`` in float64, without its per-call input checks."""
        obs = np.asarray(obs, dtype=np.float32).reshape(-1, self.layout.size)
        with self._torch.inference_mode():
            return self.actor(self._torch.as_tensor(obs)).numpy()


class SB3Policy(ActorPolicy):
    """A PPO ``MlpPolicy`` from a uavlink policy zip, acting as SB3's deterministic ``predict`` does.

    Loads only the policy network from the zip (SB3's ``load_from_zip_file``, no optimizer, no
    algorithm) plus the zip's ``uavlink_manifest.json``: the observation layout, action mapping and
    env config the policy was trained for. The manifest is required, because SB3's zip holds only
    the observation's size: without the layout nothing could check that an env (or a vehicle in
    flight) builds the same observation, so a plain SB3 ``model.save()`` zip is refused with
    "zip has no uavlink_manifest.json". A zip with a manifest comes from ``uavlink train`` or
    ``uavlink.learn.training.train(cfg, tc, out)``; ``uavlink.policies.contract.load_with_env``
    loads one together with the env it was trained in. Raises ``PolicyFileError`` for a missing,
    foreign or damaged file.
    """

    def __init__(self, path: str | Path) -> None:
        path = Path(path)
        self.path = path
        self.manifest = read_zip_manifest(path)
        layout = ObservationLayout.from_dict(self.manifest["observation_layout"])
        import torch
        from stable_baselines3.common.save_util import load_from_zip_file

        # One thread: a 3 x 128 MLP on one observation gains nothing from more, and in flight the
        # loop shares the CPU with the vehicle (and, in SITL, the simulator).
        torch.set_num_threads(1)

        # SB3's own reader and policy class with the saved settings, as PPO.load builds them, but
        # without the algorithm around the policy and its optimizer, which running it never needs.
        try:
            data, params, _ = load_from_zip_file(path, device="cpu")
            if data is None:  # SB3 returns None for a zip without its "data" entry
                raise KeyError("data")
            kwargs = {**data["policy_kwargs"], "optimizer_class": _NoOptimizer}
            policy = data["policy_class"](
                data["observation_space"],
                data["action_space"],
                lambda _: 0.0,
                use_sde=data["use_sde"],
                **kwargs,
            )
            policy.load_state_dict(params["policy"])
        except Exception as exc:  # SB3 raises many kinds on a damaged archive
            raise PolicyFileError(
                f"{path}: cannot load the SB3 model ({type(exc).__name__}: {exc})"
            ) from None
        # A privileged critic's policy reads more than the actor's observation; its actor reads that.
        actor_input = (getattr(policy, "actor_obs_size", data["observation_space"].shape[0]),)
        if actor_input != (layout.size,):
            raise PolicyFileError(
                f"{path}: model input {actor_input} does not "
                f"match its manifest's layout {layout.describe()}"
            )
        try:
            super().__init__(policy, layout, path.stem)
        except PolicyFileError as exc:
            raise PolicyFileError(f"{path}: {exc}") from None

    @functools.cached_property
    def model(self) -> Any:
        """The whole SB3 PPO model (``PPO.load``), for comparing with SB3's own ``predict``."""
        from stable_baselines3 import PPO

        return PPO.load(self.path, device="cpu")
