"""What a ground link knows of one MAVLink system, from its messages (as pymavlink's
``mavfile.sysid_state`` keeps per system): its autopilot's heartbeat and mode, its local position
and the vehicle clock behind it, its landed state and its home."""

from __future__ import annotations

import math
import time
from collections import deque
from dataclasses import dataclass, field
from typing import Any

from uavlink.mavlink.dialect import mavlink as MAV
from uavlink.mavlink.px4_modes import PX4_MAIN_OFFBOARD, decode_custom_mode
from uavlink.mavlink.rejects import RejectLog

REBOOT_BACKSTEP_S = 5.0  # LOCAL_POSITION_NED time going back more than this: the vehicle rebooted
# The vehicle's clock is read over this much of our wall time: a pause of this process (a busy
# machine) queues the vehicle's messages and they then arrive together, which a window of a few
# dozen samples (80 ms of wall time at 20x) reads as a vehicle many times faster than it is, and a
# wait sized by that speed ends too soon.
CLOCK_WINDOW_S = 2.0


@dataclass
class VehicleStatus:
    """What the link knows of one MAVLink system, from its messages."""

    component_id: int | None = None  # its autopilot's component, from its first autopilot heartbeat
    heartbeat: Any = None  # the autopilot's last HEARTBEAT
    armed: bool = False
    main_mode: int = 0
    sub_mode: int = 0
    landed_state: int = 0
    north_m: float = 0.0
    east_m: float = 0.0
    down_m: float = 0.0
    north_mps: float = 0.0  # LOCAL_POSITION_NED's vx, vy (0 where not finite)
    east_mps: float = 0.0
    time_boot_ms: int = 0
    heartbeats: int = 0
    landed_known: bool = False
    home: Any = None  # the last HOME_POSITION: where the local frame sits on Earth
    # (wall s, vehicle s) of the last CLOCK_WINDOW_S of LOCAL_POSITION_NED: the vehicle's clock
    boot_samples: deque[tuple[float, float]] = field(default_factory=deque)

    @property
    def in_air(self) -> bool:
        return self.landed_state in (MAV.MAV_LANDED_STATE_IN_AIR, MAV.MAV_LANDED_STATE_TAKEOFF)

    @property
    def offboard(self) -> bool:
        return self.main_mode == PX4_MAIN_OFFBOARD

    def track(self, msg, kind: str, src_comp: int, rejects: RejectLog) -> None:
        """Update the state from the system's HEARTBEAT, LOCAL_POSITION_NED, EXTENDED_SYS_STATE or HOME_POSITION
        (a NaN position is rejected into ``rejects``, a late one ignored)."""
        if kind == "HEARTBEAT":
            if msg.autopilot == MAV.MAV_AUTOPILOT_INVALID:
                return  # a payload's, a ground station's: not the vehicle's state
            if self.component_id is None:
                self.component_id = src_comp
            if src_comp == self.component_id:
                self.heartbeats += 1
                self.heartbeat = msg
                self.armed = bool(msg.base_mode & MAV.MAV_MODE_FLAG_SAFETY_ARMED)
                self.main_mode, self.sub_mode = decode_custom_mode(msg.custom_mode)
        elif kind == "LOCAL_POSITION_NED":
            if not all(math.isfinite(v) for v in (msg.x, msg.y, msg.z)):
                rejects.reject(
                    "position_not_finite",
                    f"LOCAL_POSITION_NED with NaN/infinite position ({msg.x}, {msg.y}, {msg.z})",
                )
                return
            samples = self.boot_samples
            newest = samples[-1][1] if samples else -math.inf
            if msg.time_boot_ms * 1e-3 < newest - REBOOT_BACKSTEP_S:
                samples.clear()  # the vehicle rebooted: its clock started again
            elif msg.time_boot_ms * 1e-3 < newest:
                return  # a late (reordered) sample: the vehicle has moved on since
            self.north_m, self.east_m, self.down_m = msg.x, msg.y, msg.z
            vx, vy = msg.vx, msg.vy
            self.north_mps, self.east_mps = (vx, vy) if math.isfinite(vx + vy) else (0.0, 0.0)
            self.time_boot_ms = msg.time_boot_ms
            now = time.monotonic()
            samples.append((now, msg.time_boot_ms * 1e-3))
            while samples[0][0] < now - CLOCK_WINDOW_S:
                samples.popleft()
        elif kind == "EXTENDED_SYS_STATE":
            self.landed_state = msg.landed_state
            self.landed_known = True
        elif kind == "HOME_POSITION":
            self.home = msg
