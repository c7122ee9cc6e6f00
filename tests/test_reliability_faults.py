"""Link faults between `uavlink fly` and the vehicle: loss, delay, duplicates, reordering, blackouts.

Flights go through the relay of ``tests/support/udp_relay.py`` (``tests/support/relay_flight.py``) on loopback (fly and the vehicle are child processes);
the vehicle's exit stats give its own truth of the episode's throughput (whatever the link lost)
and its safety monitors. ``pytest -s`` prints the table; ``research/link_faults.py`` makes the
full one (with 200 ms delay at --speed 1).
"""

from __future__ import annotations

import socket
import threading
import time

import pytest
from support.relay_flight import fly_through_relay, format_table, table_row
from support.udp_relay import BLACKOUT, CLEAN, Faults, UdpRelay

pytestmark = pytest.mark.slow  # flights through a lossy relay

OFFBOARD = 6 << 16
LOITER = 4 << 16 | 3 << 24
COM_OF_LOSS_T = 1.0
SUBSTEP_S = 0.02  # the vehicle checks the offboard stream every integration substep


def _safe(run: dict) -> None:
    """Vehicle-side: never outside the geofence, never in OFFBOARD on a setpoint older than the
    failsafe time."""
    v = run["vehicle"]["vehicle"]
    assert v["max_abs_xy_m"] <= v["fence_m"] + 1e-6, v
    assert v["max_offboard_setpoint_age_s"] <= COM_OF_LOSS_T + SUBSTEP_S + 1e-6, v
    assert run["fly"]["guarded_actions"] == 0


@pytest.mark.slow
@pytest.mark.timeout(30)
def test_relay_drops_delays_duplicates_and_reorders_and_stops_by_itself() -> None:
    with (
        socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as dest,
        socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as client,
    ):
        dest.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 20)
        dest.bind(("127.0.0.1", 0))
        dest.settimeout(0.5)
        faults = Faults(loss=0.3, delay_s=0.05, duplicate=0.1, reorder=0.1, reorder_s=0.02)
        got, delays, sent_at = [], [], {}
        back: list[tuple[str, int]] = []

        def receive() -> None:
            # Read while the client sends: a loaded machine must not overflow dest's buffer,
            # which would lose datagrams the relay did forward.
            while True:
                try:
                    data, addr = dest.recvfrom(64)
                except TimeoutError:
                    return
                n = int.from_bytes(data, "big")
                got.append(n)
                delays.append(time.monotonic() - sent_at[n])
                back[:] = [addr]

        with UdpRelay(dest.getsockname(), faults, seed=7, max_duration_s=3.0) as relay:
            reader = threading.Thread(target=receive, daemon=True)
            reader.start()
            for i in range(1000):
                sent_at[i] = time.monotonic()
                client.sendto(i.to_bytes(4, "big"), ("127.0.0.1", relay.port))
                if i % 20 == 0:  # paced, so the relay's own socket never overflows either
                    time.sleep(0.002)
            reader.join(10.0)
            assert relay.stats["up_in"] == 1000  # every datagram reached the relay
            dest.sendto(b"reply", back[0])  # the other direction goes back to the client
            client.settimeout(1.0)
            assert client.recvfrom(64)[0] == b"reply"
            stats = dict(relay.stats)
            deadline = time.monotonic() + 3.2  # the relay's whole life: it ends by itself
            while relay.running and time.monotonic() < deadline:
                time.sleep(0.02)
            assert not relay.running and relay.stats["expired"] == 1  # bounded in time
    distinct = set(got)
    assert 0.62 < len(distinct) / 1000 < 0.78  # 30 % loss
    assert len(got) - len(distinct) == stats["up_duplicated"] > 30
    assert sum(1 for a, b in zip(got, got[1:], strict=False) if b < a) > 20  # reordered
    assert min(delays) >= 0.05
    assert stats["up_dropped"] + len(distinct) == 1000


@pytest.mark.slow
@pytest.mark.timeout(120)
def test_throughput_under_10_percent_loss_stays_within_5_percent_of_clean() -> None:
    clean = fly_through_relay(CLEAN, timeout_s=60)
    lossy = fly_through_relay(Faults(loss=0.10), relay_seed=1, timeout_s=60)
    base = clean["vehicle"]["payloads"]["158"]["mean_rate_mbps"]
    rows = [table_row("clean", clean, base), table_row("10 % loss", lossy, base)]
    print("\n" + format_table(rows))
    for run in (clean, lossy):
        _safe(run)
        assert run["fly"]["ended_by"] == "episode done"
        assert run["vehicle"]["payloads"]["158"]["frames"] == 128
    # Every frame decided, but for frames that reached a loaded machine's loop in a backlog.
    assert clean["fly"]["decisions"] + clean["fly"]["stale_radio_reports"] == 128
    assert clean["fly"]["decisions"] >= 0.9 * 128
    assert lossy["relay"]["up_dropped"] > 100 and lossy["relay"]["down_dropped"] > 50
    assert abs(rows[1]["vs_clean_pct"]) <= 5.0, rows


@pytest.mark.slow
@pytest.mark.timeout(90)
def test_30_percent_loss_and_a_blackout_fail_safe_and_the_loop_recovers() -> None:
    """30 % loss from the start; 2 s into the episode a 1 s blackout (20 s of vehicle time at
    --speed 20: the offboard-loss failsafe must fire); then a clear link."""
    run = fly_through_relay(
        Faults(loss=0.30), relay_seed=3, timeout_s=70, schedule=[(2.0, BLACKOUT), (3.0, CLEAN)]
    )
    print("\n" + format_table([table_row("30 % loss + 1 s blackout, then clear", run, None)]))
    _safe(run)
    fly, vehicle = run["fly"], run["vehicle"]["vehicle"]
    assert fly["ended_by"] == "episode done", run["fly_stderr"][-2000:]
    assert vehicle["offboard_failsafes"] >= 1 and fly["offboard_reentries"] >= 1
    assert "re-entering" in run["fly_stderr"]
    # recovery: once the link is clear the vehicle is back in OFFBOARD and stays there until fly
    # itself ends the episode (hold, then land)
    clear_at = run["applied"][-1][0]
    back = run["watch"].first(OFFBOARD, after=clear_at)
    assert back is not None and back - clear_at < 3.0, run["modes"]
    after = [mode for t, mode, _ in run["modes"] if t > back]
    assert after.count(LOITER) <= 1, run["modes"]  # fly's own hold at the end, no more failsafes
    frame_back = run["watch"].frame_at(back)
    assert frame_back < 110  # most of the episode was flown after the recovery
    assert fly["decisions"] >= 128 - frame_back


@pytest.mark.slow
@pytest.mark.timeout(90)
def test_delay_duplicates_and_reordering_at_low_speed() -> None:
    """200 ms each way at --speed 5 (1 s of vehicle time), 5 % duplicated, 5 % reordered."""
    faults = Faults(delay_s=0.2, duplicate=0.05, reorder=0.05, reorder_s=0.05)
    run = fly_through_relay(faults, relay_seed=5, speed=5.0, frames=16, timeout_s=70)
    print("\n" + format_table([table_row(faults.describe(), run, None)]))
    _safe(run)
    assert run["fly"]["ended_by"] == "episode done" and run["fly"]["decisions"] >= 15
    assert run["vehicle"]["vehicle"]["offboard_failsafes"] == 0
    assert run["relay"]["up_duplicated"] > 0 and run["relay"]["down_reordered"] > 0
