"""The training's typed configuration: PPO's hyper-parameters, the budget, the warm start.

Each field says, in one place, its default, help, range and whether the paper states it; the
``uavlink train`` flags and the sweep files' ``[train]`` tables are derived from these fields
(``uavlink.config.fields``), and ``validate()`` holds every check of a training's settings.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

from uavlink.config.env import EnvConfig, fleet_sizes_of
from uavlink.config.fields import (
    SEED_MAX,
    Namer,
    check_fields,
    coerce,
    config_fields,
    nested,
    setting,
)
from uavlink.errors import ConfigError

# The rules a warm start can copy; uavlink.policies.registry builds them by these names.
BASELINE_NAMES = ("static", "oracle", "aoa", "kmeans", "explore", "kriging")
# The fleet-only teachers (uavlink.learn.teachers builds them; lead: uavlink.learn.lead_teacher) and
# what each needs of the env: a fleet (n_uavs > 1), or the any-size layout's slots (fleet_slots > 0).
NEEDS_FLEET, NEEDS_SLOTS = "fleet", "slots"
FLEET_TEACHERS: dict[str, str] = {
    "solo": NEEDS_FLEET,
    "lead": NEEDS_FLEET,
    "bearings": NEEDS_SLOTS,
    "spread": NEEDS_FLEET,
}
# What a warm start may imitate: a baseline, or a fleet-only teacher.
TEACHER_NAMES = (*BASELINE_NAMES, *FLEET_TEACHERS)


# What PPO's critic reads (TrainConfig.critic): the actor's observation, or that plus the
# privileged columns uavlink.learn.privileged appends in training only.
CRITIC_ACTOR, CRITIC_PRIVILEGED = "actor", "privileged"
CRITICS = (CRITIC_ACTOR, CRITIC_PRIVILEGED)


def config_name(path: str) -> str:
    """How validate() names a field by default: ``train.warm_start.episodes``."""
    return f"train.{path}"


@dataclass(frozen=True)
class WarmStartConfig:
    """Warm starts (ours). Behaviour cloning (uavlink/learn/imitation.py): the actor is first fitted to
    a rule's actions over ``episodes`` of its own flying. Or ``policy``: every weight comes from a
    policy file whose observation lacks some of this env's fields (uavlink/learn/policy_transfer.py).
    Either way the exploration std is set to exp(``log_std``) and PPO fits only the critic for
    ``critic_rollouts`` rollouts (the actor frozen) before it trains as usual."""

    teacher: str = setting(
        "",
        "first fit the actor to this rule's actions (behaviour cloning), then run PPO (ours; "
        f"one of {', '.join(TEACHER_NAMES)}; {', '.join(FLEET_TEACHERS)} fly fleets: "
        "uavlink/learn/teachers.py; default: off, the paper's PPO from scratch)",
        flag="--warm-start",
        metavar="RULE",
        choices=("", *TEACHER_NAMES),
    )
    episodes: int = setting(256, "episodes the rule flies to make the cloning data", low=1)
    epochs: int | None = setting(
        None,
        "passes of the actor over the cloning data (default: 20)",
        low=1,
        metavar="N",
    )
    log_std: float = setting(-1.0, "exploration log std PPO starts from after the warm start")
    critic_rollouts: int = setting(
        10, "PPO updates with the actor frozen, fitting the critic", low=0
    )
    shadow_gate_db: float | None = setting(
        None,
        "aoa teacher only: hover when the newest frame's mean SINR beats the older frames' by "
        "more than DB (ours; default: off, the SPEC's rule)",
        metavar="DB",
    )
    sinr_span_db: float | None = setting(
        None,
        "aoa teacher only: its speed span, full speed DB below the hover SINR (default: the "
        "baseline's 10 dB)",
        low=0,
        low_open=True,
        metavar="DB",
    )
    shadow_estimator_episodes: int | None = setting(
        None,
        "aoa teacher only: gate on a shadowing estimate (uavlink/learn/shadow_estimation.py) fitted on "
        "N simulated episodes (hover while the estimated mean shadowing is above "
        "--warm-start-shadow-gate-db) instead of on the SINR jump (ours)",
        low=1,
        metavar="N",
    )
    spread_m: float | None = setting(
        None,
        "spread teacher only: how much further from the other groups each UAV aims, m (default: "
        "the teacher's 20; research/spread_search.py)",
        low=0,
        metavar="M",
    )
    leader_policy: str = setting(
        "",
        "lead teacher only: the single-UAV policy file (.zip) the leading UAV flies (e.g. "
        "policies/spatial/no_move.zip; default: the single-UAV aoa rule)",
        metavar="FILE",
    )
    policy: str = setting(
        "",
        "instead of a teacher, start from this policy file's weights: one whose observation lacks "
        "some of this env's fields (e.g. policies/spatial/hotspot.zip for a map policy); its inputs keep "
        "their weights and the new ones start at zero, so PPO starts from its actions exactly; its "
        "exploration std is reset to exp(--warm-start-log-std), not kept "
        "(uavlink/learn/policy_transfer.py; ours)",
        flag="--start-from",
        metavar="FILE",
    )

    dagger_rounds: int = setting(
        0,
        "after the first fit, this many rounds in which the copy flies the same number of "
        "episodes, the teacher labels the frames it meets and the copy is fitted again on all "
        "the data (DAgger, Ross et al. 2011; ours; 0: off)",
        low=0,
        metavar="N",
    )

    def validate(self, name: Namer = config_name) -> WarmStartConfig:
        check_fields(self, lambda path: name(f"warm_start.{path}"))
        if self.dagger_rounds and not self.teacher:
            raise ConfigError(
                f"{name('warm_start.dagger_rounds')} needs a {name('warm_start.teacher')} to label "
                "the copy's flying"
            )
        for knob in ("shadow_gate_db", "sinr_span_db", "shadow_estimator_episodes"):
            if getattr(self, knob) is not None and self.teacher != "aoa":
                raise ConfigError(
                    f"{name('warm_start.' + knob)} needs {name('warm_start.teacher')} aoa"
                )
        if self.policy and self.teacher:
            raise ConfigError(
                f"{name('warm_start.policy')} starts from a policy's weights: it takes no "
                f"{name('warm_start.teacher')} (leave it empty)"
            )
        if self.spread_m is not None and self.teacher != "spread":
            raise ConfigError(
                f"{name('warm_start.spread_m')} needs {name('warm_start.teacher')} spread"
            )
        if self.leader_policy and self.teacher != "lead":
            raise ConfigError(
                f"{name('warm_start.leader_policy')} needs {name('warm_start.teacher')} lead"
            )
        if self.shadow_estimator_episodes is not None and self.shadow_gate_db is None:
            raise ConfigError(
                f"{name('warm_start.shadow_estimator_episodes')} needs "
                f"{name('warm_start.shadow_gate_db')} (the gate's threshold)"
            )
        return self

    def check_env(self, env: EnvConfig, name: Namer = config_name) -> None:
        """The checks against the env the teacher flies: a fleet's teachers need a fleet, the shadow
        gate is the single-UAV aoa rule's and compares frames."""
        needs = FLEET_TEACHERS.get(self.teacher)
        if needs is not None and env.n_uavs == 1:
            raise ConfigError(
                f"{name('warm_start.teacher')} {self.teacher} is a fleet's teacher: it needs n_uavs > 1"
            )
        if needs == NEEDS_SLOTS and env.fleet_slots == 0:
            raise ConfigError(
                f"{name('warm_start.teacher')} {self.teacher} reads the any-size fleet's bearing "
                "fixes: it needs env.fleet_slots > 0"
            )
        if self.shadow_gate_db is not None and env.n_uavs > 1:
            raise ConfigError(
                f"{name('warm_start.shadow_gate_db')} is the single-UAV aoa teacher's; a "
                f"fleet's aoa teacher takes only {name('warm_start.sinr_span_db')}"
            )
        if self.shadow_gate_db is not None and env.memory < 2:
            raise ConfigError(
                f"{name('warm_start.shadow_gate_db')} compares frames: it needs memory >= 2"
            )


@dataclass(frozen=True)
class TrainConfig:
    """PPO as the paper configures it (SPEC "What the paper reports": 12,000 episodes, lr 3e-4, 3 x 128
    actor and critic, gamma 0.99, GAE lambda 0.95, max grad norm 1.0, clip 0.2; memory M = 4 lives in
    EnvConfig) and, not marked ``paper``, our choices. An episode is ``EnvConfig.episode_frames``
    steps, so the budget is ``total_timesteps(env)``."""

    episodes: int = setting(
        12_000,
        "training budget in episodes of the env's episode_frames steps (paper: 12000)",
        low=1,
        paper=True,
    )
    learning_rate: float = setting(
        3e-4, "Adam learning rate (paper: 3e-4)", low=0, low_open=True, paper=True
    )
    net_arch: tuple[int, ...] = setting(
        (128, 128, 128),
        "hidden layers of the actor and of the critic (paper: 128 128 128)",
        paper=True,
    )
    gamma: float = setting(0.99, "discount (paper: 0.99)", low=0, low_open=True, high=1, paper=True)
    gae_lambda: float = setting(0.95, "GAE lambda (paper: 0.95)", low=0, high=1, paper=True)
    max_grad_norm: float = setting(
        1.0, "gradient clip norm (paper: 1.0)", low=0, low_open=True, paper=True
    )
    clip_range: float = setting(
        0.2, "PPO clip range (paper: 0.2)", low=0, low_open=True, paper=True
    )
    # Ours, sized for speed (docs/design/learning.md, "PPO settings the paper does not state"): one update
    # epoch of minibatch 1024 (at 10 epochs the update was ~80 % of the loop), 128 envs to amortise
    # the rollout's per-step cost (the policy's forward pass), and rollouts of whole episodes: a
    # rollout cut mid-episode bootstraps returns from a critic that cannot see the episode clock
    # (the paper's observation has none), and circular learned less. The defaults were 32 envs x
    # 128 steps, minibatch 512, 10 epochs before; the shipped recipes in sweeps/ pin those, so
    # their jobs and policies stay as they were.
    n_envs: int = setting(128, "parallel envs in the batched VecEnv (ours)", low=1)
    n_steps: int = setting(
        128,
        "steps per env per rollout (ours: a whole 128-frame episode, so no "
        "return is cut off and bootstrapped)",
        low=1,
    )
    batch_size: int = setting(1024, "PPO minibatch (ours)", low=2)
    n_epochs: int = setting(1, "PPO epochs per rollout (ours)", low=1)
    ent_coef: float = setting(0.0, "entropy bonus coefficient (ours, SB3 default)", low=0)
    vf_coef: float = setting(0.5, "value loss coefficient (ours, SB3 default)", low=0)
    # An asymmetric actor-critic (uavlink/learn/privileged.py): the critic is only needed while
    # training, so it may read what no vehicle senses; the actor, the only part a policy file flies
    # or exports, reads the observation alone and stays GPS-free.
    critic: str = setting(
        CRITIC_ACTOR,
        "what PPO's critic reads: actor (the actor's observation, as the paper's PPO) or "
        "privileged (also, in training only, every UE's true position relative to the row's UAV "
        "and velocity and the episode's progress; the actor and the saved policy read the "
        "observation alone; ours)",
        choices=CRITICS,
    )
    # Noise held for an episode tries a placement long enough to be scored on it; white noise
    # jitters a UAV about its placement (uavlink/learn/held_exploration.py).
    gsde_log_std: float | None = setting(
        None,
        "explore with gSDE after the warm start, the noise drawn once a rollout (each row's episode "
        "at n_steps = episode_frames), at this per-frame "
        "log std (ours; uavlink/learn/held_exploration.py; default: off, white Gaussian noise)",
        metavar="LOG_STD",
    )
    # Undiscounted returns reach ~100; without the scaling the critic's gradient dominates the
    # shared max-grad-norm clip. Observations are O(1) by construction and are not normalised, so
    # a saved policy needs no statistics at inference.
    normalize_reward: bool = setting(
        True,
        "scale rewards by a running estimate of the return's std "
        "(SB3 VecNormalize, rewards only; ours)",
    )
    # Domain randomisation belongs to the training, not to the policy's env: training_env_config puts
    # it into the env PPO trains in (RadioConfig.aoa_noise_max_deg, which the env core reads), while
    # the manifest keeps the env without it, so evaluation and flight run without it unless asked.
    aoa_noise_max_deg: float = setting(
        0.0,
        "train with each episode's AoA noise std drawn from [--aoa-noise-deg, this] (ours; 0: off)",
        low=0,
    )
    validation_episodes: int = setting(
        0,
        "score the deterministic policy on this many validation "
        "episodes (a stream apart from every evaluation seed) before the "
        "first update, after each and at the end, and ship the best weights "
        "(ours; uavlink/learn/selection.py; 0: off, the last weights)",
        low=0,
        metavar="N",
    )
    # One any-size fleet policy (EnvConfig.fleet_slots > 0) trains on several fleet sizes at once:
    # n_envs episodes of each, side by side in every rollout (uavlink.env.vec_env.FleetSizesVecEnv).
    fleet_sizes_up_to: int = setting(
        0,
        "train on every fleet size from 2 to this together, n_envs episodes of each (ours; needs "
        "env.fleet_slots >= this - 1; 0: env.n_uavs alone)",
        low=0,
        metavar="D",
    )
    warm_start: WarmStartConfig = nested(WarmStartConfig, "behaviour-cloning warm start (ours)")
    seed: int = setting(0, "seed of the envs, the network and the warm start", low=0, high=SEED_MAX)
    torch_threads: int = setting(1, "torch CPU threads (1 is fastest for 3x128 MLPs)", low=1)
    checkpoint_every_steps: int = setting(
        100_000, "save RUN_DIR/checkpoint.zip every this many env steps", low=1
    )

    @property
    def fleet_sizes(self) -> tuple[int, ...]:
        """The fleet sizes trained on together (``fleet_sizes_up_to``); empty: the env's own."""
        return tuple(range(2, self.fleet_sizes_up_to + 1))

    def total_timesteps(self, env: EnvConfig) -> int:
        """The budget in agent steps (what SB3 counts): ``episodes`` of the env's ``episode_frames``,
        times ``n_uavs`` for a fleet, whose UAVs each take a step per frame (with ``fleet_sizes``,
        the sizes' mean: the episodes are shared among them equally)."""
        if self.fleet_sizes:
            return (
                self.episodes * env.episode_frames * sum(self.fleet_sizes) // len(self.fleet_sizes)
            )
        return self.episodes * env.episode_frames * env.n_uavs

    def trained_timesteps(self, env: EnvConfig) -> int:
        """What a training from scratch runs: ``total_timesteps`` rounded up to whole rollouts
        (SB3 collects a whole rollout of every agent row, ``n_steps`` each, before it checks the
        budget), so a budget below one rollout trains one."""
        rows = self.n_envs * (sum(self.fleet_sizes) if self.fleet_sizes else env.n_uavs)
        rollout = rows * self.n_steps
        return -(-self.total_timesteps(env) // rollout) * rollout

    def validate(self, env: EnvConfig | None = None, name: Namer = config_name) -> TrainConfig:
        """Every check of a training's settings, each a one-line ConfigError naming the field (as
        ``name`` spells it: ``train.x`` by default, a flag for the command line). With ``env``, also
        the checks against the env it trains in."""
        check_fields(self, name)
        if self.n_envs * self.n_steps < 2:
            raise ConfigError(
                f"{name('n_envs')} x {name('n_steps')} must be >= 2 (PPO's rollout buffer)"
            )
        rollout = self.n_envs * self.n_steps
        if self.batch_size > rollout or rollout % self.batch_size:
            raise ConfigError(
                f"{name('batch_size')} must divide a rollout of {name('n_envs')} x {name('n_steps')} "
                f"= {rollout} steps into whole minibatches, got {self.batch_size}"
            )
        self.warm_start.validate(name)
        if env is not None:
            self.warm_start.check_env(env, name)
            if self.fleet_sizes_up_to and self.fleet_sizes_up_to not in fleet_sizes_of(
                env.fleet_slots
            ):
                raise ConfigError(
                    f"{name('fleet_sizes_up_to')}={self.fleet_sizes_up_to} needs the any-size "
                    f"layout with env.fleet_slots >= {max(self.fleet_sizes_up_to - 1, 1)}, "
                    f"got fleet_slots={env.fleet_slots}"
                )
            if env.radio.aoa_noise_max_deg:
                raise ConfigError(
                    f"radio.aoa_noise_max_deg is the training's AoA noise randomisation: "
                    f"set {name('aoa_noise_max_deg')} instead"
                )
            if 0 < self.aoa_noise_max_deg < env.radio.aoa_noise_deg:
                raise ConfigError(
                    f"{name('aoa_noise_max_deg')} must be 0 (off) or >= the env's "
                    f"aoa_noise_deg ({env.radio.aoa_noise_deg:g}), got {self.aoa_noise_max_deg:g}"
                )
        return self

    def to_dict(self) -> dict[str, Any]:
        """The manifest's ``training.hyperparameters``: the nested shape, lists for tuples."""
        data = dataclasses.asdict(self)
        data["net_arch"] = list(self.net_arch)
        return data

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> TrainConfig:
        """From ``to_dict``'s shape, or from an old manifest's flat one (``warm_start_teacher``, ...,
        and the unused ``extra``); an unknown key is a ConfigError."""
        values: dict[str, Any] = {}
        warm = dict(data.get("warm_start") or {})
        for key, value in data.items():
            if key in ("warm_start", "extra"):
                continue
            flat = legacy_warm_start_key(key)
            if flat is not None:
                warm[flat] = value
            else:
                values[key] = coerce(cls, key, value, f"train.{key}")
        values["warm_start"] = WarmStartConfig(
            **{k: coerce(WarmStartConfig, k, v, f"train.warm_start.{k}") for k, v in warm.items()}
        )
        return cls(**values)


def legacy_warm_start_key(key: str) -> str | None:
    """The WarmStartConfig field an old flat key (``warm_start_teacher``) names, else None."""
    if not key.startswith("warm_start_"):
        return None
    name = key.removeprefix("warm_start_")
    return name if name in {f.name for f, _ in config_fields(WarmStartConfig)} else None


PAPER_HYPERPARAMETERS = tuple(
    f.name for f, _ in config_fields(TrainConfig) if f.metadata.get("paper")
)
