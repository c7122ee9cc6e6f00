"""`uavlink fly` end to end against the SITL vehicle over loopback UDP (real subprocesses)."""

from __future__ import annotations

import json
import shlex
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from support.cli import ROOT, UAVLINK, cli_json

from uavlink.config import EnvConfig
from uavlink.flight.loop import PolicyPilot
from uavlink.mavlink.connection import free_udp_port
from uavlink.mavlink.radio_codec import RadioReport


def run(args: list[str], timeout: float = 120) -> subprocess.CompletedProcess:
    return subprocess.run(args, capture_output=True, text=True, timeout=timeout, cwd=ROOT)


def fly_json(tmp_path: Path, *extra: str) -> dict:
    proc = run([*UAVLINK, "fly", "--no-picture", "--out", str(tmp_path), "--json", *extra])
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout)


def evaluate_one(policy: str, scenario: str, seed: int) -> float:
    return cli_json(
        "evaluate",
        "--policy",
        str(ROOT / policy),
        "--scenario",
        scenario,
        "--episodes",
        "1",
        "--seed",
        str(seed),
        "--json",
    )["mean_rate_mbps"]


@pytest.mark.slow
@pytest.mark.timeout(180)
@pytest.mark.parametrize(
    "policy,scenario,seed",
    [
        ("policies/circular.zip", "circular", 3),
        ("policies/straight.zip", "straight", 5),
        ("policies/spatial/circular.zip", "circular", 0),
    ],
)
def test_sim_to_sitl_parity(tmp_path: Path, policy: str, scenario: str, seed: int) -> None:
    """Flown through the SITL (whose payload simulates the policy's channel: the spatial policy's
    manifest carries radio.shadowing_model to it), a policy scores within 5 % of its evaluation."""
    # fly's loop and the evaluation in this process (the vehicle is a child as always): the policy
    # and its runtime load once, not in two children
    flown = cli_json(
        "fly",
        "--no-picture",
        "--out",
        str(tmp_path),
        "--json",
        "--policy",
        str(ROOT / policy),
        "--scenario",
        scenario,
        "--seed",
        str(seed),
    )
    simulated = evaluate_one(policy, scenario, seed)
    print(
        f"\n{scenario} seed {seed}: flown through SITL {flown['mean_rate_mbps']:.3f} Mbps, "
        f"uavlink evaluate {simulated:.3f} Mbps"
    )
    assert flown["frames"] == 128
    assert abs(flown["mean_rate_mbps"] - simulated) <= 0.05 * simulated
    assert flown["guarded_actions"] == 0 and flown["rejected_radio_reports"] == 0


@pytest.mark.slow
@pytest.mark.timeout(120)
def test_fly_aoa_baseline_writes_tlog_and_summary(tmp_path: Path) -> None:
    summary = fly_json(tmp_path, "--policy", "aoa", "--scenario", "straight", "--frames", "20")
    assert summary["frames"] == 20 and summary["policy"] == "aoa"
    assert json.loads((tmp_path / "summary.json").read_text()) == summary
    dump = run(
        [
            sys.executable,
            "-m",
            "pymavlink.tools.mavlogdump",
            "--types",
            "HEARTBEAT,SET_POSITION_TARGET_LOCAL_NED",
            str(tmp_path / "flight.tlog"),
        ]
    )
    assert dump.returncode == 0, dump.stderr
    assert "HEARTBEAT" in dump.stdout and "SET_POSITION_TARGET_LOCAL_NED" in dump.stdout


@pytest.mark.slow
@pytest.mark.timeout(120)
def test_fly_status_line_quiet_when_piped(tmp_path: Path) -> None:
    """The live `\r` status line is for a terminal; stderr to a pipe (a log, CI) gets none of it."""
    proc = run(
        [
            *UAVLINK,
            "fly",
            "--no-picture",
            "--policy",
            "aoa",
            "--scenario",
            "straight",
            "--frames",
            "3",
            "--out",
            str(tmp_path),
        ]
    )
    assert proc.returncode == 0, proc.stderr
    assert "\r" not in proc.stderr and "frame " not in proc.stderr, proc.stderr
    assert json.loads((tmp_path / "summary.json").read_text())["frames"] == 3


@pytest.mark.slow
@pytest.mark.timeout(120)
def test_fly_bare_port_connect(tmp_path: Path) -> None:
    """The design card's `--connect udp:PORT` (listen on all interfaces) against a separate SITL."""
    port = free_udp_port()
    sitl = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "sitl_stub",
            "--scenario",
            "no_move",
            "--seed",
            "1",
            "--connect",
            f"udpout:127.0.0.1:{port}",
            "--speed",
            "20",
        ],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        cwd=ROOT,
    )
    try:
        summary = fly_json(
            tmp_path, "--policy", "static", "--connect", f"udp:{port}", "--frames", "10"
        )
    finally:
        sitl.terminate()
        sitl.wait(timeout=10)
    assert summary["frames"] == 10
    assert summary["mean_rate_mbps"] > 7.0  # hovering over the no_move cluster


@pytest.mark.parametrize(
    "policy,message",
    [
        ("missing.zip", "no such file"),
        ("oracle", "cannot fly"),
    ],
)
def test_fly_refuses_bad_policy_before_arming(tmp_path: Path, policy: str, message: str) -> None:
    proc = run([*UAVLINK, "fly", "--policy", policy, "--out", str(tmp_path)], timeout=60)
    assert proc.returncode == 2
    assert message in proc.stderr and "Traceback" not in proc.stderr
    assert not (tmp_path / "flight.tlog").exists(), "nothing was flown"


def test_fly_on_a_port_another_program_holds_says_so_in_one_line(tmp_path: Path) -> None:
    """QGroundControl listens on 14550, the default: a second listener there is the user's to move.
    The holder shares its port (SO_REUSEADDR, as pymavlink and ground stations bind): before, a
    second pymavlink listener then opened without error and heard nothing."""
    import socket

    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as holder:
        holder.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        holder.bind(("127.0.0.1", 0))
        port = holder.getsockname()[1]
        rc, line, _ = _fly_aoa_over(f"udpin:127.0.0.1:{port}", tmp_path)
    assert rc == 2 and f"cannot open udpin:127.0.0.1:{port}" in line
    assert "another ground station" in line
    assert not (tmp_path / "flight.tlog").exists(), "nothing was flown"


def test_fly_to_a_tcp_port_nobody_listens_on_is_a_link_failure_in_one_line(tmp_path: Path) -> None:
    """A refused TCP connect: exit 1 (the vehicle is not there, not bad input), one line on stderr
    that asks whether the vehicle runs, and nothing of pymavlink's retries on stdout."""
    from uavlink.mavlink.connection import free_udp_port

    port = free_udp_port()  # a port below the ephemeral range that no test listens on over TCP
    rc, line, stdout = _fly_aoa_over(f"tcp:127.0.0.1:{port}", tmp_path)
    assert (
        rc == 1 and "cannot connect to tcp:127.0.0.1" in line and "is the vehicle running" in line
    )
    assert stdout == ""


def _fly_aoa_over(url: str, out: Path) -> tuple[int, str, str]:
    """`uavlink fly --policy aoa --connect URL` as a process: its exit status, its one stderr line
    (no traceback) and its stdout."""
    proc = run(
        [*UAVLINK, "fly", "--policy", "aoa", "--connect", url, "--out", str(out)], timeout=60
    )
    assert "Traceback" not in proc.stderr, proc.stderr
    [line] = proc.stderr.strip().splitlines()
    return proc.returncode, line, proc.stdout


class _BadPolicy:
    name, layout, needs_truth = "bad", None, False

    def __init__(self, action):
        self.action = action

    def act(self, obs, truth=None):
        return np.array([self.action], dtype=float)


@pytest.mark.parametrize("action", [[np.nan, 0.0], [np.inf, 0.0], [3.0, 0.0]])
def test_policy_output_guard_holds(action) -> None:
    pilot = PolicyPilot(_BadPolicy(action), EnvConfig())
    report = RadioReport(frame=0, time_s=0.0, sinr_db=np.full(10, 10.0), aoa_deg=np.zeros(10))
    move = pilot.decide(report, np.zeros(2), first=True)
    assert np.array_equal(move, np.zeros(2)) and pilot.guarded == 1


@pytest.mark.slow
@pytest.mark.timeout(120)
def test_fly_policy_from_python_returns_the_summary_the_replay_reproduces(tmp_path: Path) -> None:
    """``fly_policy(FlyOptions(...))`` flies a shipped policy by name, writes the same summary it
    returns, and in lockstep its frames score as the summary's replay command evaluates them."""
    from uavlink.flight import FlyOptions, fly_policy

    options = FlyOptions(policy="circular", seed=4, frames=6, lockstep=True, out=tmp_path)
    summary = fly_policy(options)
    assert summary["completed"], summary["reason"]
    assert summary["frames"] == 6 and summary["policy"] == str(ROOT / "policies/circular.zip")
    assert json.loads((tmp_path / "summary.json").read_text()) == summary
    replay = shlex.split(summary["replay"])[1:]
    assert replay[:2] == ["evaluate", "--policy"]
    evaluated = cli_json(*replay, "--json")["mean_rate_mbps"]
    assert summary["mean_rate_mbps"] == pytest.approx(evaluated, rel=1e-4)
