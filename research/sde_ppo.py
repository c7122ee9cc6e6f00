"""Train one sweep job with exploration that holds for a whole episode (gSDE) after the warm start.

PPO explores with Gaussian noise drawn afresh every frame. The action is a move of at most r_max
a frame, and the policy steers back to where it wants to be, so white noise jitters a UAV about its
placement and averages out: it never tries a different placement for long enough to be scored on
it, while what separates the teachers' rules is the placement as a whole (research/log/fleet.md,
"Advantages against copies flying the same episodes"). Generalised state-dependent exploration
(gSDE; Raffin, Kober and Stulp, CoRL 2021; SB3's ``use_sde``) draws the noise as a function of the
actor's last hidden layer, eps(s) = phi(s) . W, with W drawn once per rollout (``--sample-freq -1``:
each agent row's W holds for its whole 128-frame episode), so each UAV explores a consistent
change of its placement rule. The action's per-frame law is still Gaussian, so PPO's ratio stands.

The product's callback does it (``uavlink/learn/held_exploration.py``, ``uavlink train
--gsde-log-std``, W drawn once a rollout); this script also tries other ``--sample-freq``.

    python research/sde_ppo.py sweeps/fleet.toml --scenario circular --seed 0 --log-std -1.5 \
        --out runs/trials/circular_sde_seed0.zip
    python research/fleet_bars.py --fleet DIR --scenario circular --episodes 300 --seed 1
"""

from __future__ import annotations

from entry import run_script


def main(argv: list[str] | None = None) -> int:
    from frozen_std_train import curve_sixths, sweep_job

    args, job = sweep_job(
        __doc__.split("\n\n")[0],
        argv,
        ("--log-std", {"type": float, "default": -2.0, "help": "per-frame log std (default -2)"}),
        (
            "--sample-freq",
            {"type": int, "default": -1, "help": "frames between draws of W; -1: once a rollout"},
        ),
    )

    from uavlink.learn.held_exploration import held_exploration_callback
    from uavlink.learn.training import train

    training = train(
        job.env,
        job.train,
        args.out,
        progress=False,
        callbacks=[held_exploration_callback(args.log_std, args.sample_freq)],
    )
    print(f"{job.name} with gSDE -> {args.out}; learning curve in sixths {curve_sixths(training)}")
    return 0


if __name__ == "__main__":
    run_script(main)
