"""A training stopped as a killed process stops it: at a rollout's start, by KeyboardInterrupt."""

from __future__ import annotations

from typing import Any


def stopping_at(rollout: int) -> Any:
    """An SB3 callback that raises KeyboardInterrupt when rollout ``rollout`` (1-based) starts."""
    from stable_baselines3.common.callbacks import BaseCallback

    class Stop(BaseCallback):
        def __init__(self) -> None:
            super().__init__()
            self.started = 0

        def _on_rollout_start(self) -> None:
            self.started += 1
            if self.started == rollout:
                raise KeyboardInterrupt

        def _on_step(self) -> bool:
            return True

    return Stop()


def cut_training(cfg: Any, tc: Any, out: Any, snapshot: Any, rollout: int, **train_kwargs) -> None:
    """``train`` with a snapshot at every rollout's start, stopped when rollout ``rollout`` starts
    (as a killed process would be): the snapshot of the rollout before it is left."""
    import pytest

    from uavlink.learn.training import train

    with pytest.raises(KeyboardInterrupt, match="the same command again"):
        train(
            cfg,
            tc,
            out,
            progress=False,
            snapshot=snapshot,
            snapshot_every_s=0.0,
            callbacks=[stopping_at(rollout)],
            **train_kwargs,
        )
