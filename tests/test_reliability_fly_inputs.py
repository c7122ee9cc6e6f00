"""Bad input into ``uavlink fly``'s link: fuzzed and mutated vehicle telemetry, bad radio reports,
and the policy output guard in flight (the vehicle's side: tests/test_reliability_inputs.py).

Nothing may crash, nothing unusable may reach the flight loop, and every rejected input is counted
and logged once. Everything stays on loopback and in this process.
"""

from __future__ import annotations

import logging
import math
import socket
import threading
from collections.abc import Iterator
from contextlib import contextmanager

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from support.mavlink_fuzz import FUZZ, corrupt, mutation
from support.mavlink_gcs import FAST_CLIMB_PARAMS

from sitl_stub.mavlink.server import ServerConfig, SitlServer
from sitl_stub.sim.payload import PayloadOptions
from sitl_stub.sim.radio_payload import RadioPayload
from uavlink.config import EnvConfig
from uavlink.flight.link import VehicleLink
from uavlink.flight.loop import LoopConfig, PolicyPilot, fly_vehicle
from uavlink.flight.radio_source import MavlinkRadioSource
from uavlink.mavlink.connection import free_udp_port
from uavlink.mavlink.dialect import mavlink
from uavlink.mavlink.radio_codec import RADIO_COMPONENT_ID, encode_readings, encode_score

pytestmark = pytest.mark.timeout(60)
ARM = mavlink.MAV_CMD_COMPONENT_ARM_DISARM


# -------------------------------------------------------------------- into fly's link
def _vehicle_packets() -> list[bytes]:
    enc = mavlink.MAVLink(None, 1, 1)
    radio = mavlink.MAVLink(None, 1, RADIO_COMPONENT_ID)
    readings = encode_readings(np.full(10, 12.0), np.zeros(10), True)
    msgs = [
        (enc, enc.heartbeat_encode(2, 12, 1 | 128, 6 << 16, 4)),
        (enc, enc.local_position_ned_encode(1000, 10, 20, -95, 0, 0, 0)),
        (enc, enc.extended_sys_state_encode(0, 2)),
        (enc, enc.command_ack_encode(ARM, 0, 0, 0, 255, 191)),
        (enc, enc.param_value_encode(b"MIS_TAKEOFF_ALT", 95.0, 9, 13, 11)),
        (radio, radio.debug_float_array_encode(0, b"UL_RADIO", 3, readings)),
        (
            radio,
            radio.debug_float_array_encode(0, b"UL_SCORE", 3, encode_score(np.full(10, 5e6), 0.5)),
        ),
    ]
    return [bytes(m.pack(e)) for e, m in msgs]


@contextmanager
def fly_link() -> Iterator[tuple[VehicleLink, MavlinkRadioSource, socket.socket, list]]:
    port = free_udp_port()
    link = VehicleLink(
        f"udpin:127.0.0.1:{port}", target_system=1
    )  # the packets below are system 1's
    source = MavlinkRadioSource(10)
    scores: list = []
    link.on_radio, link.on_score = source.feed, scores.append
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        yield link, source, sock, scores
    finally:
        sock.close()
        link.close()


def _deliver(link: VehicleLink, sock: socket.socket, data: bytes) -> None:
    sock.sendto(data, link.conn.port.getsockname())
    link.poll(0.0)
    link.poll(0.0)


def _finite_status(link: VehicleLink) -> None:
    s = link.status
    assert all(math.isfinite(v) for v in (s.north_m, s.east_m, s.down_m))


@pytest.mark.slow
def test_random_and_mutated_bytes_into_fly() -> None:
    with fly_link() as (link, source, sock, scores):
        valid = _vehicle_packets()

        @FUZZ
        @given(
            st.one_of(
                st.binary(max_size=300),
                st.lists(
                    mutation.map(lambda m: (m[0] % len(valid), *m[1:])), min_size=1, max_size=4
                ),
            )
        )
        def run(data) -> None:
            if isinstance(data, list):
                data = b"".join(corrupt(valid[k], pos, flip) + junk for k, pos, flip, junk in data)
            _deliver(link, sock, data)
            _finite_status(link)
            assert source.take_reports() == [] and scores == []  # nothing corrupted got through

        run()
        assert link.status.heartbeats == 0 and link.rejects.total > 0
        for _ in range(3):  # intact packets still work (after what is left of a corrupted length)
            for pkt in valid:
                _deliver(link, sock, pkt)
        assert link.status.heartbeats >= 2 and link.status.armed and link.status.offboard
        assert (link.status.north_m, link.status.down_m) == (10.0, -95.0)
        assert len(source.take_reports()) >= 2 and len(scores) >= 2


def test_fly_rejects_bad_telemetry_and_radio_reports_counts_and_logs_once(caplog) -> None:
    caplog.set_level(logging.WARNING)
    with fly_link() as (link, source, sock, scores):
        enc = mavlink.MAVLink(None, 1, 1)
        radio = mavlink.MAVLink(None, 1, RADIO_COMPONENT_ID)
        _deliver(
            link, sock, bytes(enc.local_position_ned_encode(1000, 1, 2, -3, 0, 0, 0).pack(enc))
        )
        good = encode_readings(np.full(10, 12.0), np.zeros(10), True)
        wrong_count = encode_readings(np.full(7, 12.0), np.zeros(7), True)
        nan_sinr = list(good)
        nan_sinr[3] = math.nan
        inf_aoa = list(good)
        inf_aoa[12] = math.inf
        for _ in range(3):
            for data in (wrong_count, nan_sinr, inf_aoa):
                _deliver(
                    link,
                    sock,
                    bytes(radio.debug_float_array_encode(0, b"UL_RADIO", 5, data).pack(radio)),
                )
            _deliver(
                link,
                sock,
                bytes(
                    radio.debug_float_array_encode(
                        0, b"UL_SCORE", 5, encode_score(np.full(10, np.nan), 0.5)
                    ).pack(radio)
                ),
            )
            _deliver(
                link,
                sock,
                bytes(
                    enc.local_position_ned_encode(2000, math.nan, math.inf, -95, 0, 0, 0).pack(enc)
                ),
            )
        assert source.rejected == 9 and source.take_reports() == [] and scores == []
        assert (
            link.rejects.counts["position_not_finite"] == 3
            and link.rejects.counts["radio_score"] == 3
        )
        assert (link.status.north_m, link.status.east_m, link.status.down_m) == (1.0, 2.0, -3.0)
    messages = [r.getMessage() for r in caplog.records]
    assert len([m for m in messages if "policy expects 10" in m]) == 1
    assert len([m for m in messages if "NaN or infinite" in m]) == 1
    assert len([m for m in messages if "LOCAL_POSITION_NED with NaN" in m]) == 1
    assert len([m for m in messages if "radio score" in m]) == 1


# ------------------------------------------------------------------ policy output guard
class _NanPolicy:
    name, layout, needs_truth = "nan-policy", None, False

    def act(self, obs, truth=None):
        return np.array([[math.nan, 0.5]])


@pytest.mark.slow
@pytest.mark.timeout(60)
def test_policy_output_guard_in_flight_holds_position_and_logs_clearly(caplog) -> None:
    caplog.set_level(logging.WARNING, logger="uavlink.flight.loop")
    cfg = EnvConfig().replace(scenario="straight").validate()
    server = SitlServer(
        ServerConfig(connect="udpin:127.0.0.1:0", speed=20.0, params=FAST_CLIMB_PARAMS),
        [RadioPayload(PayloadOptions("straight", 0))],
    ).start()
    link = None
    try:
        host, port = server.address
        link = VehicleLink(f"udpout:{host}:{port}")
        pilot = PolicyPilot(_NanPolicy(), cfg)
        done: dict = {}
        t = threading.Thread(
            target=lambda: done.setdefault(
                "r", fly_vehicle(link, pilot, cfg, LoopConfig(frames=8, land=False))
            ),
            daemon=True,
        )
        t.start()
        t.join(45)
        assert "r" in done, "the flight did not finish"
        result = done["r"]
        state = server.state()
    finally:
        if link is not None:
            link.close()
        server.stop()
    # Every decision is guarded; under load a backlog of reports is observed, not decided.
    assert result.decisions >= 4 and result.guarded_actions == result.decisions
    assert result.decisions + result.stale_reports == 8
    assert result.frames_missed == result.stale_reports  # no report lost: only late ones undecided
    assert state.armed and state.max_abs_xy_m < 1.0  # took off at home and held there
    lines = [r.getMessage() for r in caplog.records if "policy output guard" in r.getMessage()]
    assert len(lines) == result.guarded_actions
    assert (
        "policy 'nan-policy' returned an unusable action [[nan, 0.5]] (NaN/infinite): "
        "holding position" in lines[0]
    )
