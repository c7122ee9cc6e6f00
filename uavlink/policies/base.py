"""The policy interface shared by baselines, SB3 zip policies and ONNX policies, and the rules' base."""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any, Protocol, runtime_checkable

import numpy as np

from uavlink.env.core import GroundTruth
from uavlink.env.observation import ObservationLayout


@runtime_checkable
class Policy(Protocol):
    """Maps observations (N, obs) to actions (N, 2) in [-1, 1]; a single observation (obs,), as a
    Gymnasium env gives, is a batch of one: actions (1, 2).

    ``layout`` is the observation layout the policy was built for (None: any layout is fine).
    Only the privileged baselines (oracle, kmeans, genie) set ``needs_truth`` and read ``truth``; the
    flight loop never supplies it.
    """

    # Read-only: an implementation may declare a narrower type (``layout = None`` on a rule).
    @property
    def name(self) -> str: ...
    @property
    def layout(self) -> ObservationLayout | None: ...
    @property
    def needs_truth(self) -> bool: ...

    def act(self, obs: np.ndarray, truth: GroundTruth | None = None) -> np.ndarray: ...


class RulePolicy:
    """Base of the rule-based policies: each subclass's ``act`` takes a single observation (obs,) as
    a batch of one, returning (1, 2) as ``SB3Policy`` and ``OnnxPolicy`` do, so a rule's ``act``
    handles (N, obs) only. Subclasses' own subclasses (a teacher's variant of a rule) get it too."""

    act: Callable[..., np.ndarray]  # each subclass's own (declared here only for the type checker)

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        if "act" in cls.__dict__:
            cls.act = _one_as_batch(cls.__dict__["act"])


def _one_as_batch(act: Callable[..., np.ndarray]) -> Callable[..., np.ndarray]:
    @functools.wraps(act)
    def batched(self: Any, obs: np.ndarray, truth: GroundTruth | None = None) -> np.ndarray:
        if np.ndim(obs) == 1:
            obs = np.asarray(obs)[None]
        return act(self, obs, truth)

    return batched
