"""AUTO.MISSION: flies the stored MISSION list item by item, as PX4's navigator does in the small.

Read off PX4 v1.15 ``src/modules/navigator`` (mission_base.cpp, mission_block.cpp):

- NAV_TAKEOFF climbs at the current horizontal position to the item's altitude (MIS_TAKEOFF_ALT
  when it gives none), done within 0.5 m.
- NAV_WAYPOINT flies to the item at MPC_XY_CRUISE (or the DO_CHANGE_SPEED speed); reached inside
  the acceptance radius (param2, or NAV_ACC_RAD when 0) and NAV_MC_ALT_RAD of its altitude, then
  held for param1 seconds. NAV_LOITER_TIME is the same with its own hold time; NAV_LOITER_UNLIM
  flies there and stays.
- NAV_LAND flies to the item's position at the current altitude, then lands there.
- NAV_RETURN_TO_LAUNCH hands over to RTL (the vehicle switches to AUTO.RTL, as PX4's commander does).
- DO_CHANGE_SPEED (param2 m/s, -1 = unchanged) and DO_JUMP (param1 target seq, param2 repeat
  count: the jump is taken that many times, then the mission goes on past it) act at once.
- A latitude/longitude of 0 means the current position. Frames: relative altitude
  (MAV_FRAME_GLOBAL_RELATIVE_ALT[_INT]) or AMSL (MAV_FRAME_GLOBAL[_INT]); DO items ignore theirs.
- After the last item without a landing the vehicle holds at the last target ("mission
  finished", MISSION_STATE_COMPLETE).

MISSION_ITEM_REACHED is reported for every executed item but DO_JUMP. The current item is the
store's ``current_seq``, so MISSION_SET_CURRENT moves the executor. A new upload replaces the
mission: the executor restarts at item 0 of the new list (jump counters and speed reset) and, when
flying AUTO.MISSION, goes on with it at once.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

from sitl_stub.core.geo import GeoOrigin
from sitl_stub.core.mission_store import MISSION, MissionItem, MissionStore

NAV_WAYPOINT = 16
NAV_LOITER_UNLIM = 17
NAV_LOITER_TIME = 19
NAV_RETURN_TO_LAUNCH = 20
NAV_LAND = 21
NAV_TAKEOFF = 22
DO_JUMP = 177
DO_CHANGE_SPEED = 178
NAV_MC_ALT_RAD_M = 0.8  # PX4 NAV_MC_ALT_RAD: vertical acceptance of a multicopter waypoint
ALT_ACCEPT_M = 0.5  # takeoff done within this of its altitude
LAND_XY_ACCEPT_M = 1.0  # a landing starts its descent this close to the landing point

# MISSION_CURRENT.mission_state (MISSION_STATE)
NO_MISSION, NOT_STARTED, ACTIVE, PAUSED, COMPLETE = 1, 2, 3, 4, 5


@dataclass(frozen=True)
class Leg:
    """What the vehicle flies now: a LOCAL_NED target, a horizontal speed (None = MPC_XY_CRUISE),
    whether it is a take-off climb or a landing, or a hand-over to RTL."""

    target_ned: tuple[float, float, float]
    speed_mps: float | None = None
    takeoff: bool = False
    landing: bool = False
    return_home: bool = False


class MissionExecutor:
    """Walks the store's MISSION list; :meth:`update` is called every substep in AUTO.MISSION."""

    def __init__(self, store: MissionStore, origin: GeoOrigin, params: Mapping[str, float]) -> None:
        self.store = store
        self.origin = origin
        self.params = params
        self.started = False
        self.finished = False
        self._speed: float | None = None
        self._jumps: dict[int, int] = {}
        self._active_seq = -1
        self._phase_start: tuple[float, float, float] = (0.0, 0.0, 0.0)
        self._hold_since: float | None = None
        self._descending = False
        self._last: Leg | None = None
        self._reached: list[int] = []
        store.on_change(self._on_upload)

    # ------------------------------------------------------------------ control
    def start(self, pos: list[float]) -> str:
        """Enter AUTO.MISSION (start or resume at the current item); a refusal reason or ''."""
        if not self.store.items(MISSION):
            return "Mode change denied: no mission"
        self.started = True
        self._begin(self.store.current_seq, pos)  # resume re-enters the current item
        return ""

    def restart_at(self, seq: int) -> bool:
        """MISSION_START's first item: False when not an item of the mission."""
        if not self.store.set_current(seq):
            return False
        self.finished = False
        self._active_seq = -1
        return True

    def update(self, t: float, pos: list[float], landed: bool) -> Leg:
        """The leg to fly now, advancing past reached items."""
        items = self.store.items(MISSION)
        for _ in range(2 * len(items) + 2):  # DO items chain; a DO_JUMP loop without NAV stops here
            if self.finished or not items:
                return self._hold(pos)
            seq = self.store.current_seq
            if seq != self._active_seq:
                self.finished = False
                self._begin(seq, pos)
            leg = self._fly(items[seq], t, pos, landed)
            if leg is not None:
                self._last = leg
                return leg
        return self._hold(pos)

    def status(self, in_mission_mode: bool) -> tuple[int, int, int, int]:
        """MISSION_CURRENT's (seq, total, mission_state, mission_mode)."""
        total = len(self.store.items(MISSION))
        if total == 0:
            state = NO_MISSION
        elif self.finished:
            state = COMPLETE
        elif in_mission_mode:
            state = ACTIVE
        else:
            state = PAUSED if self.started else NOT_STARTED
        return self.store.current_seq, total, state, 1 if in_mission_mode else 2

    def drain_reached(self) -> list[int]:
        """Sequence numbers reached since the last call (for MISSION_ITEM_REACHED)."""
        out, self._reached = self._reached, []
        return out

    # ----------------------------------------------------------------- items
    def _fly(self, item: MissionItem, t: float, pos: list[float], landed: bool) -> Leg | None:
        """The leg for ``item``, or None once it is done (the executor then moved on)."""
        c = item.command
        if c == DO_CHANGE_SPEED:
            if item.param2 > 0:
                self._speed = float(item.param2)
            self._done(item)
            return None
        if c == DO_JUMP:
            count = self._jumps.get(item.seq, 0)
            if count < int(item.param2) and self.store.set_current(int(item.param1)):
                self._jumps[item.seq] = count + 1
                return None
            self._advance()
            return None
        if c == NAV_TAKEOFF:
            alt = self._altitude(item, item.z)
            alt = max(alt if alt > 0 else self.params["MIS_TAKEOFF_ALT"], -self._phase_start[2])
            if -pos[2] >= alt - ALT_ACCEPT_M:
                self._done(item)
                return None
            return Leg((self._phase_start[0], self._phase_start[1], -alt), takeoff=True)
        if c == NAV_RETURN_TO_LAUNCH:
            self._done(item)
            self.finished = True
            return Leg(self._phase_start, return_home=True)
        n, e = self._horizontal(item)
        if c == NAV_LAND:
            if not self._descending and math.hypot(n - pos[0], e - pos[1]) < LAND_XY_ACCEPT_M:
                self._descending = True
            if self._descending and landed:
                self._done(item)
                return None
            down = 1.0 if self._descending else self._phase_start[2]  # 1 m below ground: touch down
            return Leg((n, e, down), self._speed, landing=self._descending)
        if c not in (NAV_WAYPOINT, NAV_LOITER_TIME, NAV_LOITER_UNLIM):
            self._advance()  # not flown here (PX4 refuses most at upload)
            return None
        leg = Leg((n, e, -self._altitude(item, item.z)), self._speed)
        if self._hold_since is None and self._arrived(item, leg.target_ned, pos):
            self._hold_since = t
        hold_s = item.param1 if c in (NAV_LOITER_TIME, NAV_WAYPOINT) else math.inf
        if self._hold_since is not None and t - self._hold_since >= max(0.0, hold_s):
            self._done(item)
            return None
        return leg

    def _arrived(
        self, item: MissionItem, target: tuple[float, float, float], pos: list[float]
    ) -> bool:
        radius = item.param2 if item.command == NAV_WAYPOINT and item.param2 > 0 else 0.0
        radius = radius or self.params["NAV_ACC_RAD"]
        return (
            math.hypot(target[0] - pos[0], target[1] - pos[1]) <= radius
            and abs(target[2] - pos[2]) <= NAV_MC_ALT_RAD_M
        )

    def _done(self, item: MissionItem) -> None:
        self._reached.append(item.seq)
        self._advance()

    def _advance(self) -> None:
        seq = self.store.current_seq
        if not self.store.set_current(seq + 1):
            self.finished = True
        return None

    def _begin(self, seq: int, pos: list[float]) -> None:
        self._active_seq = seq
        self._phase_start = (pos[0], pos[1], pos[2])
        self._hold_since = None
        self._descending = False

    def _hold(self, pos: list[float]) -> Leg:
        """Mission over (or nothing flyable): hold at the last target (here when none)."""
        last = self._last or Leg((pos[0], pos[1], pos[2]))
        self._last = Leg(last.target_ned, last.speed_mps, landing=last.landing)
        return self._last

    def _on_upload(self, mission_type: int) -> None:
        if mission_type != MISSION:
            return
        self._jumps.clear()
        self._speed = None
        self.finished = False
        self.started = False
        self._active_seq = -1

    # ------------------------------------------------------------ coordinates
    def _horizontal(self, item: MissionItem) -> tuple[float, float]:
        if item.x == 0 and item.y == 0:
            return self._phase_start[0], self._phase_start[1]
        return self.origin.to_local(*item.lat_lon_deg())

    def _altitude(self, item: MissionItem, z: float) -> float:
        """Height above home of an item's altitude ``z`` in its frame."""
        return item.height_above_home_m(z, self.origin.alt_amsl_m)
