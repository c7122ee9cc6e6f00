"""Training throughput: env steps per second of ``uavlink train`` end to end, against the env's own rate.

For the default settings (``TrainConfig()`` on ``circular``) and for each shipped recipe (the
distinct PPO-loop settings of ``sweeps/*.toml``), runs ``uavlink.learn.training.train`` (what ``uavlink
train`` calls: the batched VecEnv, reward scaling, SB3's PPO, the progress/learning-curve callback,
TensorBoard logs and checkpoints in a run folder) and reports
  - the marginal rate between two budgets: env steps from the end of the first rollout's update to
    the end of training, over the wall time between them, so start-up (imports, the model, the
    first rollout) and the final save do not count (``uavlink train``'s evaluation is not run);
  - where that time goes, per env step: the env's physics (``BatchedUavEnv.step``/``reset`` less the
    observation), the observation (``ObservationBuilder``), the VecEnv face (SB3 infos, reward
    scaling), the policy's forward passes in the rollout (actions, values, the bootstrap values of
    cut-off episodes), the rollout buffer (add, GAE), the PPO update (with SB3's per-rollout log
    dump), and the rest (SB3's loop, callbacks, checkpoints);
  - the env's own rate at N = 256: ``benchmarks/env_throughput.py``'s batched measurement (random
    actions) of the env the setting trains in (``training_env_config``: its scenario, D, shadowing
    model, fleet_slots, memory, AoA noise; the default settings': circular, fading and shadowing
    on), measured just before and just after each training measurement, and the ratio of the two
    (the target, >= 0.1x: the default settings' is ``meets_target``, every fleet recipe's
    ``fleet_recipes_meet_target``, each row's its own ``meets_target``). With ``--repeats`` every
    setting is measured that many times, the settings interleaved; each ratio is then the repeats'
    mean with a 95 % interval, and ">=" is the issues' (not below with the interval: a tie meets
    it; ``above_target`` where the whole interval clears it).
An env step is one frame of one env (a fleet's frame moves all its UAVs: SB3's agent steps / D).
A recipe that trains on several fleet sizes at once (``train.fleet_sizes_up_to``: n_envs episodes
of each size side by side) counts SB3's agent steps / mean(sizes), so one frame of each of its
envs is n_envs x len(sizes) env steps; its env rate is that of stepping equal numbers of envs of
each size, len(sizes) / sum(1 / rate_D) from each size's own rate at N = 256 (reported alongside).
A recipe's warm start (behaviour cloning) is start-up and is not run here; its critic warm-up
rollouts (actor frozen, a cheaper update) are left out with it, so a recipe's rate is its steady
state. Rates are wall time, with the process's CPU time alongside (steadier on a shared machine).

    python benchmarks/train_throughput.py                 # Markdown table (about 2 minutes, idle)
    python benchmarks/train_throughput.py --json          # one JSON object
    python benchmarks/train_throughput.py --min-steps 500000 --env-seconds 3   # longer, steadier
    python benchmarks/train_throughput.py --no-recipes    # the default settings only
    python benchmarks/train_throughput.py --json --only fleet   # the fleet recipes only (a minute)
    python benchmarks/train_throughput.py --no-recipes --variant torch_threads=2 --variant n_epochs=1
                                                          # the default beside variants of it
    python benchmarks/train_throughput.py --only fleet --sweeps sweeps --sweeps research/sweeps/X.toml
                                                          # shipped recipes beside a research one
    python benchmarks/train_throughput.py --only fleet --repeats 5 --json
                                                          # each ratio with a 95 % interval
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
import json
import math
import os
import platform
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np
from env_throughput import TARGET_BATCHED_N, Bench, batched_bench

from uavlink.config import EnvConfig, TrainConfig
from uavlink.config.train import WarmStartConfig
from uavlink.errors import ConfigError
from uavlink.sweep.rows import t975
from uavlink.sweep.sweep_file import load_spec, tomllib

ROOT = Path(__file__).resolve().parents[1]
TARGET_RATIO = 0.1
PHASES = ("env", "observation", "vecenv", "policy", "buffer", "update", "other")
# What makes one recipe's PPO loop faster or slower than another's (not the learning rate, the
# teacher, the seed or the budget): recipes equal in these share a measurement.
SPEED_TRAIN = (
    "n_envs",
    "n_steps",
    "batch_size",
    "n_epochs",
    "normalize_reward",
    "net_arch",
    "fleet_sizes",
    "gsde_log_std",  # held exploration draws its noise from the actor's features every step
)
SPEED_ENV = (
    "n_uavs",
    "fleet_reuse",
    "fleet_slots",
    "radio.shadowing_model",
    "radio.aoa_noise_max_deg",
    "memory",
    "place_cell_m",  # the memory of place and the model of the field are built every step
    "place_model",
)


@dataclasses.dataclass
class Setting:
    name: str
    cfg: EnvConfig
    tc: TrainConfig
    covers: list[str]

    @property
    def sizes(self) -> tuple[int, ...]:
        """The fleet sizes the training steps side by side (one: the env's own n_uavs)."""
        return self.tc.fleet_sizes or (self.cfg.n_uavs,)

    @property
    def agents_per_env_step(self) -> float:
        """SB3's agent steps per env step: D, or the sizes' mean (n_envs episodes of each)."""
        return sum(self.sizes) / len(self.sizes)

    @property
    def is_fleet(self) -> bool:
        return self.cfg.n_uavs > 1 or bool(self.tc.fleet_sizes)

    def env_configs(self) -> list[EnvConfig]:
        """The env the training steps, one config per fleet size (``training_env_config``'s)."""
        from uavlink.learn.training import training_env_config

        env = training_env_config(self.cfg, self.tc)
        if not self.tc.fleet_sizes:
            return [env]
        return [env.replace(n_uavs=size).validate() for size in self.tc.fleet_sizes]


def default_setting() -> Setting:
    return Setting(
        "default",
        EnvConfig().replace(scenario="circular").validate(),
        TrainConfig(),
        ["uavlink train"],
    )


def variant_setting(spec: str) -> Setting:
    """The default settings with TrainConfig overrides ``KEY=VALUE[,KEY=VALUE]`` (a side-by-side variant)."""
    from uavlink.config.fields import coerce

    base = default_setting()
    overrides = {}
    for item in spec.split(","):
        key, sep, value = item.partition("=")
        if not sep:
            raise ValueError(f"--variant {spec!r}: expected KEY=VALUE")
        try:  # a TOML value, as in a sweep file's [train] table
            parsed = tomllib.loads(f"v = {value.strip()}")["v"]
        except tomllib.TOMLDecodeError:
            parsed = value.strip()
        overrides[key.strip()] = coerce(TrainConfig, key.strip(), parsed, key.strip())
    tc = dataclasses.replace(base.tc, **overrides).validate(base.cfg)
    return Setting(f"default {spec}", base.cfg, tc, [f"uavlink train with {spec}"])


def _speed_key(cfg: EnvConfig, tc: TrainConfig) -> tuple:
    flat_env = {**cfg.to_dict(), **{f"radio.{k}": v for k, v in cfg.to_dict()["radio"].items()}}
    return tuple(str(getattr(tc, k)) for k in SPEED_TRAIN) + tuple(
        str(bool(v) if k.endswith("noise_max_deg") else v)
        for k, v in ((k, flat_env[k]) for k in SPEED_ENV)
    )


def recipe_settings(sweeps: Path) -> list[Setting]:
    """One Setting per distinct PPO-loop setting of the sweep files in the folder ``sweeps`` (or of
    that one file), naming the recipes it covers."""
    from uavlink.learn.training import training_env_config

    found: dict[tuple, Setting] = {}
    for path in sorted(sweeps.glob("*.toml")) if sweeps.is_dir() else [sweeps]:
        spec = load_spec(path)
        for scenario in spec.scenarios:
            for point in spec.points():
                cfg, tc = spec.configs(scenario, point, spec.seeds[0])
                key = _speed_key(training_env_config(cfg, tc), tc)
                label = f"{spec.name}:{scenario}" + "".join(f" {k}={v}" for k, v in point.items())
                if key not in found:
                    found[key] = Setting(f"{spec.name}:{scenario}", cfg, tc, [])
                found[key].covers.append(label)
    return list(found.values())


def env_cores(venv: Any) -> list[Any]:
    """The batched cores under SB3's VecEnv (through VecNormalize): a ``UavVecEnv``'s one, or each
    part's of a ``FleetSizesVecEnv`` (one ``UavVecEnv``, or a wrapper of one, per fleet size)."""
    inner = venv.unwrapped if hasattr(venv, "unwrapped") else venv
    parts = getattr(inner, "parts", None)
    if parts is None:
        return [inner.core]
    return [core for part in parts for core in env_cores(part)]


class LoopTimer:
    """Accumulates wall time per phase of SB3's PPO loop by wrapping the methods each phase runs.
    Built as an SB3 callback so ``train`` installs it on its own model; it only observes."""

    def __init__(self) -> None:
        self.totals = dict.fromkeys(
            ("core", "observation", "vecenv", "policy", "buffer", "update"), 0.0
        )
        self.rollouts = 0
        self.marks: list[
            tuple[int, float, float, dict[str, float]]
        ] = []  # (steps, wall, cpu, totals)
        self._wrapped: list[tuple[Any, str]] = []
        self.update_start: float | None = None

    def _wrap(self, owner: Any, name: str, phase: str) -> None:
        inner = getattr(owner, name)

        @functools.wraps(inner)
        def timed(*args, **kwargs):
            start = time.perf_counter()
            try:
                return inner(*args, **kwargs)
            finally:
                self.totals[phase] += time.perf_counter() - start

        setattr(owner, name, timed)  # an instance attribute over the class's method
        self._wrapped.append((owner, name))

    def unwrap(self) -> None:
        """Back to the class's methods (the model is saved next: its attributes get pickled)."""
        for owner, name in self._wrapped:
            delattr(owner, name)
        self._wrapped.clear()

    def callback(self):
        from stable_baselines3.common.callbacks import BaseCallback

        timer = self

        class Marks(BaseCallback):
            def _on_training_start(self) -> None:
                model, venv = self.model, self.model.get_env()
                timer._wrap(venv, "step_wait", "vecenv")
                for core in env_cores(venv):
                    timer._wrap(core, "step", "core")
                    timer._wrap(core, "reset", "core")
                    timer._wrap(core._builder, "push", "observation")
                    timer._wrap(core._builder, "reset", "observation")
                timer._wrap(model.policy, "forward", "policy")
                timer._wrap(model.policy, "predict_values", "policy")
                timer._wrap(model.rollout_buffer, "add", "buffer")
                timer._wrap(model.rollout_buffer, "compute_returns_and_advantage", "buffer")
                # The update is timed between the callbacks (a wrapper on the model itself would be
                # pickled into the run's checkpoints): from a rollout's end to the next one's start.

            def _on_rollout_end(self) -> None:
                timer.update_start = time.perf_counter()

            def _on_rollout_start(self) -> None:
                timer.end_update()
                timer.rollouts += 1
                if timer.rollouts == 2:  # the first rollout and its update are done: budget one
                    timer.mark(self.num_timesteps)

            def _on_step(self) -> bool:
                return True

            def _on_training_end(self) -> None:
                timer.end_update()
                timer.mark(self.num_timesteps)
                timer.unwrap()

        return Marks()

    def end_update(self) -> None:
        if self.update_start is not None:
            self.totals["update"] += time.perf_counter() - self.update_start
            self.update_start = None

    def mark(self, steps: int) -> None:
        self.marks.append((steps, time.perf_counter(), time.process_time(), dict(self.totals)))

    def report(self, agents_per_env_step: float) -> dict[str, Any]:
        """The timed span's rates; SB3's agent steps / ``agents_per_env_step`` (D, or the mean of
        the fleet sizes trained side by side) are its env steps."""
        (s0, w0, c0, t0), (s1, w1, c1, t1) = self.marks[0], self.marks[-1]
        env_steps, wall, cpu = (s1 - s0) / agents_per_env_step, w1 - w0, c1 - c0
        d = {k: t1[k] - t0[k] for k in t1}
        phases = {
            "env": d["core"] - d["observation"],
            "observation": d["observation"],
            "vecenv": d["vecenv"] - d["core"],
            "policy": d["policy"],
            "buffer": d["buffer"],
            "update": d["update"],
        }
        phases["other"] = wall - sum(phases.values())
        return {
            "env_steps": int(env_steps),
            "rollouts": self.rollouts - 1,
            "seconds": round(wall, 3),
            "env_steps_per_s": round(env_steps / wall, 1),
            "env_steps_per_cpu_s": round(env_steps / cpu, 1),
            "us_per_env_step": {k: round(1e6 * v / env_steps, 3) for k, v in phases.items()},
            "share": {k: round(v / wall, 4) for k, v in phases.items()},
        }


def measure_training(setting: Setting, min_steps: int) -> dict[str, Any]:
    """``train`` for 1 + k rollouts (k >= 2, k rollouts >= ``min_steps`` env steps), timed after the first."""
    from uavlink.learn.training import train

    cfg, tc = setting.cfg, setting.tc
    # a rollout: n_steps frames of n_envs episodes of each fleet size
    rollout_env_steps = tc.n_envs * len(setting.sizes) * tc.n_steps
    k = max(2, math.ceil(min_steps / rollout_env_steps))
    # tc.total_timesteps(cfg) = episodes x episode_frames x mean(sizes) >= (1 + k) rollouts' agent steps
    episodes = math.ceil((1 + k) * rollout_env_steps / cfg.episode_frames)
    tc = dataclasses.replace(tc, episodes=episodes, warm_start=WarmStartConfig())
    timer = LoopTimer()
    with tempfile.TemporaryDirectory(prefix="uavlink-train-throughput-") as tmp:
        train(
            cfg,
            tc,
            Path(tmp) / "policy.zip",
            run_dir=Path(tmp) / "run",
            progress=False,
            callbacks=[timer.callback()],
        )
    return timer.report(setting.agents_per_env_step)


class EnvRates:
    """The env's own rate at N = 256 for every env a setting trains in, one batched bench per
    distinct config (built and warmed up at first use), each measured just before and just after
    a training measurement: a bench measured since the last training is not measured again."""

    def __init__(self, env_seconds: float, seed: int) -> None:
        self.env_seconds, self.seed = env_seconds, seed
        self.benches: dict[str, tuple[EnvConfig, Bench]] = {}
        self.trainings = 0
        self._measured_at: dict[str, int] = {}  # bench -> trainings done when last measured

    def bench(self, cfg: EnvConfig) -> tuple[str, Bench]:
        key = json.dumps(cfg.to_dict(), sort_keys=True, default=str)
        if key not in self.benches:
            env = batched_bench(cfg, TARGET_BATCHED_N, self.seed)
            env.measure(
                min(0.2, self.env_seconds)
            )  # warm-up: caches, the first episode's allocations
            env.us_per_call.clear()
            env.cpu_us_per_call.clear()
            self.benches[key] = (cfg, env)
        return key, self.benches[key][1]

    def measure(self, key: str, bench: Bench) -> None:
        bench.measure(self.env_seconds)
        self._measured_at[key] = self.trainings

    def before(self, setting: Setting) -> list[tuple[str, Bench, int]]:
        """Measure (unless measured since the last training) each env the setting trains in, one
        per fleet size; (key, bench, index of the bracket's first measurement) per size."""
        marks = []
        for cfg in setting.env_configs():
            key, bench = self.bench(cfg)
            if self._measured_at.get(key) != self.trainings:
                self.measure(key, bench)
            marks.append((key, bench, len(bench.us_per_call) - 1))
        return marks

    def after(self, setting: Setting, marks: list[tuple[str, Bench, int]]) -> dict[str, Any]:
        """Measure each env again; the rates of the bracket (the mean of the two measurements' µs
        per call), per size and for the mix (equal numbers of envs of each size)."""
        self.trainings += 1
        by_size, by_size_cpu = {}, {}
        for (key, bench, before), size in zip(marks, setting.sizes, strict=True):
            self.measure(key, bench)
            by_size[size] = 1e6 * TARGET_BATCHED_N / float(np.mean(bench.us_per_call[before:]))
            by_size_cpu[size] = (
                1e6 * TARGET_BATCHED_N / float(np.mean(bench.cpu_us_per_call[before:]))
            )
        mix = len(by_size) / sum(1 / r for r in by_size.values())
        mix_cpu = len(by_size_cpu) / sum(1 / r for r in by_size_cpu.values())
        return {"rate": mix, "rate_cpu": mix_cpu, "by_size": by_size, "by_size_cpu": by_size_cpu}

    def rows(self) -> list[dict[str, Any]]:
        return [
            {
                "scenario": cfg.scenario,
                "fleet_slots": cfg.fleet_slots,
                "memory": cfg.memory,
                "aoa_noise_max_deg": cfg.radio.aoa_noise_max_deg,
                **Bench.row(bench),
            }
            for cfg, bench in self.benches.values()
        ]


def measure_row(
    setting: Setting, envs: EnvRates, min_steps: int
) -> tuple[dict[str, Any], dict[str, Any]]:
    """One training measurement of ``setting`` inside its bracket of env measurements: the training
    row (``LoopTimer.report``) and the env's rates."""
    marks = envs.before(setting)
    row = measure_training(setting, min_steps)
    return row, envs.after(setting, marks)


def ratio_interval(ratios: list[float]) -> tuple[float, float, float]:
    """The mean of the repeats' ratios and its 95 % Student-t interval (nan bounds for one)."""
    mean = float(np.mean(ratios))
    if len(ratios) < 2:
        return mean, math.nan, math.nan
    half = t975(len(ratios) - 1) * float(np.std(ratios, ddof=1)) / math.sqrt(len(ratios))
    return mean, mean - half, mean + half


def setting_row(
    setting: Setting, measured: list[tuple[dict[str, Any], dict[str, Any]]]
) -> dict[str, Any]:
    """A setting's row from its repeats: each repeat's ratio is its training rate over the env's rate
    in its own bracket (paired); rates and µs per step are the repeats' means. ``meets_target``: one
    repeat at or above the target, or with repeats the interval not below it (a tie meets it: the
    issues' ">="); ``above_target``: the whole interval above it."""
    tc, cfg = setting.tc, setting.cfg
    ratios = [row["env_steps_per_s"] / env["rate"] for row, env in measured]
    ratios_cpu = [row["env_steps_per_cpu_s"] / env["rate_cpu"] for row, env in measured]
    ratio, lo, hi = ratio_interval(ratios)
    rows, envs = [row for row, _ in measured], [env for _, env in measured]

    def mean(values: list[float]) -> float:
        return float(np.mean(values))

    return {
        "setting": setting.name,
        "covers": setting.covers,
        "scenario": cfg.scenario,
        "n_envs": tc.n_envs,
        "n_steps": tc.n_steps,
        "batch_size": tc.batch_size,
        "n_epochs": tc.n_epochs,
        "n_uavs": cfg.n_uavs,
        "fleet_slots": cfg.fleet_slots,
        "fleet_sizes": list(tc.fleet_sizes),
        "agents_per_env_step": setting.agents_per_env_step,
        "shadowing_model": cfg.radio.shadowing_model,
        "env_steps": sum(r["env_steps"] for r in rows),
        "rollouts": sum(r["rollouts"] for r in rows),
        "seconds": round(sum(r["seconds"] for r in rows), 3),
        "env_steps_per_s": round(mean([r["env_steps_per_s"] for r in rows]), 1),
        "env_steps_per_cpu_s": round(mean([r["env_steps_per_cpu_s"] for r in rows]), 1),
        "us_per_env_step": {
            k: round(mean([r["us_per_env_step"][k] for r in rows]), 3)
            for k in rows[0]["us_per_env_step"]
        },
        "share": {k: round(mean([r["share"][k] for r in rows]), 4) for k in rows[0]["share"]},
        "env_n256_steps_per_s": round(mean([e["rate"] for e in envs]), 1),
        "env_n256_steps_per_cpu_s": round(mean([e["rate_cpu"] for e in envs]), 1),
        "env_n256_steps_per_s_by_size": {
            str(d): round(mean([e["by_size"][d] for e in envs]), 1) for d in setting.sizes
        },
        "env_n256_steps_per_cpu_s_by_size": {
            str(d): round(mean([e["by_size_cpu"][d] for e in envs]), 1) for d in setting.sizes
        },
        "repeats": len(measured),
        "ratios": [round(r, 6) for r in ratios],
        "ratio": round(ratio, 4),
        "ratio_ci95": None if math.isnan(lo) else [round(lo, 4), round(hi, 4)],
        "ratio_cpu": round(mean(ratios_cpu), 4),
        "meets_target": bool((ratio if math.isnan(hi) else hi) >= TARGET_RATIO),
        "above_target": bool((ratio if math.isnan(lo) else lo) >= TARGET_RATIO),
    }


def run(
    settings: list[Setting], min_steps: int, env_seconds: float, seed: int, repeats: int = 1
) -> dict[str, Any]:
    envs = EnvRates(env_seconds, seed)
    measured: list[list[tuple[dict[str, Any], dict[str, Any]]]] = [[] for _ in settings]
    for _ in range(repeats):  # the settings interleaved, so a slow spell of the machine hits all
        for setting, found in zip(settings, measured, strict=True):
            found.append(measure_row(setting, envs, min_steps))
    rows = [setting_row(s, m) for s, m in zip(settings, measured, strict=True)]
    report: dict[str, Any] = {
        "benchmark": "train_throughput",
        "statistic": "marginal wall-time rate from the end of the first rollout's update to the end of "
        "training, in env steps (SB3's agent steps / D, or / mean(sizes) for a mix of fleet sizes); "
        "the env's N = 256 rate is that of the env the setting trains in (env_throughput.py's "
        "batched env, random actions), the mean of its measurements just before and just after; "
        "for a mix of sizes, len(sizes) / sum(1 / rate_D) (equal numbers of envs of each size); "
        "CPU-time rates alongside; with repeats, each repeat's ratio is paired with its own "
        "bracket of env measurements, the settings interleaved, and the ratio is the repeats' mean "
        "with a 95 % Student-t interval",
        "min_steps": min_steps,
        "repeats": repeats,
        "env_seconds": env_seconds,
        "seed": seed,
        "load_average": list(os.getloadavg()) if hasattr(os, "getloadavg") else None,
        "machine": {
            "python": platform.python_version(),
            "numpy": np.__version__,
            "cpus": os.cpu_count(),
            "platform": platform.platform(),
        },
        "env_n256": envs.rows(),
        "results": rows,
        "target_ratio": TARGET_RATIO,
    }
    default = next((r for r in rows if r["setting"] == "default"), None)
    if default is not None:
        report["default_ratio"] = default["ratio"]
        report["default_ratio_cpu"] = default["ratio_cpu"]
        report["meets_target"] = default["meets_target"]
    fleets = [r for s, r in zip(settings, rows, strict=True) if s.is_fleet]
    if fleets:
        report["fleet_recipes_meet_target"] = all(r["meets_target"] for r in fleets)
        report["fleet_recipes_above_target"] = all(r["above_target"] for r in fleets)
    return report


def ratio_text(row: dict[str, Any]) -> str:
    """A row's ratio, with its 95 % interval over the repeats where there are several."""
    ci = row["ratio_ci95"]
    return f"{row['ratio']:.3f}" + (f" [{ci[0]:.3f}, {ci[1]:.3f}]" if ci else "")


def markdown(report: dict[str, Any]) -> str:
    load = report.get("load_average")
    lines = [
        f"training throughput (marginal rate after the first rollout, >= {report['min_steps']:,} env steps "
        f"per setting"
        + (f" x {report['repeats']} repeats" if report["repeats"] > 1 else "")
        + f"; {report['machine']['cpus']} CPUs"
        + (f", load average {load[0]:.1f} at the start)" if load else ")"),
        "",
        "| setting | N | n_steps | batch | epochs | D | env steps/s | per CPU-s | env N=256/s | ratio | ratio (CPU) "
        "| µs/step: " + " / ".join(PHASES) + " |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|",
    ]
    for r in report["results"]:
        us = " / ".join(f"{r['us_per_env_step'][p]:.1f}" for p in PHASES)
        d = "+".join(map(str, r["fleet_sizes"])) or str(r["n_uavs"])
        lines.append(
            f"| {r['setting']} | {r['n_envs']} | {r['n_steps']} | {r['batch_size']} | {r['n_epochs']} "
            f"| {d} | {r['env_steps_per_s']:,.0f} | {r['env_steps_per_cpu_s']:,.0f} "
            f"| {r['env_n256_steps_per_s']:,.0f} | {ratio_text(r)} | {r['ratio_cpu']:.3f} | {us} |"
        )
    lines.append("")
    for r in report["results"]:
        env = f"env {r['scenario']}, {r['shadowing_model']}" + (
            f", fleet_slots {r['fleet_slots']}" if r["fleet_slots"] else ""
        )
        if len(r["env_n256_steps_per_s_by_size"]) > 1:
            env += ", N = 256 per size: " + ", ".join(
                f"D = {d} {rate:,.0f}/s" for d, rate in r["env_n256_steps_per_s_by_size"].items()
            )
        lines.append(f"- {r['setting']} ({env}): {', '.join(r['covers'])}")
    if "meets_target" in report:
        ok = "meets" if report["meets_target"] else "MISSES"
        lines += [
            "",
            f"default `uavlink train`: {report['default_ratio']:.3f}x the env's N = 256 rate "
            f"({report['default_ratio_cpu']:.3f}x in CPU time; {ok} the target of >= {TARGET_RATIO}x)",
        ]
    if "fleet_recipes_meet_target" in report:
        ok = "meet" if report["fleet_recipes_meet_target"] else "do NOT all meet"
        if report["repeats"] > 1:
            ok += " (not below it with the 95 % interval; " + (
                "every interval above it)"
                if report["fleet_recipes_above_target"]
                else "not every interval above it)"
            )
        lines += [
            "",
            f"fleet recipes, each against its own fleet env's N = 256 rate: {ok} the target of "
            f">= {TARGET_RATIO}x",
        ]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--min-steps",
        type=int,
        default=65_536,
        help="env steps timed per setting, after the first rollout (default 65536)",
    )
    parser.add_argument(
        "--env-seconds",
        type=float,
        default=1.0,
        help="wall time of each measurement of the env's N = 256 rate (default 1)",
    )
    parser.add_argument(
        "--sweeps",
        type=Path,
        action="append",
        help="folder of the sweep files whose recipes are measured, or one sweep file; "
        "repeatable, side by side in one run (default: sweeps/)",
    )
    parser.add_argument(
        "--no-recipes", action="store_true", help="measure the default settings only"
    )
    parser.add_argument(
        "--variant",
        action="append",
        default=[],
        metavar="KEY=VALUE[,...]",
        help="also measure the default settings with these TrainConfig overrides (repeatable)",
    )
    parser.add_argument(
        "--only",
        metavar="SUBSTRING",
        help="measure only the settings whose name contains this (e.g. fleet)",
    )
    parser.add_argument(
        "--repeats",
        type=int,
        default=1,
        help="measure every setting this many times, interleaved, and give each ratio a 95 %% "
        "interval (default 1)",
    )
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--json", action="store_true", help="print one JSON object instead of a table"
    )
    args = parser.parse_args(argv)
    if args.min_steps < 1 or args.env_seconds <= 0 or args.repeats < 1:
        parser.error("--min-steps, --env-seconds and --repeats must be positive")
    args.sweeps = args.sweeps or [ROOT / "sweeps"]
    if missing := [str(path) for path in args.sweeps if not path.exists()]:
        parser.error(f"--sweeps {', '.join(missing)}: no such folder or file")
    settings = [default_setting()]
    try:
        settings += [variant_setting(v) for v in args.variant]
    except (ValueError, ConfigError) as exc:
        parser.error(str(exc))
    if not args.no_recipes:
        settings += [setting for path in args.sweeps for setting in recipe_settings(path)]
    if args.only is not None:
        settings = [s for s in settings if args.only in s.name]
        if not settings:
            parser.error(f"--only {args.only!r}: no setting's name contains it")
    report = run(settings, args.min_steps, args.env_seconds, args.seed, args.repeats)
    print(json.dumps(report, indent=2) if args.json else markdown(report))
    return 0


if __name__ == "__main__":
    sys.exit(main())
