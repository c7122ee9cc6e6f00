"""What a training run shows and keeps as it goes (``uavlink.learn.training.train``'s monitor).

Its progress (tqdm's bar on a terminal; in a log or a pipe a line at every tenth of the budget), the
learning curve (the mean episode throughput of each rollout's finished episodes, which the
manifest keeps), ``RUN_DIR/checkpoint.zip`` for ``uavlink train --resume``, and SB3's per-update
records as ``progress.csv`` beside TensorBoard's events. Imports stable-baselines3 inside.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["save_checkpoint", "training_monitor"]


def save_checkpoint(model: Any, run_dir: Path) -> Path:
    """``run_dir``/checkpoint.zip, written whole (to a partial file, then renamed)."""
    checkpoint, partial = run_dir / "checkpoint.zip", run_dir / "checkpoint.partial.zip"
    model.save(partial)
    partial.replace(checkpoint)
    return checkpoint


def _continued_csv(path: Path, steps: int) -> Any:
    """SB3's CSV table at ``path``, keeping the rows of the first ``steps`` env steps already in it.

    A run continued from a snapshot or a checkpoint logs into the same ``ppo_N`` folder, and SB3's
    ``CSVOutputFormat`` opens its file empty: the table would lose the run's start. Rows past
    ``steps`` (logged after the snapshot, before the stop) are the ones the continued run repeats.
    """
    from stable_baselines3.common.logger import CSVOutputFormat

    lines = path.read_text().splitlines() if steps and path.is_file() else []
    keys = lines[0].split(",") if lines else []
    table = CSVOutputFormat(str(path))
    if "time/total_timesteps" in keys:
        table.keys = keys
        column = keys.index("time/total_timesteps")
        kept = [row for row in lines[1:] if int(row.split(",")[column] or 0) <= steps]
        table.file.write("\n".join([lines[0], *kept]) + "\n")
        table.file.flush()
    return table


def training_monitor(total: int, run_dir: Path | None, checkpoint_every: int, progress: bool):
    """The SB3 callback of every ``train`` run: ``total`` env steps' progress (a bar on a terminal,
    a line at every tenth of it in a log), the learning curve the manifest keeps, a checkpoint in
    ``run_dir`` every ``checkpoint_every`` steps, and SB3's per-update records as a CSV table."""
    from stable_baselines3.common.callbacks import BaseCallback

    class TrainingMonitor(BaseCallback):
        """Progress bar with the mean episode throughput (on a terminal; in a log or a pipe a line
        at every tenth of the budget instead), learning curve, periodic checkpoint."""

        def __init__(self) -> None:
            super().__init__()
            self.curve: list[tuple[int, float]] = []
            self._bar = None
            self.next_checkpoint = checkpoint_every  # steps; a training snapshot carries it
            self._csv: Any = None
            self._next_line: int | None = None  # steps at which the next log line is due
            self._start = time.perf_counter()

        def _on_training_start(self) -> None:
            if run_dir is not None and self.logger.dir:
                # Beside TensorBoard's events (RUN_DIR/ppo_N), the same per-update records as a
                # table: train/explained_variance, train/value_loss, rollout/mean_rate_mbps, ...
                self._csv = _continued_csv(
                    Path(self.logger.dir) / "progress.csv", self.num_timesteps
                )
                self.logger.output_formats.append(self._csv)
            if progress:
                from tqdm.auto import tqdm

                # disable=None: no bar when stderr is not a terminal (logs, pipes, CI)
                self._bar = bar = tqdm(
                    total=total,
                    initial=self.num_timesteps,
                    unit="step",
                    dynamic_ncols=True,
                    disable=None,
                )
                if bar.disable:  # hours of silence in a log otherwise
                    self._next_line = self._tenth_after(self.num_timesteps)

        def _on_step(self) -> bool:
            # Fixed-length episodes end together: look at the infos only on a step where some did.
            done = self.locals["dones"].any()
            rates = (
                [i["episode"]["mean_rate_mbps"] for i in self.locals["infos"] if "episode" in i]
                if done
                else []
            )
            if rates:
                mean = float(np.mean(rates))
                self.curve.append((int(self.num_timesteps), round(mean, 4)))
                self.logger.record("rollout/mean_rate_mbps", mean)
                if self._bar is not None:
                    self._bar.set_postfix_str(f"{mean:.2f} Mbps")
            if self._bar is not None:
                self._bar.n = min(self.num_timesteps, total)
                self._bar.refresh() if self.num_timesteps % 4096 < self.training_env.num_envs else None
            if self._next_line is not None and self.num_timesteps >= self._next_line:
                self._log_line()
            if run_dir is not None and self.num_timesteps >= self.next_checkpoint:
                save_checkpoint(self.model, run_dir)
                self.next_checkpoint += checkpoint_every
            return True

        def _log_line(self) -> None:
            steps = min(self.num_timesteps, total)
            rate = f", {self.curve[-1][1]:.2f} Mbps" if self.curve else ""
            minutes = (time.perf_counter() - self._start) / 60
            print(
                f"train: {100 * steps // total} % ({steps:,} of {total:,} steps){rate}, "
                f"{minutes:.1f} min",
                file=sys.stderr,
                flush=True,
            )
            self._next_line = None if steps >= total else self._tenth_after(steps)

        @staticmethod
        def _tenth_after(steps: int) -> int:
            """The first step of the next tenth of the budget after ``steps`` (k x total / 10, up)."""
            return -(-(steps * 10 // total + 1) * total // 10)

        def _on_training_end(self) -> None:
            if self._bar is not None:
                self._bar.n = min(self.num_timesteps, total)
                self._bar.close()
            # SB3 writes an update's records (train/...) when the next rollout's are written: the
            # last update's would be lost
            self.logger.record("time/total_timesteps", self.num_timesteps)
            self.logger.dump(self.num_timesteps)
            if self._csv is not None:
                self.logger.output_formats.remove(self._csv)
                self._csv.close()

    return TrainingMonitor()
