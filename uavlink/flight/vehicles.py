"""The vehicles a flight flies: the embedded ``sitl_stub`` (``--fleet D`` for a fleet; one vehicle
per free loopback port) started for the flight, or those ``--connect URL1,URL2,...`` names (one URL
per vehicle, or one URL carrying every system); the checks of ``--seed``, ``--speed`` and
``--connect`` made before anything starts."""

from __future__ import annotations

import contextlib
import math
from collections.abc import Iterator
from pathlib import Path

from uavlink.config import EnvConfig, changed_settings, check_seed
from uavlink.errors import LinkError, UserError
from uavlink.mavlink.connection import free_udp_ports, normalize_connection

# Wall seconds for the embedded vehicle to open its links (as the heartbeat wait).
VEHICLE_START_S = 30.0


def check_vehicle_options(seed: int, speed: float) -> None:
    """``--seed`` and ``--speed``, checked before anything starts or is written: the embedded
    vehicle would refuse them too, but only after ``fly`` had made its --out folder."""
    check_seed(seed, "--seed")
    if not (math.isfinite(speed) and speed > 0):
        raise UserError(
            f"--speed must be a number > 0 (simulated seconds per wall second), got {speed:g}"
        )


@contextlib.contextmanager
def started_vehicle(connect: str | list[str], speed: float, args: list[str], log_path: Path):
    """The embedded vehicle (:func:`sitl_stub.launcher.vehicle_process`), waited for until its
    links are open: one that exits at start (a bad argument) ends ``fly`` at once with the
    vehicle's own error line (LinkError), not after a heartbeat wait that cannot succeed."""
    from sitl_stub.launcher import VehicleExited, vehicle_process

    with vehicle_process(connect, speed, args, log_path=log_path) as vehicle:
        try:
            vehicle.wait_started(VEHICLE_START_S)
        except VehicleExited as exc:
            raise LinkError(
                f"the embedded vehicle (sitl-stub) {exc} (its log: {log_path})"
            ) from None
        yield vehicle


def split_urls(connect: str) -> list[str]:
    """``URL1,URL2,...`` -> the URLs, each checked (UserError naming a bad one)."""
    urls = [u.strip() for u in connect.split(",")]
    for url in urls:
        try:
            normalize_connection(url)
        except ValueError as exc:
            raise UserError(f"--connect {url!r}: {exc}") from None
    return urls


def vehicle_args(
    cfg: EnvConfig, seed: int, lockstep: bool = False, signing_key_file: Path | None = None
) -> list[str]:
    """The ``sitl_stub`` options whose radio payload simulates ``cfg`` from episode 0 of ``seed``
    (``--fleet D`` for ``n_uavs`` = D > 1), in lockstep and signing with the key file when asked:
    the embedded vehicle's, and what a vehicle started by hand needs to serve a policy of ``cfg``
    (benchmarks/soak.py, the tests)."""
    args = ([] if cfg.n_uavs == 1 else ["--fleet", str(cfg.n_uavs)]) + (
        ["--lockstep"] if lockstep else []
    )
    args += [
        "--scenario",
        cfg.scenario,
        "--seed",
        str(seed),
        "--aoa-noise-deg",
        repr(float(cfg.radio.aoa_noise_deg)),
    ]
    for pair in changed_settings(cfg):
        if not pair.startswith(("n_uavs=", "scenario=")):
            args += ["--set", pair]
    return args + ([] if signing_key_file is None else ["--signing-key", str(signing_key_file)])


def embedded_lockstep(log_path: Path) -> dict:
    """How well the embedded vehicle held lockstep, from the stats it printed on exit to its log:
    ``lockstep_timeouts``, the frames it went on without a decision (a machine too busy to decide
    within 2 s of wall time), after which the flight no longer replays as its evaluation; None
    where it printed no stats or no lockstep counter."""
    from sitl_stub.launcher import exit_stats, lockstep_timeouts

    stats = exit_stats(log_path.read_text(errors="replace")) if log_path.exists() else None
    return {"lockstep_timeouts": None if stats is None else lockstep_timeouts(stats)}


@contextlib.contextmanager
def embedded_vehicles(
    cfg: EnvConfig,
    seed: int,
    speed: float,
    log_path: Path,
    signing_key_file: Path | None = None,
    lockstep: bool = False,
) -> Iterator[list[str]]:
    """The embedded SITL (:func:`started_vehicle`), its radio payload simulating ``cfg``
    (:func:`vehicle_args`; ``sitl_stub --fleet D`` for ``n_uavs`` = D > 1), vehicle i sending to free
    loopback port i; yields the URLs to listen on, in vehicle (UAV) order."""
    ports = free_udp_ports(cfg.n_uavs)
    args = vehicle_args(cfg, seed, lockstep, signing_key_file)
    with started_vehicle([f"udpout:127.0.0.1:{p}" for p in ports], speed, args, log_path):
        yield [f"udpin:127.0.0.1:{p}" for p in ports]
