"""The policy interface shared by baselines, SB3 zip policies and ONNX policies."""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np

from uavlink.env.core import GroundTruth
from uavlink.env.observation import ObservationLayout


@runtime_checkable
class Policy(Protocol):
    """Maps observations (N, obs) to actions (N, 2) in [-1, 1].

    ``layout`` is the observation layout the policy was built for (None: any layout is fine).
    Only the privileged baselines (oracle, kmeans, genie) set ``needs_truth`` and read ``truth``; the
    flight loop never supplies it.
    """

    name: str
    layout: ObservationLayout | None
    needs_truth: bool

    def act(self, obs: np.ndarray, truth: GroundTruth | None = None) -> np.ndarray: ...
