"""Sweeps on Dask: a real scheduler and worker processes on 127.0.0.1, worker death, spec errors.

Jobs are tiny (512 env steps of PPO, 4 evaluation episodes per policy). Workers run with
UAVLINK_SWEEP_TRACE, so every job start and end is recorded per worker process.
"""

from __future__ import annotations

import json
import os
import re
import signal
import socket
import subprocess
import sys
import time
import zipfile
from collections import Counter
from pathlib import Path

import pytest

pytest.importorskip("distributed")
pytest.importorskip("stable_baselines3")

from uavlink.cli import main  # noqa: E402
from uavlink.config import EnvConfig, TrainConfig, WarmStartConfig  # noqa: E402
from uavlink.config.fields import config_fields, with_changes  # noqa: E402
from uavlink.errors import UserError  # noqa: E402
from uavlink.sweep.aggregate import (  # noqa: E402
    collect,
    export_median_policies,
    finished_rows,
    read_record,
    record_path,
    results_section,
    summary_table,
)
from uavlink.sweep.jobs import figures  # noqa: E402
from uavlink.sweep.rows import SettingRow, t975  # noqa: E402
from uavlink.sweep.runner import run_sweep  # noqa: E402
from uavlink.sweep.spec import (  # noqa: E402
    KEY_VERSION,
    NEUTRAL_TRAIN_DEFAULTS,
    NEUTRAL_WARM_START_DEFAULTS,
    POLICY_FILE_FIELDS,
    Job,
    SweepSpecError,
)
from uavlink.sweep.sweep_file import load_spec, parse_spec  # noqa: E402

TINY = """
name = "tiny4"
scenarios = ["straight", "circular"]
seeds = [0, 1]
[train]
episodes = 4
n_envs = 4
batch_size = 128
n_epochs = 1
[eval]
episodes = 4
"""


def _free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


class Cluster:
    """``dask scheduler`` and ``dask worker`` processes on loopback, workers without a nanny."""

    def __init__(self, tmp: Path, n_workers: int = 2, env: dict[str, str] | None = None) -> None:
        self.port = _free_port()
        self.address = f"tcp://127.0.0.1:{self.port}"
        self.trace = tmp / "trace"
        self.trace.mkdir()
        base = {**os.environ, "UAVLINK_SWEEP_TRACE": str(self.trace), **(env or {})}
        logs = tmp / "logs"
        logs.mkdir()
        self.procs: list[subprocess.Popen] = []
        self.scheduler = self._start(
            ["scheduler", "--host", "127.0.0.1", "--port", str(self.port), "--no-dashboard"],
            base,
            logs / "scheduler.log",
        )
        deadline = time.monotonic() + 30
        while True:
            try:
                socket.create_connection(("127.0.0.1", self.port), timeout=1).close()
                break
            except OSError:
                assert time.monotonic() < deadline, "scheduler did not start"
                time.sleep(0.1)
        self.workers = [
            self._start(
                [
                    "worker",
                    self.address,
                    "--nthreads",
                    "1",
                    "--host",
                    "127.0.0.1",
                    "--no-dashboard",
                    "--no-nanny",
                    "--name",
                    f"w{i}",
                ],
                base,
                logs / f"worker{i}.log",
            )
            for i in range(n_workers)
        ]
        from distributed import Client

        with Client(self.address, timeout="20s") as client:
            client.wait_for_workers(n_workers, timeout=40)

    def _start(self, args: list[str], env: dict[str, str], log: Path) -> subprocess.Popen:
        with log.open("w") as handle:
            proc = subprocess.Popen(
                [sys.executable, "-m", "dask", *args],
                env=env,
                stdout=handle,
                stderr=subprocess.STDOUT,
            )
        self.procs.append(proc)
        return proc

    def events(self) -> list[tuple[int, str, str]]:
        """(pid, start|end, job key) for every traced event."""
        out = []
        for log in self.trace.glob("*.log"):
            for line in log.read_text().splitlines():
                event, key, _ = line.split()
                out.append((int(log.stem), event, key))
        return out

    def close(self) -> None:
        """Kill every process: the traces are appended and closed per event, and a graceful Dask
        shutdown (SIGTERM) takes ~5 s of the test's wall time for nothing it checks."""
        for proc in reversed(self.procs):
            if proc.poll() is None:
                proc.kill()
        for proc in self.procs:
            proc.wait(timeout=10)


@pytest.fixture
def cluster_factory(tmp_path: Path):
    made: list[Cluster] = []

    def make(**kwargs) -> Cluster:
        folder = tmp_path / f"cluster{len(made)}"
        folder.mkdir()
        made.append(Cluster(folder, **kwargs))
        return made[-1]

    yield make
    for cluster in made:
        cluster.close()


def _results(sweep_dir: Path) -> dict[str, dict]:
    return {p.parent.name: json.loads(p.read_text()) for p in sweep_dir.glob("*/result.json")}


@pytest.mark.slow
@pytest.mark.timeout(120)
def test_sweep_on_scheduler_and_two_workers(tmp_path: Path, cluster_factory, capsys) -> None:
    sweep_file = tmp_path / "tiny4.toml"
    sweep_file.write_text(TINY)
    cluster = cluster_factory(n_workers=2)
    out = tmp_path / "runs"
    assert (
        main(
            [
                "sweep",
                str(sweep_file),
                "--scheduler",
                cluster.address,
                "--out-root",
                str(out),
            ]
        )
        == 0
    )
    spec = load_spec(sweep_file)
    keys = {job.key for job in spec.jobs()}
    results = _results(out / "tiny4")
    assert len(keys) == 4 and {r["key"] for r in results.values()} == keys
    # stderr is no terminal here: a line per finished job, as the jobs come back from the workers
    err = capsys.readouterr().err
    assert sorted(re.findall(r"^job (\S+) done \(\d/4\)", err, re.M)) == sorted(results), err

    # Every job ran exactly once, and both worker processes ran some.
    events = cluster.events()
    assert Counter(k for _, e, k in events if e == "start") == dict.fromkeys(keys, 1)
    assert Counter(k for _, e, k in events if e == "end") == dict.fromkeys(keys, 1)
    assert {pid for pid, _, _ in events} == {w.pid for w in cluster.workers}
    assert len({r["worker"]["address"] for r in results.values()}) == 2
    for name in results:
        folder = out / "tiny4" / name
        assert zipfile.is_zipfile(folder / "policy.zip") and (folder / "policy.json").is_file()
    summary = (out / "tiny4" / "summary.md").read_text()
    assert "| straight | 2/2 |" in summary and (out / "tiny4" / "throughput.png").is_file()

    # The same jobs run one after another in this process, without Dask: the same figures.
    # Its stderr is no terminal (pytest's capture): no bar, a line per finished job instead.
    lines: list[str] = []
    sequential = run_sweep(spec, tmp_path / "seq", workers=0, log=lines.append)
    assert sequential.finished == 4
    done = [line for line in lines if line.startswith("job ")]
    assert [line.split(" done (")[1].split(")")[0] for line in done] == ["1/4", "2/4", "3/4", "4/4"]
    assert all(re.search(r"PPO \d+\.\d{3} Mbps on \d+ episodes of seed 0, ", x) for x in done)
    for name, result in _results(tmp_path / "seq" / "tiny4").items():
        assert result["worker"]["address"] == "in-process"
        assert figures(result) == figures(results[name])

    # A rerun does no work (it does not even need the scheduler); it can ship the median seeds.
    cluster.close()
    capsys.readouterr()
    policies = tmp_path / "policies"
    assert (
        main(
            [
                "sweep",
                str(sweep_file),
                "--scheduler",
                cluster.address,
                "--out-root",
                str(out),
                "--no-progress",
                "--policies-out",
                str(policies),
            ]
        )
        == 0
    )
    assert "4 already done, 0 to run" in capsys.readouterr().err
    assert len(cluster.events()) == len(events)
    for scenario in ("straight", "circular"):
        manifest = json.loads((policies / f"{scenario}.json").read_text())
        seeds = {int(s): v for s, v in manifest["selection"]["seeds_mbps"].items()}
        assert manifest["selection"]["seed"] == min(
            seeds, key=lambda s: (seeds[s], s)
        )  # lower median of 2
        assert zipfile.is_zipfile(policies / f"{scenario}.zip")
    # Shipping again writes the same bytes: re-shipped policies show no diff in git.
    shipped = {p.name: p.read_bytes() for p in policies.iterdir()}
    time.sleep(2.1)  # zip timestamps have a 2 s resolution
    assert (
        main(
            [
                "sweep",
                str(sweep_file),
                "--out-root",
                str(out),
                "--workers",
                "0",
                "--no-progress",
                "--policies-out",
                str(policies),
            ]
        )
        == 0
    )
    assert {p.name: p.read_bytes() for p in policies.iterdir()} == shipped


@pytest.mark.slow  # trains one small job three times
def test_a_job_stopped_mid_training_continues_from_its_snapshot_to_the_same_figures(
    tmp_path: Path,
) -> None:
    from support.interrupt import cut_training

    from uavlink.sweep.jobs import run_job
    from uavlink.sweep.sweep_file import tomllib

    longer = TINY.replace("episodes = 4\nn_envs", "episodes = 12\nn_envs")
    job = parse_spec(tomllib.loads(longer)).jobs()[0]
    whole = run_job(job.to_dict())  # 3 rollouts of 4 envs x 128 frames
    folder = tmp_path / "sweep"
    folder.mkdir()
    snapshot = folder / f"{job.name}.snapshot"
    cut_training(job.env, job.train, tmp_path / "cut.zip", snapshot, 3)
    assert snapshot.is_file()
    continued = run_job(job.to_dict(), str(folder))
    assert figures(continued) == figures(whole) and not snapshot.exists()


@pytest.mark.slow
@pytest.mark.timeout(120)
def test_worker_killed_mid_job_is_retried_elsewhere(tmp_path: Path, cluster_factory) -> None:
    sweep_file = tmp_path / "tiny4.toml"
    sweep_file.write_text(TINY)
    # 1 s after each start line, then the job imports torch (seconds, in a fresh worker) and trains:
    # a kill within the second after the start line lands mid-job; the survivor runs every job
    cluster = cluster_factory(n_workers=2, env={"UAVLINK_SWEEP_DELAY_S": "1"})
    out = tmp_path / "runs"
    sweep = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "uavlink.cli",
            "sweep",
            str(sweep_file),
            "--scheduler",
            cluster.address,
            "--out-root",
            str(out),
            "--no-progress",
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        deadline = time.monotonic() + 60
        victim = None
        while victim is None:
            assert time.monotonic() < deadline and sweep.poll() is None, "no job started"
            started = [pid for pid, event, _ in cluster.events() if event == "start"]
            victim = next((w for w in cluster.workers if w.pid in started), None)
            time.sleep(0.05)
        victim.send_signal(signal.SIGKILL)  # inside the job's 1 s delay: mid-job
        stdout, stderr = sweep.communicate(timeout=90)
    finally:
        if sweep.poll() is None:
            sweep.kill()
    assert sweep.returncode == 0, stderr
    keys = {job.key for job in load_spec(sweep_file).jobs()}
    events = cluster.events()
    killed = [k for pid, e, k in events if pid == victim.pid and e == "start"]
    assert killed and not [k for pid, e, k in events if pid == victim.pid and e == "end"]
    assert Counter(k for _, e, k in events if e == "end") == dict.fromkeys(keys, 1)
    results = _results(out / "tiny4")
    assert {r["key"] for r in results.values()} == keys
    assert all(r["worker"]["pid"] != victim.pid for r in results.values())


@pytest.mark.slow
@pytest.mark.timeout(180)
def test_embedded_cluster_moves_a_busy_dashboard_port_quietly_and_on_loopback(
    tmp_path: Path,
) -> None:
    """A second sweep beside a first one: the dashboard's port is taken, so Dask serves it on a free
    one; the sweep names that one and prints no warning about the move."""
    sweep_file = tmp_path / "one.toml"
    sweep_file.write_text(
        TINY.replace('["straight", "circular"]', '["straight"]').replace("[0, 1]", "[0]")
    )
    holder = socket.socket()
    holder.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    try:
        holder.bind(("127.0.0.1", 8787))
        holder.listen()
    except OSError:
        pass  # something already holds it, which is the case under test
    try:
        proc = subprocess.run(
            [sys.executable, "-m", "uavlink.cli", "sweep", str(sweep_file), "--workers", "1"]
            + ["--out-root", str(tmp_path / "runs"), "--no-progress"],
            capture_output=True,
            text=True,
            timeout=170,
        )
    finally:
        holder.close()
    assert proc.returncode == 0, proc.stderr
    assert "already in use" not in proc.stderr and "Warning" not in proc.stderr, proc.stderr
    dashboard = [line for line in proc.stderr.splitlines() if line.startswith("dashboard: ")]
    assert len(dashboard) == 1, proc.stderr
    assert dashboard[0].startswith("dashboard: http://127.0.0.1:"), dashboard
    assert ":8787/" not in dashboard[0], dashboard


BAD_SPECS = [
    ("frobnicate = 1\n", "'frobnicate'"),
    ("[train]\nlernin_rate = 0.1\n", "'lernin_rate'"),
    ("[train]\nepisodes = -3\n", "train.episodes"),
    ("[train]\nseed = 3\n", "'seed'"),
    ("[env]\nr_max_m = -1.0\n", "r_max_m"),
    ('[env]\n"radio.shadowing" = "yes"\n', "radio.shadowing"),
    ("[env]\nradio.no_such_field = 1\n", "radio.no_such_field"),
    ("[grid]\nlearning_rate = []\n", "'learning_rate'"),
    ('[grid]\n"radio.aoa_noise_deg" = [0.0, -5.0]\n', "radio.aoa_noise_deg"),
    ("[eval]\nepisodes = 0\n", "eval.episodes"),
    ('scenarios = ["sideways"]\n', "scenarios"),
    ("[scenario_train.circular]\nepisodes = 4\n", "'circular'"),  # not one of the sweep's scenarios
    (
        "[scenario_train.straight]\nradio.shadowing = false\n",
        "radio.shadowing",
    ),  # train fields only
    ("[scenario_train.straight]\nn_envs = 0\n", "train.n_envs"),
    ("[train]\nwarm_start_epochs = 8.5\n", "warm_start_epochs"),  # optional, but an integer
    (
        "[train]\nwarm_start_epochs = 0\n",
        "train.warm_start.epochs",
    ),  # an old key: the error names the new one
    ("[train.warm_start]\nsinr_span_db = 0\n", "train.warm_start.sinr_span_db"),
    ("[train]\nwarm_start.shadow_gate_db = 1.0\n", "train.warm_start.shadow_gate_db needs"),
    ('[train]\nwarm_start.teacher = "aoa"\nwarm_start_teacher = "aoa"\n', "'warm_start_teacher'"),
    ('[env]\n"radio.aoa_noise_max_deg" = 50.0\n', "set train.aoa_noise_max_deg"),
    ("[env]\naoa_noise_max_deg = 50.0\n", "set train.aoa_noise_max_deg"),
    (
        "[scenario_train.straight]\nlearning_rate = 1e-4\n[grid]\nlearning_rate = [1e-4]\n",
        "'learning_rate'",
    ),
]


@pytest.mark.timeout(30)
@pytest.mark.parametrize(("text", "named"), BAD_SPECS)
def test_bad_sweep_file_is_one_line_naming_the_key(
    tmp_path: Path, capsys, text: str, named: str
) -> None:
    path = tmp_path / "bad.toml"
    path.write_text('name = "bad"\nscenarios = ["straight"]\n' * ("scenarios" not in text) + text)
    assert main(["sweep", str(path), "--out-root", str(tmp_path / "runs")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("uavlink sweep: error:") and named in err, err
    assert not (tmp_path / "runs").exists()  # nothing started


def test_a_sweep_path_that_is_no_file_says_what_it_is(tmp_path: Path, capsys) -> None:
    """A folder was `cannot read ([Errno 21] Is a directory: ...)`; a missing file names itself."""
    assert main(["sweep", str(tmp_path)]) == 2
    assert "is a folder; give a sweep file" in capsys.readouterr().err
    assert main(["sweep", str(tmp_path / "nope.toml")]) == 2
    assert "nope.toml: no such sweep file" in capsys.readouterr().err


def test_job_keys_are_stable_and_grid_expands() -> None:
    spec = parse_spec(
        {
            "name": "a",
            "scenarios": ["straight"],
            "seeds": 2,
            "train": {"episodes": 4},
            "env": {"radio": {"aoa_noise_deg": 5}},
            "grid": {"learning_rate": [1e-4, 3e-4], "r_max_m": [10, 12.0]},
        }
    )
    jobs = spec.jobs()
    assert len(jobs) == 8 and len({j.key for j in jobs}) == 8
    assert jobs[0].point == {"train.learning_rate": 1e-4, "env.r_max_m": 10.0}
    # Same settings, written differently (bare vs qualified key, int vs float, other sweep name): same key.
    same = parse_spec(
        {
            "name": "b",
            "scenarios": ["straight"],
            "seeds": [0],
            "train": {"episodes": 4, "learning_rate": 1e-4},
            "env": {"r_max_m": 10, "aoa_noise_deg": 5.0},
        }
    )
    assert same.jobs()[0].key == jobs[0].key
    assert jobs[0].env.radio.aoa_noise_deg == 5.0 and jobs[0].train.seed == 0
    # The default 12.0 written out is the same job as leaving r_max_m alone.
    assert (
        parse_spec({"seeds": [0], "env": {"r_max_m": 12}}).jobs()[0].key
        == parse_spec({"seeds": [0]}).jobs()[0].key
    )
    # A training field added after the key's version, at its default, is the same job; set, another.
    plain = parse_spec({"seeds": [0]}).jobs()[0].key
    assert parse_spec({"seeds": [0], "train": {"validation_episodes": 0}}).jobs()[0].key == plain
    assert parse_spec({"seeds": [0], "train": {"validation_episodes": 64}}).jobs()[0].key != plain


def test_scenario_train_overrides_reach_only_their_scenario() -> None:
    base = {
        "name": "a",
        "scenarios": ["straight", "hotspot"],
        "seeds": [0],
        "train": {"episodes": 4},
    }
    plain = {j.scenario: j for j in parse_spec(base).jobs()}
    spec = parse_spec(
        {
            **base,
            "scenario_train": {
                "hotspot": {
                    "n_envs": 8,
                    "warm_start": {"teacher": "aoa", "shadow_gate_db": 1, "epochs": 80},
                }
            },
        }
    )
    jobs = {j.scenario: j for j in spec.jobs()}
    assert jobs["straight"].key == plain["straight"].key  # untouched scenario: same job
    hotspot = jobs["hotspot"].train
    assert jobs["hotspot"].key != plain["hotspot"].key
    assert (hotspot.n_envs, hotspot.episodes, hotspot.warm_start.shadow_gate_db) == (8, 4, 1.0)
    assert hotspot.warm_start.epochs == 80 and isinstance(hotspot.warm_start.epochs, int)
    assert isinstance(hotspot.warm_start.shadow_gate_db, float)  # an optional number: 1 becomes 1.0
    assert jobs["straight"].train.n_envs == TrainConfig().n_envs
    # The old flat keys name the same fields: the same jobs.
    old = parse_spec(
        {
            **base,
            "scenario_train": {
                "hotspot": {
                    "n_envs": 8,
                    "warm_start_teacher": "aoa",
                    "warm_start_shadow_gate_db": 1.0,
                    "warm_start_epochs": 80,
                }
            },
        }
    )
    assert [j.key for j in old.jobs()] == [j.key for j in spec.jobs()]


def test_shipped_sweeps_and_their_old_spelling(tmp_path: Path, capsys) -> None:
    assert main(["sweep", "sweeps/table1.toml", "--dry-run", "--out-root", str(tmp_path)]) == 0
    rows = [line for line in capsys.readouterr().out.splitlines() if line.endswith("| to run |")]
    assert len(rows) == 18 and sum("| hotspot |" in r for r in rows) == 3
    # table1.toml as it was written before the warm start's fields were nested: the same 18 jobs.
    old = Path("sweeps/table1.toml").read_text().replace("warm_start.", "warm_start_")
    (tmp_path / "table1.toml").write_text(old)
    assert [j.key for j in load_spec(tmp_path / "table1.toml").jobs()] == [
        j.key for j in load_spec("sweeps/table1.toml").jobs()
    ]
    hotspot = load_spec("sweeps/table1.toml").jobs()[-1].train
    assert hotspot.warm_start == WarmStartConfig("aoa", 1024, 80, -3.0, 10, 2.0, 8.0, 512)
    assert len(load_spec("sweeps/tiny.toml").jobs()) == 8


def test_job_keys_are_versioned_hashes_of_the_full_configs() -> None:
    job = parse_spec({"name": "a", "scenarios": ["straight"], "seeds": [0]}).jobs()[0]
    assert job.settings()["key_version"] == KEY_VERSION
    full = job.train.to_dict()
    for (
        later
    ) in NEUTRAL_WARM_START_DEFAULTS:  # fields added later, out of the key at their defaults
        del full["warm_start"][later]
    for later in NEUTRAL_TRAIN_DEFAULTS:
        del full[later]
    assert job.settings()["train"] == full  # nothing else left out, nothing bent
    assert Job.from_dict(json.loads(json.dumps(job.to_dict()))).key == job.key
    # Reordering keys changes nothing; changing any setting changes the key.
    reordered = Job(
        job.sweep,
        job.scenario,
        job.seed,
        {},
        EnvConfig.from_dict(dict(reversed(job.env.to_dict().items()))),
        TrainConfig.from_dict(dict(reversed(job.train.to_dict().items()))),
        dict(reversed(job.eval.items())),
    )
    assert reordered.key == job.key
    keys = {job.key}
    for path, value in _changed_train_fields(job.train):
        keys.add(
            Job(
                job.sweep,
                job.scenario,
                job.seed,
                {},
                job.env,
                with_changes(job.train, {path: value}),
                job.eval,
            ).key
        )
    for changes in ({"r_max_m": 8.0}, {"radio.shadowing": False}, {"area.half_width_m": 150.0}):
        keys.add(
            Job(
                job.sweep,
                job.scenario,
                job.seed,
                {},
                job.env.replace(**changes),
                job.train,
                job.eval,
            ).key
        )
    keys.add(
        Job(
            job.sweep, job.scenario, job.seed, {}, job.env, job.train, {**job.eval, "episodes": 7}
        ).key
    )
    assert len(keys) == 1 + len(_changed_train_fields(job.train)) + 3 + 1


def _changed_train_fields(tc: TrainConfig) -> list[tuple[str, object]]:
    """(path, another value) for every field of ``tc``, nested ones included."""
    other = {
        bool: lambda v: not v,
        int: lambda v: v + 1,
        float: lambda v: v + 0.5,
        str: lambda v: "aoa",
        tuple: lambda v: (64,),
        type(None): lambda v: 1,
    }
    out = []
    for f, _ in config_fields(TrainConfig):
        if f.name == "warm_start":
            out += [
                (
                    f"warm_start.{w.name}",
                    "policies/spatial/no_move.zip"
                    if w.name in POLICY_FILE_FIELDS  # a file
                    else other[type(getattr(tc.warm_start, w.name))](
                        getattr(tc.warm_start, w.name)
                    ),
                )
                for w, _ in config_fields(WarmStartConfig)
            ]
        else:
            out.append((f.name, other[type(getattr(tc, f.name))](getattr(tc, f.name))))
    return out


def test_t_quantiles() -> None:
    assert t975(1) == pytest.approx(12.706) and t975(2) == pytest.approx(4.303)
    assert t975(40) == pytest.approx(2.021, abs=2e-3) and t975(1000) == pytest.approx(
        1.962, abs=2e-3
    )


def test_fleet_fields_at_their_neutral_defaults_leave_job_keys_alone():
    """Fields added with a default that reproduces every old figure (the fleet's, at n_uavs = 1)
    stay out of a job's key at that default, so finished sweeps keep their keys; set, they count."""
    from uavlink.config import EnvConfig, TrainConfig
    from uavlink.sweep.spec import NEUTRAL_ENV_DEFAULTS, Job

    one = Job(
        "s",
        "straight",
        0,
        {},
        EnvConfig(scenario="straight"),
        TrainConfig(),
        {"episodes": 5, "seed": 0},
    )
    assert not set(NEUTRAL_ENV_DEFAULTS) & set(one.settings()["env"])
    assert set(NEUTRAL_ENV_DEFAULTS) <= set(EnvConfig().to_dict())  # each is a real field ...
    assert all(
        getattr(EnvConfig(), k) == v for k, v in NEUTRAL_ENV_DEFAULTS.items()
    )  # ... at its default
    two = Job(
        "s",
        "straight",
        0,
        {},
        EnvConfig(scenario="straight", n_uavs=2),
        TrainConfig(),
        {"episodes": 5, "seed": 0},
    )
    assert two.settings()["env"]["n_uavs"] == 2 and two.key != one.key


def test_a_new_warm_start_field_at_its_default_keeps_the_old_keys() -> None:
    """warm_start.leader_policy came after the per-size fleet sweep ran: at its default ("") it stays
    out of the key, so its circular jobs keep the key their results were made under (the record in
    policies/fleet_d2/); set, it is a new job."""
    old_circular = parse_spec(
        {
            "name": "fleet",
            "scenarios": ["circular"],
            "seeds": [0],
            "env": {"n_uavs": 2, "radio.shadowing_model": "spatial"},
            "train": {
                "episodes": 2000,
                "n_envs": 64,
                "batch_size": 2048,
                "n_steps": 128,
                "n_epochs": 10,
                "warm_start": {"teacher": "solo"},
            },
            "eval": {"episodes": 100, "seed": 0},
        }
    ).jobs()[0]
    record = json.loads(Path("policies/fleet_d2/fleet.sweep.json").read_text())
    assert old_circular.key == "a9cf0d725a16" and any(
        job["key"] == "a9cf0d725a16" for job in record["jobs"]
    )
    lead = parse_spec(
        {"seeds": [0], "env": {"n_uavs": 2}, "train": {"warm_start": {"teacher": "lead"}}}
    ).jobs()[0]
    led = parse_spec(
        {
            "seeds": [0],
            "env": {"n_uavs": 2},
            "train": {
                "warm_start": {"teacher": "lead", "leader_policy": "policies/spatial/no_move.zip"}
            },
        }
    ).jobs()[0]
    assert lead.key != led.key


@pytest.mark.parametrize(
    "warm_start",
    [{"teacher": "lead", "leader_policy": "leader.zip"}, {"policy": "leader.zip"}],
    ids=["leader_policy", "start_policy"],
)
def test_a_jobs_key_names_its_warm_start_files_bytes(
    tmp_path: Path, monkeypatch, warm_start: dict
) -> None:
    """The lead teacher's leader and a start policy are files: the key hashes their bytes, so a
    re-shipped file makes new jobs (a sweep record's figures of the old ones no longer count), and a
    job carries the hash to its worker unchanged. A file that is not there fails at load time,
    naming the path."""
    monkeypatch.chdir(tmp_path)
    leader = tmp_path / "leader.zip"
    data = {"seeds": [0], "env": {"n_uavs": 2}, "train": {"warm_start": warm_start}}

    def key() -> str:
        return parse_spec(data).jobs()[0].key

    leader.write_bytes(b"one")
    first = key()
    assert key() == first
    job = parse_spec(data).jobs()[0]
    leader.write_bytes(b"two")
    assert key() != first
    assert (
        Job.from_dict(job.to_dict()).key == first
    )  # the worker keeps the hash the job was made with
    leader.unlink()
    with pytest.raises(UserError, match="leader.zip: cannot read it"):
        key()


def test_a_jobs_json_of_before_the_start_policy_keeps_its_leaders_hash() -> None:
    """jobs.json written before warm_start.policy kept the leader's hash as ``leader_sha256``."""
    data = {
        "seeds": [0],
        "env": {"n_uavs": 2},
        "train": {
            "warm_start": {"teacher": "lead", "leader_policy": "policies/spatial/no_move.zip"}
        },
    }
    job = parse_spec(data).jobs()[0]
    old = {k: v for k, v in job.to_dict().items() if k != "file_sha256"}
    old["leader_sha256"] = job.file_sha256["leader_policy"]
    assert Job.from_dict(old).key == job.key


@pytest.mark.slow
def test_shipped_record_rebuilds_the_results_section_without_runs(tmp_path: Path) -> None:
    """--policies-out keeps the sweep's record beside the median seeds; where runs/ is gone (a fresh
    clone) docs/results.md's across-seed section is rebuilt from it, the same text and figures, and
    a recipe changed since the record finds no figures there."""

    (tmp_path / "tiny4.toml").write_text(TINY)
    (tmp_path / "changed.toml").write_text(TINY.replace("episodes = 4", "episodes = 5", 1))
    spec, changed = load_spec(tmp_path / "tiny4.toml"), load_spec(tmp_path / "changed.toml")
    run_sweep(spec, tmp_path / "runs", workers=0, progress=False, log=lambda _: None)
    sweep_dir, shipped = tmp_path / "runs" / "tiny4", tmp_path / "policies"
    export_median_policies(spec, sweep_dir, shipped)
    record = read_record(record_path(shipped, spec))
    assert set(record) == {job.key for job in spec.jobs()}
    for entry in record.values():
        assert "policy_zip" not in entry and "worker" not in entry
        assert not any(
            isinstance(v, list)
            for figures in entry["evaluation"].values()
            for v in figures.values()
        )
    assert summary_table(collect(spec, tmp_path / "gone", record), []) == summary_table(
        collect(spec, sweep_dir), []
    )

    sections = {}
    for name, source in (("runs", sweep_dir), ("record", tmp_path / "gone")):
        assets = tmp_path / f"assets_{name}"
        sections[name] = results_section(spec, source, assets, Path("results"), shipped)
        assert sorted(p.name for p in assets.iterdir()) == [
            "sweep_tiny4_learning_curves.png",
            "sweep_tiny4_throughput.png",
        ]
    assert sections["runs"] == sections["record"]
    assert (
        "| straight | 2/2 |" in sections["record"]
        and "(results/sweep_tiny4_throughput.png)" in sections["record"]
    )
    assert (
        f"in `{shipped}/` (the single-policy table above) are each scenario's median seed."
        in sections["runs"]
    )

    # a shipped policy chosen from another run (its seeds' figures differ): the section says which
    from uavlink.policies.manifest import read_zip_manifest, write_zip_manifest

    scenario = spec.scenarios[0]
    manifest = read_zip_manifest(shipped / f"{scenario}.zip")
    manifest["selection"]["seeds_mbps"] = {
        k: v + 0.01 for k, v in manifest["selection"]["seeds_mbps"].items()
    }
    write_zip_manifest(shipped / f"{scenario}.zip", manifest)
    text = results_section(spec, sweep_dir, tmp_path / "assets_moved", Path("results"), shipped)
    assert (
        f"not this run's median seeds for {scenario}: they were chosen from an earlier run" in text
    )
    assert "; elsewhere they are." in text

    with pytest.raises(UserError, match="not finished"):
        finished_rows(changed, tmp_path / "gone", record)


@pytest.mark.slow
def test_sweep_reruns_only_what_its_shipped_record_lacks(tmp_path: Path, capsys) -> None:
    """On a fresh clone (no runs/) `uavlink sweep FILE --policies-out DIR` counts the jobs of DIR's
    record as done: nothing runs and nothing shipped changes; a recipe changed for one scenario
    runs and re-ships that scenario only, and the record follows."""
    sweep_file, shipped = tmp_path / "tiny4.toml", tmp_path / "policies"
    sweep_file.write_text(TINY)

    def sweep(out_root: str, *extra: str) -> str:
        capsys.readouterr()
        assert (
            main(
                [
                    "sweep",
                    str(sweep_file),
                    "--out-root",
                    str(tmp_path / out_root),
                    "--workers",
                    "0",
                    "--no-progress",
                    "--policies-out",
                    str(shipped),
                    *extra,
                ]
            )
            == 0
        )
        return capsys.readouterr().err

    sweep("runs")
    before = {p.name: p.read_bytes() for p in shipped.iterdir()}
    assert "4 already done, 0 to run" in sweep("fresh")
    assert {p.name: p.read_bytes() for p in shipped.iterdir()} == before
    assert (
        main(
            [
                "sweep",
                str(sweep_file),
                "--out-root",
                str(tmp_path / "fresh2"),
                "--dry-run",
                "--policies-out",
                str(shipped),
            ]
        )
        == 0
    )
    assert capsys.readouterr().out.count("done (record)") == 4

    sweep_file.write_text(TINY + "[scenario_train.straight]\nepisodes = 5\n")
    changed = load_spec(sweep_file)
    assert "2 already done, 2 to run" in sweep("fresh3")
    after = {p.name: p.read_bytes() for p in shipped.iterdir()}
    assert (
        after["circular.zip"] == before["circular.zip"]
        and after["straight.zip"] != before["straight.zip"]
    )
    assert set(read_record(record_path(shipped, changed))) == {job.key for job in changed.jobs()}
    straight = json.loads((shipped / "straight.json").read_text())["selection"]["key"]
    assert straight in {job.key for job in changed.jobs() if job.scenario == "straight"}


@pytest.mark.slow
def test_record_out_keeps_the_jobs_figures_and_ships_no_policy(tmp_path: Path, capsys) -> None:
    """`--record-out DIR` writes the record of every finished job (a rerun over finished runs runs
    nothing) and copies no policy: the record of policies trained before stands beside them."""
    sweep_file, records = tmp_path / "tiny4.toml", tmp_path / "records"
    sweep_file.write_text(TINY)
    args = ["sweep", str(sweep_file), "--out-root", str(tmp_path / "runs"), "--workers", "0"]
    assert main([*args, "--no-progress"]) == 0
    capsys.readouterr()
    assert main([*args, "--no-progress", "--record-out", str(records)]) == 0
    assert "4 already done, 0 to run" in capsys.readouterr().err
    spec = load_spec(sweep_file)
    assert [p.name for p in records.iterdir()] == ["tiny4.sweep.json"]
    recorded = read_record(record_path(records, spec))
    assert set(recorded) == {job.key for job in spec.jobs()}
    job = spec.jobs()[0]
    run = json.loads((tmp_path / "runs" / "tiny4" / job.name / "result.json").read_text())
    for policy, scored in run["evaluation"].items():
        assert recorded[job.key]["evaluation"][policy]["mean_rate_mbps"] == scored["mean_rate_mbps"]


def test_the_fast_ppo_defaults_leave_the_shipped_jobs_as_they_were() -> None:
    """TrainConfig's PPO loop defaults changed (2026-12-02); the shipped sweep files pin the old loop, so
    their jobs keep the keys (and the settings) their results and policies were made under."""
    keys = {
        (spec, j.scenario, j.seed): j.key
        for spec in ("table1", "table1_spatial", "tiny")
        for j in load_spec(Path(f"sweeps/{spec}.toml")).jobs()
    }
    assert keys["table1", "straight", 1] == "ddda9676f0af"
    assert (
        keys["table1", "hotspot", 0] == "5a1875c9e4c8"
    )  # a [scenario_train] recipe: 256 envs, 128 steps
    assert keys["table1_spatial", "straight", 0] == "618c70d06377"
    assert keys["tiny", "straight", 0] in ("1d48d5ec3402", "77c334c765b2")  # the grid's two points
    job = load_spec(Path("sweeps/table1.toml")).jobs()[0].train
    assert (
        (job.n_envs, job.n_steps, job.batch_size, job.n_epochs)
        == (32, 128, 512, 10)
        != (
            TrainConfig().n_envs,
            TrainConfig().n_steps,
            TrainConfig().batch_size,
            TrainConfig().n_epochs,
        )
    )


def test_scenario_env_overrides_reach_only_their_scenario() -> None:
    base = {
        "name": "a",
        "scenarios": ["no_move", "straight"],
        "seeds": [0],
        "train": {"episodes": 4},
        "env": {"radio": {"shadowing_model": "spatial"}, "place_cell_m": 12.0},
    }
    plain = {j.scenario: j for j in parse_spec(base).jobs()}
    jobs = {
        j.scenario: j
        for j in parse_spec(
            {**base, "scenario_env": {"no_move": {"place_model": "kriging"}}}
        ).jobs()
    }
    assert jobs["straight"].key == plain["straight"].key
    assert jobs["no_move"].key != plain["no_move"].key
    assert jobs["no_move"].env.place_model == "kriging"
    assert jobs["straight"].env.place_model == "cells"
    with pytest.raises(SweepSpecError, match="place_model .*scenario no_move"):
        parse_spec({**base, "scenario_env": {"no_move": {"place_model": "gp"}}})
    with pytest.raises(SweepSpecError, match="scenario_env"):
        parse_spec(
            {**base, "scenario_env": {"no_move": {"r_max_m": 10.0}}, "grid": {"r_max_m": [10.0]}}
        )


def test_learning_curves_show_a_jobs_validation_curve_and_the_kept_point(
    tmp_path: Path, monkeypatch
) -> None:
    import matplotlib.pyplot as plt

    from uavlink.sweep.plots import plot_learning_curves

    kept = []
    monkeypatch.setattr(plt, "close", kept.append)  # keep the figure to read it back
    validation = {
        "curve": [[0, 6.3], [100, 6.35], [200, 6.2]],
        "kept_steps": 100,
        "kept_mbps": 6.35,
    }
    results = [
        {
            "seed": 0,
            "training": {"learning_curve": [[50, 6.1], [200, 6.3]], "validation": validation},
        },
        {"seed": 1, "training": {"learning_curve": [[50, 6.0], [200, 6.2]]}},
    ]  # a record before it
    plot_learning_curves([SettingRow("hotspot", {}, 2, results)], [], tmp_path / "curves.png")
    assert (tmp_path / "curves.png").stat().st_size > 0
    lines = kept[0].axes[0].get_lines()
    dashed = [line for line in lines if line.get_linestyle() == "--"]
    assert len(dashed) == 1 and list(dashed[0].get_xydata().tolist()) == validation["curve"]
    (star,) = [line for line in lines if line.get_marker() == "*"]
    assert star.get_xydata().tolist() == [[100, 6.35]]
    assert star.get_color() == dashed[0].get_color() == lines[0].get_color()  # the seed's colour
