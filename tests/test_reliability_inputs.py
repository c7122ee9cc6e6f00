"""Bad input into the vehicle: fuzzed and mutated MAVLink, out-of-range fields, COMMAND_ACK results
(fly's side: tests/test_reliability_fly_inputs.py).

Nothing may crash, nothing unsafe may be flown (the vehicle stays finite, inside the geofence and
under the vertical fence), every rejected input is counted and logged once, and every command
gets the right COMMAND_ACK. Hypothesis runs are bounded (examples, no deadline); everything stays
on loopback and in this process (the vehicle's loop is stepped by the test).
"""

from __future__ import annotations

import logging
import math
import os
import select
import socket
import time
from collections.abc import Iterator
from contextlib import contextmanager

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from support.mavlink_fuzz import FUZZ, corrupt, mutation
from support.mavlink_gcs import FAST_CLIMB_PARAMS

from sitl_stub.core.params import PARAM_DEFS
from sitl_stub.flight.vehicle import MAX_ALTITUDE_M
from sitl_stub.mavlink.server import ServerConfig, SitlServer
from sitl_stub.sim.payload import PayloadOptions
from sitl_stub.sim.radio_payload import RadioPayload
from uavlink.mavlink.dialect import mavlink
from uavlink.mavlink.radio_codec import RADIO_COMPONENT_ID
from uavlink.mavlink.rejects import drop_unfinished_frame, rescan_bad_frame
from uavlink.mavlink.signing import SigningGuard

pytestmark = pytest.mark.timeout(60)
R = mavlink  # MAV_RESULT_* names
ARM = mavlink.MAV_CMD_COMPONENT_ARM_DISARM
RESULTS = {
    R.MAV_RESULT_ACCEPTED,
    R.MAV_RESULT_TEMPORARILY_REJECTED,
    R.MAV_RESULT_DENIED,
    R.MAV_RESULT_UNSUPPORTED,
    R.MAV_RESULT_FAILED,
}


# --------------------------------------------------------------------------- the harness
class Vehicle:
    """An in-process SitlServer on udpin loopback, stepped by the test; a socket talks to it."""

    def __init__(self, server: SitlServer) -> None:
        self.server = server
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.setblocking(False)
        self.parser = mavlink.MAVLink(None)
        self.parser.robust_parsing = True
        self.acks: list = []

    def send(self, data: bytes, chunks: int = 1) -> None:
        step = max(1, math.ceil(len(data) / chunks))
        for i in range(0, max(len(data), 1), step):
            self.sock.sendto(data[i : i + step], self.server.address)
        # Loopback delivery is quick but not instant on a loaded machine: let the datagrams land
        # before the vehicle reads, and give an answer a moment before draining.
        select.select([self.server.conn.port], [], [], 0.05)
        for _ in range(2):
            self.server.iterate()
        select.select([self.sock], [], [], 0.005)
        self.drain()

    def drain(self) -> None:
        while True:
            try:
                data = self.sock.recv(65535)
            except BlockingIOError:
                return
            for m in self.parser.parse_buffer(data) or []:
                if m.get_type() == "COMMAND_ACK":
                    self.acks.append(m)

    def safe(self) -> None:
        """Nothing crashed and nothing unsafe is being flown."""
        s = self.server.vehicle.state()
        values = (
            s.north_m,
            s.east_m,
            s.down_m,
            s.vn_mps,
            s.ve_mps,
            s.vd_mps,
            s.yaw_rad,
            s.roll_rad,
            s.pitch_rad,
        )
        assert all(math.isfinite(v) for v in values), s
        fence = self.server.vehicle.fence_m
        assert abs(s.north_m) <= fence and abs(s.east_m) <= fence and s.max_abs_xy_m <= fence
        assert -MAX_ALTITUDE_M - 1e-6 <= s.down_m <= 1e-9, s
        sp = s.setpoint_ned
        assert sp is None or (all(math.isfinite(v) for v in sp) and -MAX_ALTITUDE_M <= sp[2] <= 0)
        for d in PARAM_DEFS:
            assert d.min <= self.server.params[d.name] <= d.max
        assert self.server.stats["handler_errors"] == 0
        assert self.server.error is None


@contextmanager
def vehicle(key: bytes | None = None, payload: bool = False) -> Iterator[Vehicle]:
    payloads = [RadioPayload(PayloadOptions("straight", 0))] if payload else []
    server = SitlServer(
        ServerConfig(
            connect="udpin:127.0.0.1:0", speed=20.0, params=FAST_CLIMB_PARAMS, signing_key=key
        ),
        payloads,
    )
    server.open()
    v = Vehicle(server)
    try:
        v.send(b"")  # say hello (the vehicle answers whoever sent something)
        yield v
    finally:
        v.sock.close()
        server.close()


def gcs_encoder(key: bytes | None = None, sysid: int = 245, compid: int = 190):
    enc = mavlink.MAVLink(None, sysid, compid)
    if key is not None:
        SigningGuard(key).attach(enc)
    return enc


def packets(enc) -> list[bytes]:
    """Valid packets of every kind the vehicle acts on."""
    msgs = [
        enc.command_long_encode(1, 0, ARM, 0, 1, 0, 0, 0, 0, 0, 0),
        enc.command_long_encode(1, 1, mavlink.MAV_CMD_NAV_TAKEOFF, 0, *[math.nan] * 7),
        enc.command_long_encode(1, 0, mavlink.MAV_CMD_DO_SET_MODE, 0, 129, 6, 0, 0, 0, 0, 0),
        enc.command_int_encode(1, 0, 6, mavlink.MAV_CMD_NAV_LAND, 0, 0, 0, 0, 0, 0, 0, 0, 0),
        enc.set_position_target_local_ned_encode(
            0, 1, 0, 1, 0xDF8, 50, -50, -20, 0, 0, 0, 0, 0, 0, 0, 0
        ),
        enc.param_set_encode(1, 0, b"MPC_XY_VEL_MAX", 3.0, 9),
        enc.set_mode_encode(1, 1, 4 << 16 | 2 << 24),
        enc.param_request_list_encode(1, 0),
        enc.mission_request_list_encode(1, 0, 0),
        enc.ping_encode(1, 2, 0, 0),
        enc.file_transfer_protocol_encode(0, 1, 1, [0, 0, 0, 4] + [0] * 247),
        enc.heartbeat_encode(6, 8, 0, 0, 4),
    ]
    return [bytes(m.pack(enc)) for m in msgs]


def _until_ack(v: Vehicle, packet, tries: int = 10, wait_s: float = 0.3) -> int:
    """Send ``packet()`` until an ACK comes back; returns how many were sent. Each try keeps stepping
    the vehicle for up to ``wait_s``: on a loaded machine a loopback datagram (or its ACK) can take
    longer than the two server iterations ``send`` runs. A packet held back behind the rest of a
    corrupted frame is answered once later bytes show that frame bad, so every try can get its ACK."""
    for sent in range(1, tries + 1):
        v.send(packet())
        deadline = time.monotonic() + wait_s
        while not v.acks and time.monotonic() < deadline:
            time.sleep(0.005)
            v.send(b"")
        if v.acks:
            return sent
    raise AssertionError("no ACK for an intact packet")


# -------------------------------------------------------------------- into the vehicle
def _parse_all(data: bytes, rescan: bool) -> list[str]:
    """Message types a robust pymavlink parser returns for ``data`` fed one byte at a time."""
    parser = mavlink.MAVLink(None)
    parser.robust_parsing = True
    kinds = []
    for byte in data:  # byte by byte: the parser's cross-datagram state is what matters
        msg = parser.parse_char(bytes([byte]))
        while msg is not None:
            kinds.append(msg.get_type())
            if rescan:
                rescan_bad_frame(parser, msg)
            msg = parser.parse_char(b"")
    return kinds


def test_rescan_puts_a_parser_back_in_frame_after_a_stray_marker() -> None:
    """A stray MAVLink 2 marker claiming a 48-byte payload (read as an unknown message, whose CRC
    pymavlink cannot check) swallows genuine packets behind it; rescanning loses none of them."""
    enc = gcs_encoder()
    command = bytes(enc.command_long_encode(1, 0, ARM, 0, 1, 0, 0, 0, 0, 0, 0).pack(enc))
    stream = b"\xfd\x30\x00" + command * 6
    assert _parse_all(stream, rescan=False).count("COMMAND_LONG") < 6
    kinds = _parse_all(stream, rescan=True)
    assert kinds.count("COMMAND_LONG") == 6 and "BAD_DATA" in kinds


def test_a_frame_one_datagram_left_unfinished_does_not_swallow_the_next() -> None:
    """UDP carries whole packets: garbage whose last start marker claims more bytes than its
    datagram has is dropped at the datagram's end, not completed from the genuine packets after it."""
    enc = gcs_encoder()
    command = bytes(enc.command_long_encode(1, 0, ARM, 0, 1, 0, 0, 0, 0, 0, 0).pack(enc))
    for framed in (False, True):
        parser = mavlink.MAVLink(None)
        parser.robust_parsing = True
        kinds = []
        for datagram in (b"\xfe" * 300, command, command, command):
            if framed:
                drop_unfinished_frame(parser)
            msg = parser.parse_char(datagram)
            while msg is not None:
                kinds.append(msg.get_type())
                rescan_bad_frame(parser, msg)
                msg = parser.parse_char(b"")
        assert (kinds.count("COMMAND_LONG") == 3) is framed, kinds
    # A whole frame still waiting, and a frame split across bytes of one datagram, are kept.
    parser = mavlink.MAVLink(None)
    parser.buf, parser.buf_index = bytearray(command), 0
    assert (
        drop_unfinished_frame(parser) == 0 and parser.parse_char(b"").get_type() == "COMMAND_LONG"
    )
    parser.buf, parser.buf_index = bytearray(command[:10]), 0
    assert drop_unfinished_frame(parser) == 10 and parser.buf_len() == 0
    # Behind whole frames still waiting (the parser takes one a datagram) and garbage, the
    # unfinished frame alone goes.
    parser.robust_parsing = True  # as both ends parse: garbage is BAD_DATA, not an exception
    parser.buf, parser.buf_index = bytearray(command + b"\x01\x02" + command + command[:10]), 0
    assert drop_unfinished_frame(parser) == 10
    kinds = []
    msg = parser.parse_char(b"")
    while msg is not None:
        kinds.append(msg.get_type())
        msg = parser.parse_char(b"")
    assert kinds == ["COMMAND_LONG", "BAD_DATA", "COMMAND_LONG"] and parser.buf_len() == 0, kinds


@pytest.mark.slow
def test_a_garbage_datagram_costs_the_vehicle_no_command() -> None:
    enc = gcs_encoder()

    def capabilities() -> bytes:
        request = mavlink.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES
        return bytes(enc.command_long_encode(1, 0, request, 0, 1, 0, 0, 0, 0, 0, 0).pack(enc))

    with vehicle() as v:
        v.send(b"\xfe" * 300)  # the last start marker claims 254 bytes the datagram does not have
        assert _until_ack(v, capabilities) == 1  # answered at once (six tries, 2.5 s, before)


@pytest.mark.slow
def test_random_bytes_into_the_vehicle() -> None:
    with vehicle() as v:

        @FUZZ
        @given(st.binary(max_size=400), st.integers(1, 4))
        def run(data: bytes, chunks: int) -> None:
            v.send(data, chunks)
            v.safe()
            assert not v.server.vehicle.armed

        run()
        # everything was counted, and each kind was logged once, not once per packet
        assert v.server.rejects.total > 0


@pytest.mark.slow
def test_mutated_packets_into_the_vehicle_are_counted_and_have_no_effect(caplog) -> None:
    caplog.set_level(logging.WARNING, logger="sitl_stub")
    with vehicle() as v:
        valid = packets(gcs_encoder())
        before = v.server.vehicle.state()

        @FUZZ
        @given(st.lists(mutation, min_size=1, max_size=4), st.integers(1, 3))
        def run(mutations, chunks: int) -> None:
            stream = b"".join(
                corrupt(valid[k], pos, flip) + junk for k, pos, flip, junk in mutations
            )
            v.send(stream, chunks)
            v.safe()

        run()
        after = v.server.vehicle.state()
        assert not after.armed and after.mode is before.mode
        assert after.setpoints_accepted == 0 and v.server.params["MPC_XY_VEL_MAX"] == 12.0
        assert not [a for a in v.acks if a.command in (ARM, mavlink.MAV_CMD_NAV_TAKEOFF)]
        counts = v.server.rejects.counts
        assert counts["bad_data"] > 20
        bad_data_logs = [r for r in caplog.records if "bad MAVLink data" in r.getMessage()]
        assert len(bad_data_logs) == 1  # logged once, counted every time
        # intact packets still work after all that (once the parser has skipped what is left of
        # a corrupted length: at most one maximum-size packet)
        _until_ack(v, lambda: valid[0])
        assert v.acks[-1].command == ARM and v.acks[-1].result == R.MAV_RESULT_ACCEPTED


@pytest.mark.slow
def test_mutated_signed_packets_never_pass_the_signing_check() -> None:
    key = os.urandom(32)
    with vehicle(key=key) as v:
        enc = gcs_encoder(key)

        @FUZZ
        @given(st.lists(mutation, min_size=1, max_size=3))
        def run(mutations) -> None:
            fresh = packets(enc)  # freshly signed: only the corruption can make them fail
            v.send(
                b"".join(corrupt(fresh[k], pos, flip) + junk for k, pos, flip, junk in mutations)
            )
            v.safe()

        run()
        assert not v.server.vehicle.armed and v.server.vehicle.offboard.setpoints_accepted == 0
        assert v.acks == []
        signing = v.server.signing.stats()
        assert signing["rejected_bad_signature"] + signing["rejected_unsigned"] > 50
        sent = _until_ack(v, lambda: packets(enc)[0])  # intact ones do, every one of them
        assert [(a.command, a.result) for a in v.acks] == [(ARM, R.MAV_RESULT_ACCEPTED)] * sent


finite_or_not = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True, width=32),
    st.sampled_from([math.nan, math.inf, -math.inf, 3.4e38, -3.4e38, 0.0, 1.0]),
)


@pytest.mark.slow
def test_out_of_range_fields_are_refused_or_clamped(caplog) -> None:
    caplog.set_level(logging.WARNING, logger="sitl_stub")
    with vehicle(payload=True) as v:
        enc = gcs_encoder()
        known = [ARM, 22, 21, 20, 176, 511, 512, 510, 520, 31337, 0, 65535]

        @FUZZ
        @given(
            st.one_of(st.sampled_from(known), st.integers(0, 65535)),
            st.lists(finite_or_not, min_size=7, max_size=7),
            st.sampled_from([0, 1, 158]),
            st.one_of(st.just(1), st.integers(0, 255)),
            st.one_of(st.sampled_from([0xDF8, 0x9F8, 0]), st.integers(0, 0xFFFF)),
            st.lists(finite_or_not, min_size=4, max_size=4),
            st.booleans(),
        )
        def run(command, params, component, frame, type_mask, sp, as_int) -> None:
            if as_int:
                msg = enc.command_int_encode(
                    1,
                    component,
                    frame,
                    command,
                    0,
                    0,
                    *params[:4],
                    int(np.clip(np.nan_to_num(params[4]), -(2**31), 2**31 - 1)),
                    int(np.clip(np.nan_to_num(params[5]), -(2**31), 2**31 - 1)),
                    params[6],
                )
            else:
                msg = enc.command_long_encode(1, component, command, 0, *params)
            before = len(v.acks)
            v.send(bytes(msg.pack(enc)))
            acks = v.acks[before:]
            assert len(acks) == 1 and acks[0].command == command  # exactly one answer
            assert acks[0].result in RESULTS
            known_ids = mavlink.enums["MAV_CMD"]
            if component == 158 or command not in known_ids or command in (0, 31337):
                assert acks[0].result == R.MAV_RESULT_UNSUPPORTED
            sp_msg = enc.set_position_target_local_ned_encode(
                0, 1, 0, frame, type_mask, *sp[:3], 0, 0, 0, 0, 0, 0, sp[3], 0
            )
            v.send(bytes(sp_msg.pack(enc)))
            v.safe()

        run()
        counts = v.server.rejects.counts
        assert counts["command_unsupported"] > 0 and counts["setpoint_frame"] > 0
        assert counts["setpoint_type_mask"] > 0 and counts["setpoint_not_finite"] > 0
        assert counts["command_denied"] > 0
    logged = [r.getMessage() for r in caplog.records]
    assert len([m for m in logged if "unsupported command 31337" in m]) <= 1


@pytest.mark.parametrize(
    "name,params,result",
    [
        ("unknown command", (31337, 0, 0, 0, 0, 0, 0, 0), R.MAV_RESULT_UNSUPPORTED),
        ("arm p1 NaN", (ARM, math.nan, 0, 0, 0, 0, 0, 0), R.MAV_RESULT_DENIED),
        ("takeoff while disarmed", (22, *[math.nan] * 7), R.MAV_RESULT_TEMPORARILY_REJECTED),
        ("mode with infinite base", (176, math.inf, 4, 3, 0, 0, 0, 0), R.MAV_RESULT_DENIED),
        ("unknown mode", (176, 1, 99, 0, 0, 0, 0, 0), R.MAV_RESULT_DENIED),
        ("manual mode (no RC)", (176, 1, 1, 0, 0, 0, 0, 0), R.MAV_RESULT_TEMPORARILY_REJECTED),
        ("message interval infinite", (511, 30, math.inf, 0, 0, 0, 0, 0), R.MAV_RESULT_DENIED),
        ("message interval negative", (511, 30, -0.5, 0, 0, 0, 0, 0), R.MAV_RESULT_DENIED),
        ("request unknown message", (512, 1e9, 0, 0, 0, 0, 0, 0), R.MAV_RESULT_DENIED),
        ("request NaN message", (512, math.nan, 0, 0, 0, 0, 0, 0), R.MAV_RESULT_DENIED),
        ("arm", (ARM, 1, 0, 0, 0, 0, 0, 0), R.MAV_RESULT_ACCEPTED),
    ],
)
def test_command_ack_results(name: str, params: tuple, result: int, caplog) -> None:
    caplog.set_level(logging.WARNING, logger="sitl_stub")
    with vehicle() as v:
        enc = gcs_encoder()
        for _ in range(3):  # the same refusal three times: three ACKs, one log line
            v.send(bytes(enc.command_long_encode(1, 0, params[0], 0, *params[1:]).pack(enc)))
        assert [(a.command, a.result) for a in v.acks] == [(params[0], result)] * 3
        if result != R.MAV_RESULT_ACCEPTED:
            assert sum(v.server.rejects.counts.values()) == 3
            assert len([r for r in caplog.records if "rejected input" in r.getMessage()]) == 1
        v.safe()


def test_a_failing_command_handler_answers_failed_and_the_vehicle_flies_on(monkeypatch) -> None:
    with vehicle(payload=True) as v:
        enc = gcs_encoder()

        def broken(req, wall):
            raise ZeroDivisionError("a bug")

        monkeypatch.setattr(v.server.commands, "handle", broken)
        v.send(bytes(enc.command_long_encode(1, 0, ARM, 0, 1, 0, 0, 0, 0, 0, 0).pack(enc)))
        assert [(a.command, a.result) for a in v.acks] == [(ARM, R.MAV_RESULT_FAILED)]
        monkeypatch.undo()
        v.server.stats["handler_errors"] = 0
        # a command for the radio payload component (it has no command handler)
        v.send(
            bytes(
                enc.command_long_encode(1, RADIO_COMPONENT_ID, ARM, 0, 1, 0, 0, 0, 0, 0, 0).pack(
                    enc
                )
            )
        )
        assert (v.acks[-1].command, v.acks[-1].result) == (ARM, R.MAV_RESULT_UNSUPPORTED)
        v.send(bytes(enc.command_long_encode(1, 0, ARM, 0, 1, 0, 0, 0, 0, 0, 0).pack(enc)))
        assert (v.acks[-1].command, v.acks[-1].result) == (ARM, R.MAV_RESULT_ACCEPTED)
        v.safe()
