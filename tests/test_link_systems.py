"""VehicleLink finds its vehicle by heartbeat, not by assuming system 1, and keeps state per system.

A real ``sitl-stub`` process runs as MAVLink system 2 (PX4's MAV_SYS_ID=2); the vehicle ignores
commands addressed to any other system, so an arm that takes effect shows the link targeted it.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from support.mavlink_gcs import FAST_TAKEOFF

from sitl_stub.launcher import vehicle_process
from uavlink.flight.link import LinkError, VehicleLink
from uavlink.mavlink.connection import free_udp_port
from uavlink.mavlink.dialect import mavlink

pytestmark = [pytest.mark.slow, pytest.mark.timeout(120)]

FAST = (*FAST_TAKEOFF, "--no-payload")


def test_link_learns_system_2_from_its_heartbeat_and_commands_it(tmp_path: Path) -> None:
    port = free_udp_port()
    with vehicle_process(f"udpout:127.0.0.1:{port}", 10.0, ["--system-id", "2", *FAST]) as vehicle:
        elsewhere = VehicleLink(f"udpin:127.0.0.1:{port}", target_system=7)
        try:  # told to fly system 7: system 2 is heard and tracked, but never taken for it
            with pytest.raises(LinkError, match="no heartbeat"):
                elsewhere.wait_vehicle(timeout_s=3.0)
            assert elsewhere.target_system == 7 and elsewhere.status.heartbeats == 0
            assert elsewhere.systems[2].heartbeats > 0 and elsewhere.systems[2].component_id == 1
        finally:
            elsewhere.close()
        link = VehicleLink(f"udpin:127.0.0.1:{port}", tlog=tmp_path / "link.tlog")
        try:
            assert link.target_system is None
            link.wait_vehicle(timeout_s=20.0)
            assert (link.target_system, link.target_component) == (2, 1), vehicle.output()
            assert set(link.systems) == {2}
            link.arm()
            link.takeoff(5.0)
            assert link.status.armed and link.status.in_air and -link.status.down_m >= 4.0
            assert link.systems[2] is link.status
        finally:
            link.close()


def test_a_command_the_vehicle_refuses_for_now_is_sent_again_until_it_takes() -> None:
    """PX4 answers a request its state refuses for now TEMPORARILY_REJECTED (Commander.cpp): a
    disarm in the air, an arming before the estimator is ready. ``command`` sends it again."""
    port = free_udp_port()
    with vehicle_process(f"udpout:127.0.0.1:{port}", 10.0, list(FAST)):
        link = VehicleLink(f"udpin:127.0.0.1:{port}")
        try:
            link.wait_vehicle(timeout_s=20.0)
            link.arm()
            link.takeoff(5.0)
            with pytest.raises(LinkError, match=r"for now, 3 times \(TEMPORARILY_REJECTED\)"):
                link.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 0.0, ack_wait_s=0.1, tries=3)
            assert link.status.armed and link.status.in_air
            link.command(mavlink.MAV_CMD_NAV_LAND)
            # Refused while the vehicle descends, accepted once it is down.
            link.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 0.0, ack_wait_s=0.25, tries=80)
            assert link.wait_wall(lambda: not link.status.armed, 2.0)
        finally:
            link.close()
