"""Sweeps on Dask: a real scheduler and worker processes on 127.0.0.1, worker death, spec errors.

Jobs are tiny (512 env steps of PPO, 4 evaluation episodes per policy). Workers run with
UAVLINK_SWEEP_TRACE, so every job start and end is recorded per worker process.
"""

from __future__ import annotations

import json
import os
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
from uavlink.sweep.aggregate import t975  # noqa: E402
from uavlink.sweep.jobs import figures  # noqa: E402
from uavlink.sweep.runner import run_sweep  # noqa: E402
from uavlink.sweep.spec import load_spec, parse_spec  # noqa: E402

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
        self.scheduler = self._start(["scheduler", "--host", "127.0.0.1", "--port", str(self.port),
                                      "--no-dashboard"], base, logs / "scheduler.log")
        deadline = time.monotonic() + 30
        while True:
            try:
                socket.create_connection(("127.0.0.1", self.port), timeout=1).close()
                break
            except OSError:
                assert time.monotonic() < deadline, "scheduler did not start"
                time.sleep(0.1)
        self.workers = [self._start(["worker", self.address, "--nthreads", "1", "--host", "127.0.0.1",
                                     "--no-dashboard", "--no-nanny", "--name", f"w{i}"],
                                    base, logs / f"worker{i}.log") for i in range(n_workers)]
        from distributed import Client

        with Client(self.address, timeout="20s") as client:
            client.wait_for_workers(n_workers, timeout=40)

    def _start(self, args: list[str], env: dict[str, str], log: Path) -> subprocess.Popen:
        with log.open("w") as handle:
            proc = subprocess.Popen([sys.executable, "-m", "dask", *args], env=env, stdout=handle,
                                    stderr=subprocess.STDOUT)
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
        for proc in reversed(self.procs):
            if proc.poll() is None:
                proc.terminate()
        for proc in self.procs:
            try:
                proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                proc.kill()


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
    assert main(["sweep", str(sweep_file), "--scheduler", cluster.address, "--out-root", str(out),
                 "--no-progress"]) == 0
    spec = load_spec(sweep_file)
    keys = {job.key for job in spec.jobs()}
    results = _results(out / "tiny4")
    assert len(keys) == 4 and {r["key"] for r in results.values()} == keys

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
    sequential = run_sweep(spec, tmp_path / "seq", workers=0, progress=False, log=lambda _: None)
    assert sequential.finished == 4
    for name, result in _results(tmp_path / "seq" / "tiny4").items():
        assert result["worker"]["address"] == "in-process"
        assert figures(result) == figures(results[name])

    # A rerun does no work (it does not even need the scheduler); it can ship the median seeds.
    cluster.close()
    capsys.readouterr()
    policies = tmp_path / "policies"
    assert main(["sweep", str(sweep_file), "--scheduler", cluster.address, "--out-root", str(out),
                 "--no-progress", "--policies-out", str(policies)]) == 0
    assert "4 already done, 0 to run" in capsys.readouterr().err
    assert len(cluster.events()) == len(events)
    for scenario in ("straight", "circular"):
        manifest = json.loads((policies / f"{scenario}.json").read_text())
        seeds = {int(s): v for s, v in manifest["selection"]["seeds_mbps"].items()}
        assert manifest["selection"]["seed"] == min(seeds, key=lambda s: (seeds[s], s))  # lower median of 2
        assert zipfile.is_zipfile(policies / f"{scenario}.zip")
    # Shipping again writes the same bytes: re-shipped policies show no diff in git.
    shipped = {p.name: p.read_bytes() for p in policies.iterdir()}
    time.sleep(2.1)  # zip timestamps have a 2 s resolution
    assert main(["sweep", str(sweep_file), "--out-root", str(out), "--workers", "0", "--no-progress",
                 "--policies-out", str(policies)]) == 0
    assert {p.name: p.read_bytes() for p in policies.iterdir()} == shipped


@pytest.mark.slow
@pytest.mark.timeout(120)
def test_worker_killed_mid_job_is_retried_elsewhere(tmp_path: Path, cluster_factory) -> None:
    sweep_file = tmp_path / "tiny4.toml"
    sweep_file.write_text(TINY)
    cluster = cluster_factory(n_workers=2, env={"UAVLINK_SWEEP_DELAY_S": "2"})
    out = tmp_path / "runs"
    sweep = subprocess.Popen(
        [sys.executable, "-m", "uavlink.cli", "sweep", str(sweep_file), "--scheduler", cluster.address,
         "--out-root", str(out), "--no-progress"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 60
        victim = None
        while victim is None:
            assert time.monotonic() < deadline and sweep.poll() is None, "no job started"
            started = [pid for pid, event, _ in cluster.events() if event == "start"]
            victim = next((w for w in cluster.workers if w.pid in started), None)
            time.sleep(0.05)
        victim.send_signal(signal.SIGKILL)  # inside the job's 2 s delay: mid-job
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


BAD_SPECS = [
    ("frobnicate = 1\n", "'frobnicate'"),
    ("[train]\nlernin_rate = 0.1\n", "'lernin_rate'"),
    ("[train]\nepisodes = -3\n", "train.episodes"),
    ("[train]\nseed = 3\n", "'seed'"),
    ("[env]\nr_max_m = -1.0\n", "r_max_m"),
    ("[env]\n\"radio.shadowing\" = \"yes\"\n", "radio.shadowing"),
    ("[env]\nradio.no_such_field = 1\n", "radio.no_such_field"),
    ("[grid]\nlearning_rate = []\n", "'learning_rate'"),
    ("[grid]\n\"radio.aoa_noise_deg\" = [0.0, -5.0]\n", "radio.aoa_noise_deg"),
    ("[eval]\nepisodes = 0\n", "eval.episodes"),
    ("scenarios = [\"sideways\"]\n", "scenarios"),
    ("[scenario_train.circular]\nepisodes = 4\n", "'circular'"),  # not one of the sweep's scenarios
    ("[scenario_train.straight]\nradio.shadowing = false\n", "radio.shadowing"),  # train fields only
    ("[scenario_train.straight]\nn_envs = 0\n", "train.n_envs"),
    ("[train]\nwarm_start_epochs = 8.5\n", "warm_start_epochs"),  # optional, but an integer
    ("[train]\nwarm_start_epochs = 0\n", "warm_start_epochs"),
    ("[train]\nwarm_start_sinr_span_db = 0\n", "warm_start_sinr_span_db"),
    ("[scenario_train.straight]\nlearning_rate = 1e-4\n[grid]\nlearning_rate = [1e-4]\n", "'learning_rate'"),
]


@pytest.mark.timeout(30)
@pytest.mark.parametrize(("text", "named"), BAD_SPECS)
def test_bad_sweep_file_is_one_line_naming_the_key(tmp_path: Path, capsys, text: str, named: str) -> None:
    path = tmp_path / "bad.toml"
    path.write_text('name = "bad"\nscenarios = ["straight"]\n' * ("scenarios" not in text) + text)
    assert main(["sweep", str(path), "--out-root", str(tmp_path / "runs")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("uavlink sweep: error:") and named in err, err
    assert not (tmp_path / "runs").exists()  # nothing started


def test_job_keys_are_stable_and_grid_expands() -> None:
    spec = parse_spec({"name": "a", "scenarios": ["straight"], "seeds": 2,
                       "train": {"episodes": 4}, "env": {"radio": {"aoa_noise_deg": 5}},
                       "grid": {"learning_rate": [1e-4, 3e-4], "r_max_m": [10, 12.0]}})
    jobs = spec.jobs()
    assert len(jobs) == 8 and len({j.key for j in jobs}) == 8
    assert jobs[0].point == {"train.learning_rate": 1e-4, "env.r_max_m": 10.0}
    # Same settings, written differently (bare vs qualified key, int vs float, other sweep name): same key.
    same = parse_spec({"name": "b", "scenarios": ["straight"], "seeds": [0],
                       "train": {"episodes": 4, "learning_rate": 1e-4}, "env": {"r_max_m": 10,
                                                                               "aoa_noise_deg": 5.0}})
    assert same.jobs()[0].key == jobs[0].key
    assert jobs[0].env_config().radio.aoa_noise_deg == 5.0 and jobs[0].train_config().seed == 0
    # The default 12.0 written out is the same job as leaving r_max_m alone.
    assert parse_spec({"seeds": [0], "env": {"r_max_m": 12}}).jobs()[0].key == \
        parse_spec({"seeds": [0]}).jobs()[0].key


def test_scenario_train_overrides_reach_only_their_scenario() -> None:
    base = {"name": "a", "scenarios": ["straight", "hotspot"], "seeds": [0], "train": {"episodes": 4}}
    plain = {j.scenario: j for j in parse_spec(base).jobs()}
    spec = parse_spec({**base, "scenario_train": {"hotspot": {"n_envs": 8, "warm_start_teacher": "aoa",
                                                              "warm_start_shadow_gate_db": 1,
                                                              "warm_start_epochs": 80}}})
    jobs = {j.scenario: j for j in spec.jobs()}
    assert jobs["straight"].key == plain["straight"].key  # untouched scenario: same job
    hotspot = jobs["hotspot"].train_config()
    assert jobs["hotspot"].key != plain["hotspot"].key
    assert (hotspot.n_envs, hotspot.episodes, hotspot.warm_start_shadow_gate_db) == (8, 4, 1.0)
    assert hotspot.warm_start_epochs == 80 and isinstance(hotspot.warm_start_epochs, int)
    assert isinstance(hotspot.warm_start_shadow_gate_db, float)  # an optional number: 1 becomes 1.0
    assert jobs["straight"].train_config().n_envs == 32


def test_t_quantiles() -> None:
    assert t975(1) == pytest.approx(12.706) and t975(2) == pytest.approx(4.303)
    assert t975(40) == pytest.approx(2.021, abs=2e-3) and t975(1000) == pytest.approx(1.962, abs=2e-3)
