"""``uavlink train``: PPO on the batched env, options from ``TrainConfig``; the saved policy's
evaluation goes into its manifest."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from uavlink.cli.options import add_env_options, output_file, output_folder
from uavlink.config import MIXED, SCENARIOS, EnvConfig, TrainConfig
from uavlink.config.fields import add_options, flag_of, from_options
from uavlink.errors import UserError, require
from uavlink.policies.contract import EnvOverrides, apply_overrides


def cmd_train(args: argparse.Namespace) -> int:
    from uavlink.learn.training import check_checkpoint, train

    output_file(
        args.out, "--out", (".zip",)
    )  # the policy's place, checked before hours of training
    cfg = apply_overrides(
        EnvConfig(),
        EnvOverrides.from_command_line(args.scenario, args.aoa_noise_deg, args.overrides),
    )
    tc = from_options(TrainConfig, args).validate(cfg, name=lambda path: flag_of(TrainConfig, path))
    if args.eval_episodes < 0:
        raise UserError(f"--eval-episodes must be >= 0 (0: skip), got {args.eval_episodes}")
    from uavlink.policies.manifest import read_zip_manifest

    for file in (
        tc.warm_start.policy,
        tc.warm_start.leader_policy,
    ):  # the loader's checks, before any output
        if file:
            read_zip_manifest(Path(file))
    require("stable_baselines3")
    if args.resume is not None:
        check_checkpoint(args.resume, cfg, tc)
    if args.snapshot is not None:  # train() checks again; here, before any output or folder
        from uavlink.learn.snapshot import check_can_snapshot, read_snapshot

        check_can_snapshot(tc, args.resume)
        output_file(args.snapshot, "--snapshot", ())
        if read_snapshot(args.snapshot, cfg, tc) is not None:
            print(f"continuing from the snapshot {args.snapshot}", file=sys.stderr)
    run_dir = output_folder(
        args.run_dir or Path("runs") / f"{args.out.stem}-seed{tc.seed}", "--run-dir"
    )
    budget, trained = tc.total_timesteps(cfg), tc.trained_timesteps(cfg)
    rounded = f" (rounded up to whole rollouts: {trained:,})" if trained > budget else ""
    print(
        f"training PPO on {cfg.scenario!r} for {budget:,} env steps{rounded}; "
        f"TensorBoard logs and checkpoint in {run_dir}",
        file=sys.stderr,
    )
    training = train(
        cfg,
        tc,
        args.out,
        run_dir,
        resume=args.resume,
        progress=not args.no_progress,
        snapshot=args.snapshot,
    )
    print(
        f"saved {args.out} ({training['total_timesteps']:,} steps in {training['wall_time_s']:.0f} s)"
    )
    if training["validation"]:
        kept = training["validation"]
        print(
            f"kept the weights after {kept['kept_steps']:,} steps: {kept['kept_mbps']:.3f} Mbps on "
            f"{kept['episodes']} validation episodes (the last: {kept['curve'][-1][1]:.3f})"
        )
    if args.eval_episodes:
        print(
            f"evaluating {args.out} on {args.eval_episodes} episodes (seed 0) into its manifest",
            file=sys.stderr,
        )
        for scenario, figures in _attach_evaluation(args.out, cfg, args.eval_episodes).items():
            print(
                f"{scenario}: {figures['mean_rate_mbps']:.3f} Mbps ± {figures['ci95_mbps']:.3f} (95 %), "
                f"R_fair {figures['mean_fair_rate']:.3f}"
            )
    return 0


def _attach_evaluation(path: Path, cfg: EnvConfig, episodes: int) -> dict[str, dict]:
    """Evaluate the saved policy (seed 0) and store the figures in its manifest; the figures by scenario."""
    from uavlink.evaluation import evaluate_policy
    from uavlink.policies.manifest import read_zip_manifest, write_zip_manifest
    from uavlink.policies.sb3_policy import SB3Policy

    policy = SB3Policy(path)
    figures = {}
    for scenario in SCENARIOS if cfg.scenario == MIXED else [cfg.scenario]:
        result = evaluate_policy(policy, cfg.replace(scenario=scenario), episodes, seed=0)
        figures[scenario] = {k: v for k, v in result.to_dict().items() if k != "episode_rate_mbps"}
    manifest = read_zip_manifest(path)
    manifest["evaluation"] = figures
    write_zip_manifest(path, manifest)
    return figures


def add_train_parser(sub) -> None:
    p = sub.add_parser(
        "train",
        help="train a PPO policy",
        description="Train PPO on the batched env. Defaults are the paper's; the training "
        "options are TrainConfig's fields (uavlink/config/train.py).",
    )
    add_env_options(p)
    p.add_argument("--out", type=Path, required=True, help="policy zip to write (FILE.zip)")
    add_options(p, TrainConfig)
    p.add_argument(
        "--run-dir",
        type=Path,
        default=None,
        help="TensorBoard logs and checkpoint (default runs/OUT-seedN)",
    )
    p.add_argument(
        "--resume",
        type=Path,
        default=None,
        help="continue from a checkpoint (RUN_DIR/checkpoint.zip, written every --checkpoint-every-steps "
        "and on Ctrl-C) or a policy zip this command saved; the PPO settings are this "
        "command's",
    )
    p.add_argument(
        "--snapshot",
        type=Path,
        default=None,
        metavar="FILE",
        help="keep a snapshot of the run here (between rollouts, every minute); when FILE is "
        "there, continue from it to the weights the uninterrupted run gives (run the same "
        "command again after Ctrl-C or a crash); removed once the policy is saved",
    )
    p.add_argument(
        "--eval-episodes",
        type=int,
        default=100,
        help="evaluate after training into the manifest (default 100; 0: skip)",
    )
    p.add_argument(
        "--no-progress",
        action="store_true",
        help="no progress bar (on a terminal) nor a line at every tenth of the budget (in a log)",
    )
    p.set_defaults(func=cmd_train)
