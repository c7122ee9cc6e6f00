"""Train one sweep job whose spread teacher pushes the UAVs apart by ``--spread-m``, then pair the
policy with that teacher.

From a kmeans copy PPO climbs about 2 % on hotspot and stops there; from a copy of the spread
teacher (20 m), about 3 % above kmeans, it finds nothing more (research/log/fleet.md, "Advantages
against copies flying the same episodes"). Is the climb's length fixed, so that a start between
the two (10 m) climbs past the teacher it copied, up to or beyond the 20 m rule? This runs a sweep
job (its env and train settings, unchanged; its teacher must be ``spread``) with the spread teacher
built at ``--spread-m``, then flies the policy and that same teacher on the same seeded episodes at
each D of ``--sizes`` (paired 95 % intervals). The manifest names the teacher ``spread`` without
the distance: ``research/fleet_bars.py`` would rebuild the 20 m rule, so the pairing is here.

    python research/spread_start_ppo.py research/sweeps/fleet_spread_mc.toml --scenario hotspot \
        --seed 1 --spread-m 10 --out runs/trials/hotspot_spread10.zip
    python research/spread_start_ppo.py research/sweeps/fleet_spread_mc.toml --scenario hotspot \
        --seed 1 --spread-m 10 --measure runs/trials/hotspot_spread10.zip --episodes 300
"""

from __future__ import annotations

import functools
from pathlib import Path
from typing import Any
from unittest import mock

from entry import run_script
from fleet_bars import paired_ratio, ratio_text


def against_teacher(
    path: Path, spread_m: float, sizes: list[int], episodes: int, seed: int
) -> list[dict[str, Any]]:
    """The policy at ``path`` and the spread teacher at ``spread_m`` on the same episodes, per D."""
    from uavlink.evaluation import evaluate_policy
    from uavlink.learn.teachers import SpreadTeacher
    from uavlink.policies.contract import EnvOverrides, load_with_env

    [(policy, built)] = load_with_env([str(path)], EnvOverrides())
    rows = []
    for size in sizes:
        cfg = built.replace(n_uavs=size).validate()
        ppo = evaluate_policy(policy, cfg, episodes, seed)
        teacher = evaluate_policy(SpreadTeacher(cfg, spread_m), cfg, episodes, seed)
        rows.append(
            {
                "n_uavs": size,
                "ppo_mbps": round(ppo.mean_rate_mbps, 3),
                "teacher_mbps": round(teacher.mean_rate_mbps, 3),
                "vs_teacher": paired_ratio(ppo, teacher),
            }
        )
    return rows


def main(argv: list[str] | None = None) -> int:
    from frozen_std_train import curve_sixths, sweep_job

    args, job = sweep_job(
        __doc__.split("\n\n")[0].replace("\n", " "),
        argv,
        ("--spread-m", {"type": float, "required": True, "help": "the teacher's spread (m)"}),
        ("--sizes", {"type": int, "nargs": "+", "default": [2, 3, 4]}),
        ("--episodes", {"type": int, "default": 300, "help": "episodes of the pairing"}),
        ("--pair-seed", {"type": int, "default": 1, "help": "seed of the pairing's episodes"}),
        ("--measure", {"type": Path, "help": "pair this trained policy only; no training"}),
        out_unless="measure",
    )
    if job.train.warm_start.teacher != "spread":
        raise SystemExit(f"{job.name}: its teacher is {job.train.warm_start.teacher!r}, not spread")
    path = args.measure
    if path is None:
        from uavlink.learn import teachers
        from uavlink.learn.training import train

        teacher = functools.partial(teachers.SpreadTeacher, spread_m=args.spread_m)
        with mock.patch.object(teachers, "SpreadTeacher", teacher):
            training = train(job.env, job.train, args.out, progress=False)
        print(
            f"{job.name}, spread {args.spread_m:g} m -> {args.out}; curve {curve_sixths(training)}"
        )
        path = args.out
    for row in against_teacher(path, args.spread_m, args.sizes, args.episodes, args.pair_seed):
        print(
            f"D = {row['n_uavs']}: {row['ppo_mbps']:.2f} Mbps, its teacher (spread "
            f"{args.spread_m:g} m) {row['teacher_mbps']:.2f}: {ratio_text(row['vs_teacher'])}"
        )
    return 0


if __name__ == "__main__":
    run_script(main)
