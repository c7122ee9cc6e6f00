"""Test helpers that talk to a vehicle process as a ground station would: :class:`Gcs` (a stock
pymavlink client), :func:`wait_for_vehicle`, :func:`parse_vehicle_stats` (the ``sitl-stub: stats``
line a vehicle prints on exit), :func:`param_args` (a vehicle's ``--param`` arguments) and a quick
climb: :data:`FAST_CLIMB_PARAMS`, as vehicle args :data:`FAST_TAKEOFF`."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

from sitl_stub.launcher import exit_stats


def param_args(params: dict[str, float]) -> tuple[str, ...]:
    """A vehicle's ``--param NAME=VALUE`` arguments for ``params``."""
    return tuple(a for name, value in params.items() for a in ("--param", f"{name}={value:g}"))


FAST_CLIMB_PARAMS = {"MPC_TKO_SPEED": 5.0, "MPC_Z_VEL_MAX_UP": 5.0}  # 95 m in ~20 s sim
FAST_TAKEOFF = param_args(FAST_CLIMB_PARAMS)


class Gcs:
    """A pymavlink ground station on ``udpout`` to a listening vehicle, optionally signing with
    pymavlink's own ``setup_signing`` (a stock client). It records the autopilot's heartbeats
    (wall time, custom_mode, armed) and every COMMAND_ACK addressed to it."""

    def __init__(
        self, port: int, system_id: int = 245, component_id: int = 190, key: bytes | None = None
    ) -> None:
        from uavlink.mavlink.dialect import mavutil

        self.conn = mavutil.mavlink_connection(
            f"udpout:127.0.0.1:{port}",
            source_system=system_id,
            source_component=component_id,
            dialect="common",
        )
        if key is not None:
            self.conn.setup_signing(key, sign_outgoing=True)
        self.mav = self.conn.mav
        self.id = (system_id, component_id)
        self.modes: list[tuple[float, int, bool]] = []
        self.acks: list[Any] = []
        self.texts: list[str] = []
        self.last: dict[str, Any] = {}
        self._hb = 0.0

    def close(self) -> None:
        self.conn.close()

    def pump(self, timeout: float = 0.02) -> None:
        """Send our heartbeat (twice a second) and handle what arrived within ``timeout``."""
        now = time.monotonic()
        if now - self._hb >= 0.5:
            self._hb = now
            self.mav.heartbeat_send(6, 8, 0, 0, 4)  # MAV_TYPE_GCS, MAV_AUTOPILOT_INVALID, ACTIVE
        m = self.conn.recv_match(blocking=True, timeout=timeout)
        while m is not None:
            self._record(m)
            m = self.conn.recv_match(blocking=False)

    def _record(self, m: Any) -> None:
        kind = m.get_type()
        if kind == "BAD_DATA" or m.get_srcSystem() != 1:
            return
        self.last[kind] = m
        if kind == "HEARTBEAT" and m.get_srcComponent() == 1:
            armed = bool(m.base_mode & 128)
            if not self.modes or self.modes[-1][1:] != (m.custom_mode, armed):
                self.modes.append((time.monotonic(), m.custom_mode, armed))
        elif kind == "COMMAND_ACK" and (m.target_system, m.target_component) == self.id:
            self.acks.append(m)
        elif kind == "STATUSTEXT":
            self.texts.append(m.text)

    def wait(self, condition: Callable[[], bool], timeout: float, what: str) -> None:
        deadline = time.monotonic() + timeout
        while not condition():
            if time.monotonic() > deadline:
                raise AssertionError(f"timed out after {timeout} s waiting for {what}")
            self.pump()

    def wait_message(
        self, kind: str, timeout: float = 10.0, pred: Callable[[Any], bool] = lambda m: True
    ) -> Any:
        self.last.pop(kind, None)
        self.wait(lambda: kind in self.last and pred(self.last[kind]), timeout, kind)
        return self.last[kind]

    @property
    def mode(self) -> tuple[int, bool] | None:
        return self.modes[-1][1:] if self.modes else None

    def command(self, cmd: int, *params: float, wait_s: float = 3.0) -> int | None:
        """COMMAND_LONG (target component 0, like pymavlink GCSs); the ACK result or None."""
        p = list(params) + [0.0] * (7 - len(params))
        before = len(self.acks)
        self.mav.command_long_send(1, 0, cmd, 0, *p)
        deadline = time.monotonic() + wait_s
        while time.monotonic() < deadline:
            self.pump()
            for ack in self.acks[before:]:
                if ack.command == cmd:
                    return int(ack.result)
        return None

    def acks_for(self, cmd: int) -> list[Any]:
        return [a for a in self.acks if a.command == cmd]


def wait_for_vehicle(gcs: Gcs, vehicle: Any, timeout: float = 20.0) -> None:
    """Pump ``gcs`` until the vehicle's heartbeat arrives (fails early if the process died)."""
    deadline = time.monotonic() + timeout
    while gcs.mode is None:
        assert vehicle.proc.poll() is None, vehicle.output()
        assert time.monotonic() < deadline, "the vehicle never answered"
        gcs.pump(0.1)


def parse_vehicle_stats(output: str) -> dict[str, Any]:
    stats = exit_stats(output)
    assert stats is not None, f"no stats line in the vehicle's output:\n{output[-2000:]}"
    return stats
