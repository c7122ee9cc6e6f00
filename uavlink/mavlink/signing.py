"""MAVLink 2 message signing for both ends of the flight link (``uavlink fly`` and ``sitl_stub``).

The wire format is MAVLink 2's (``incompat_flags`` bit 0, then link id, a 48-bit timestamp in
10 us units since 2015-01-01 00:00 UTC, and the first 6 bytes of SHA-256(key + packet)); packets
are built by pymavlink. Verification is our own, plugged into pymavlink's parser in place of its
``check_signature``, because pymavlink records a stream's timestamp *before* it checks the
signature: one forged packet with a far-future timestamp would then make every genuine packet of
that stream look like a replay. Here a packet counts only if its signature is right, and only then
is its timestamp recorded. The rules (MAVLink's signing spec):

- A stream is (link id, system id, component id). Its timestamps must rise: a packet whose
  timestamp is not newer than the last accepted one of its stream is a replay and is refused.
- A stream not seen before is accepted when its timestamp is at most 60 s behind the receiver's
  clock (wall time, or the newest timestamp accepted, whichever is later).
- With a key configured, unsigned packets are refused (PX4 with MAV_SIGN_CFG=2 does the same).

Outgoing timestamps follow the wall clock (``max(last + 1, now)``), so a receiver that (re)starts
later still accepts the stream; pymavlink alone would count +1 per packet from the start time and
fall behind wall time within minutes.

Rejected packets never reach the application: pymavlink turns them into BAD_DATA. Each is counted
by reason in :attr:`SigningGuard.rejected`; the first of each reason is logged (and passed to
``on_first_reject``, e.g. for a STATUSTEXT).
"""

from __future__ import annotations

import argparse
import hashlib
import hmac
import logging
import os
import stat
import time
from collections import Counter
from collections.abc import Callable
from pathlib import Path
from typing import Any

from uavlink.errors import UserError

log = logging.getLogger(__name__)

KEY_LEN = 32
EPOCH_2015_UNIX_S = 1_420_070_400
TICKS_PER_S = 100_000  # the timestamp unit is 10 us
NEW_STREAM_WINDOW_TICKS = 60 * TICKS_PER_S  # MAVLink: a new stream may be 1 minute old
SIGNATURE_BLOCK_LEN = 13  # link id (1) + timestamp (6) + signature (6)

#: Reasons a packet is refused, as counted in :attr:`SigningGuard.rejected`.
REASONS = {
    "unsigned": "unsigned packet",
    "bad_signature": "wrong signature (not signed with our key)",
    "replay": "replayed or reordered packet (timestamp not newer than the stream's last)",
    "stale_stream": "new stream more than 60 s behind our clock (old capture?)",
}


class SigningKeyError(UserError):
    """A key file that cannot be used; the message says why (one line)."""


def signing_timestamp(unix_s: float | None = None) -> int:
    """MAVLink signing time: 10 us units since 2015-01-01 00:00 UTC (from ``time.time()``)."""
    now = time.time() if unix_s is None else unix_s
    return max(int((now - EPOCH_2015_UNIX_S) * TICKS_PER_S), 0)


def key_file_argument(text: str) -> str:
    """argparse type of ``--signing-key`` on both ends: an empty name is refused rather than read
    as no key, so ``--signing-key "$KEY"`` with the variable unset cannot fly an open link."""
    if not text.strip():
        raise argparse.ArgumentTypeError(
            "an empty file name (an unset variable?); leave the option out to fly unsigned"
        )
    return text


def load_key(path: str | os.PathLike[str]) -> bytes:
    """The 32 raw bytes of a key file; SigningKeyError when missing or not exactly 32 bytes."""
    p = Path(path)
    try:
        key = p.read_bytes()
    except OSError as exc:
        raise SigningKeyError(f"cannot read signing key {p}: {exc.strerror or exc}") from None
    if len(key) != KEY_LEN:
        raise SigningKeyError(
            f"signing key {p} has {len(key)} bytes; a key is {KEY_LEN} raw bytes "
            "(make one with `uavlink keygen --out FILE`)"
        )
    try:
        mode = p.stat().st_mode
    except OSError:  # pragma: no cover - it was just read
        mode = 0
    if mode & (stat.S_IRWXG | stat.S_IRWXO):
        log.warning(
            "signing key %s is readable by other users (mode %o); chmod 600 it",
            p,
            stat.S_IMODE(mode),
        )
    return key


def write_key(path: str | os.PathLike[str]) -> Path:
    """Write a new random key (``os.urandom``) to a new file with mode 0600; never overwrites
    (FileExistsError)."""
    p = Path(path)
    fd = os.open(p, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    try:
        os.write(fd, os.urandom(KEY_LEN))
        os.fchmod(fd, 0o600)  # whatever the umask
    finally:
        os.close(fd)
    return p


def signature_ok(key: bytes, packet: bytes | bytearray) -> bool:
    """True when a signed MAVLink 2 packet's 6-byte signature matches ``key``."""
    if len(packet) < SIGNATURE_BLOCK_LEN + 12:
        return False
    expected = hashlib.sha256(bytes(key) + bytes(packet[:-6])).digest()[:6]
    return hmac.compare_digest(expected, bytes(packet[-6:]))


def packet_timestamp(packet: bytes | bytearray) -> int:
    """The signing timestamp of a signed packet."""
    return int.from_bytes(bytes(packet[-12:-6]), "little")


class SigningGuard:
    """Signs what one or more pymavlink ``MAVLink`` objects send and verifies what one of them parses.

    ``attach(mav)`` makes ``mav`` sign every packet it sends (timestamps from the wall clock) and,
    when ``mav`` also parses input, refuse every packet that is unsigned, wrongly signed, replayed
    or from a stream too old to be new. ``clock`` returns Unix seconds (tests pass a fake one).
    """

    def __init__(
        self,
        key: bytes,
        link_id: int = 0,
        clock: Callable[[], float] = time.time,
        on_first_reject: Callable[[str, str], None] | None = None,
    ) -> None:
        if len(key) != KEY_LEN:
            raise SigningKeyError(f"a signing key is {KEY_LEN} bytes, got {len(key)}")
        if not 0 <= link_id <= 255:
            raise ValueError(f"link_id must be in 0..255, got {link_id}")
        self.key = bytes(key)
        self.link_id = link_id
        self.clock = clock
        self.on_first_reject = on_first_reject
        self.accepted = 0
        self.rejected: Counter[str] = Counter({reason: 0 for reason in REASONS})
        self.streams: dict[tuple[int, int, int], int] = {}
        self._newest_accepted = 0
        self._pending: str | None = None
        self._attached: list[Any] = []

    # ------------------------------------------------------------------ attach
    def attach(self, mav: Any) -> Any:
        """Sign ``mav``'s output and verify its input; returns ``mav``."""
        s = mav.signing
        s.secret_key = self.key
        s.sign_outgoing = True
        s.link_id = self.link_id
        s.timestamp = signing_timestamp(self.clock())
        s.allow_unsigned_callback = self._refuse
        mav.check_signature = self._check  # replaces pymavlink's (which records before verifying)
        send = mav.send

        def send_signed(msg: Any, force_mavlink1: bool = False) -> None:
            # The signing clock tracks wall time; +1 keeps it strictly rising within a burst.
            s.timestamp = max(s.timestamp, signing_timestamp(self.clock()))
            send(msg, force_mavlink1=False)

        mav.send = send_signed
        self._attached.append(mav)
        return mav

    def is_attached(self, mav: Any) -> bool:
        """True when ``mav`` is one this guard signs for (a replaced parser would not be)."""
        return any(m is mav for m in self._attached)

    # ----------------------------------------------------------------- verify
    def now_ticks(self) -> int:
        """The receiver's clock for the new-stream rule: wall time, never behind what we accepted."""
        return max(signing_timestamp(self.clock()), self._newest_accepted)

    def check(self, packet: bytes | bytearray, src_system: int, src_component: int) -> str | None:
        """None when a signed packet is acceptable (and then its timestamp is recorded), else the
        reason (a key of :data:`REASONS`). The signature is checked before anything is recorded."""
        if not signature_ok(self.key, packet):
            return "bad_signature"
        ts = packet_timestamp(packet)
        stream = (packet[-13], src_system, src_component)
        last = self.streams.get(stream)
        if last is None:
            if ts + NEW_STREAM_WINDOW_TICKS < self.now_ticks():
                return "stale_stream"
        elif ts <= last:
            return "replay"
        self.streams[stream] = ts
        self._newest_accepted = max(self._newest_accepted, ts)
        return None

    def _check(self, msgbuf: bytearray, src_system: int, src_component: int) -> bool:
        reason = self.check(msgbuf, src_system, src_component)
        if reason is None:
            self.accepted += 1
            return True
        self._pending = reason  # pymavlink calls _refuse next; it counts the reason
        return False

    def _refuse(self, mav: Any, msg_id: int) -> bool:
        reason, self._pending = self._pending or "unsigned", None
        self.reject(reason, msg_id)
        return False

    def reject(self, reason: str, msg_id: int | None = None) -> None:
        """Count a refused packet; the first of each reason is logged and reported."""
        self.rejected[reason] += 1
        if self.rejected[reason] == 1:
            what = _message_name(msg_id)
            text = f"signing: refused {REASONS[reason]}" + (f" ({what})" if what else "")
            log.warning("%s; further ones are counted, not logged", text)
            if self.on_first_reject is not None:
                self.on_first_reject(reason, text)

    @property
    def rejected_total(self) -> int:
        return sum(self.rejected.values())

    def stats(self) -> dict[str, int]:
        """Counters: packets accepted and refused by reason."""
        return {"accepted": self.accepted, **{f"rejected_{k}": v for k, v in self.rejected.items()}}


def _message_name(msg_id: int | None) -> str:
    if msg_id is None:
        return ""
    try:
        from pymavlink.dialects.v20 import common

        cls = common.mavlink_map.get(int(msg_id))
    except Exception:  # pragma: no cover - name lookup is cosmetic
        cls = None
    return cls.msgname if cls is not None else f"message id {msg_id}"
