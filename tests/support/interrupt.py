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
