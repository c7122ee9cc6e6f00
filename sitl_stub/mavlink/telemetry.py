"""MAVLink telemetry of the vehicle as PX4's mavlink module would send it.

Every message is built from a :class:`~sitl_stub.core.vehicle_state.VehicleState` (and the
:class:`~sitl_stub.sim.battery.Battery`); ``time_boot_ms`` and ``time_usec`` are simulated time since
boot. Global positions come from the LOCAL_NED position through the configured
:class:`~sitl_stub.core.geo.GeoOrigin` (which is also home). One method per message; a new message is a
method plus a row in ``_builders`` (and a default rate in :mod:`sitl_stub.mavlink.streams` to stream it).

``mav`` sends where the server routes it (every link, or the link whose request is being
answered); ``announce`` (default ``mav``) sends STATUSTEXT, which goes to every link as PX4's
mavlink_log does.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

from sitl_stub.core.geo import GeoOrigin
from sitl_stub.core.vehicle_state import VehicleState
from sitl_stub.sim.battery import CELL_COUNT, Battery
from uavlink.mavlink.dialect import mavlink
from uavlink.mavlink.frames import deg_to_e7

# PX4 reports every sensor present, enabled and healthy in SITL; GEOFENCE healthy keeps MAVProxy
# from announcing "fence breach" (it is unhealthy while VehicleState.fence_breached), PREARM_CHECK
# and GPS make MAVSDK's health armable / position ok.
SENSORS = (
    mavlink.MAV_SYS_STATUS_SENSOR_3D_GYRO
    | mavlink.MAV_SYS_STATUS_SENSOR_3D_ACCEL
    | mavlink.MAV_SYS_STATUS_SENSOR_3D_MAG
    | mavlink.MAV_SYS_STATUS_SENSOR_ABSOLUTE_PRESSURE
    | mavlink.MAV_SYS_STATUS_SENSOR_GPS
    | mavlink.MAV_SYS_STATUS_SENSOR_ANGULAR_RATE_CONTROL
    | mavlink.MAV_SYS_STATUS_SENSOR_ATTITUDE_STABILIZATION
    | mavlink.MAV_SYS_STATUS_SENSOR_YAW_POSITION
    | mavlink.MAV_SYS_STATUS_SENSOR_Z_ALTITUDE_CONTROL
    | mavlink.MAV_SYS_STATUS_SENSOR_XY_POSITION_CONTROL
    | mavlink.MAV_SYS_STATUS_SENSOR_MOTOR_OUTPUTS
    | mavlink.MAV_SYS_STATUS_GEOFENCE
    | mavlink.MAV_SYS_STATUS_AHRS
    | mavlink.MAV_SYS_STATUS_SENSOR_BATTERY
    | mavlink.MAV_SYS_STATUS_PREARM_CHECK
)

# SYS_STATUS health bits an injected failure (sitl_stub.flight.failures) clears.
_FAILED_BITS = {
    "gps": mavlink.MAV_SYS_STATUS_SENSOR_GPS,
    "battery": mavlink.MAV_SYS_STATUS_SENSOR_BATTERY,
    "motor": mavlink.MAV_SYS_STATUS_SENSOR_MOTOR_OUTPUTS,
}

CAPABILITIES = (
    mavlink.MAV_PROTOCOL_CAPABILITY_MAVLINK2
    | mavlink.MAV_PROTOCOL_CAPABILITY_COMMAND_INT
    | mavlink.MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_BYTEWISE
    | mavlink.MAV_PROTOCOL_CAPABILITY_SET_POSITION_TARGET_LOCAL_NED
    # the mission protocol (sitl_stub.mavlink.mission_protocol): MAVSDK's mission_raw wants MISSION_INT,
    # QGroundControl downloads fence and rally only when these say so
    | mavlink.MAV_PROTOCOL_CAPABILITY_MISSION_FLOAT
    | mavlink.MAV_PROTOCOL_CAPABILITY_MISSION_INT
    | mavlink.MAV_PROTOCOL_CAPABILITY_MISSION_FENCE
    | mavlink.MAV_PROTOCOL_CAPABILITY_MISSION_RALLY
)
FLIGHT_SW_VERSION = 1 << 24 | 14 << 16 | 0 << 8 | 255  # "v1.14.0 official", PX4's encoding
UID = int.from_bytes(b"SITLSTUB", "big")
UNKNOWN_TEMPERATURE = 32767  # BATTERY_STATUS.temperature INT16_MAX: not measured
UNUSED_CELL = 65535  # BATTERY_STATUS.voltages UINT16_MAX: no such cell
# PX4's BAT_LOW_THR, BAT_CRIT_THR, BAT_EMERGEN_THR (remaining fraction) -> charge_state
_CHARGE_STATES = (
    (0.05, mavlink.MAV_BATTERY_CHARGE_STATE_EMERGENCY),
    (0.07, mavlink.MAV_BATTERY_CHARGE_STATE_CRITICAL),
    (0.15, mavlink.MAV_BATTERY_CHARGE_STATE_LOW),
)

_AUTO_FLAGS = (
    mavlink.MAV_MODE_FLAG_AUTO_ENABLED
    | mavlink.MAV_MODE_FLAG_STABILIZE_ENABLED
    | mavlink.MAV_MODE_FLAG_GUIDED_ENABLED
)


def base_mode(state: VehicleState) -> int:
    """HEARTBEAT.base_mode: custom mode enabled, PX4's auto/guided flags, SAFETY_ARMED when armed."""
    flags = mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | _AUTO_FLAGS
    if state.armed:
        flags |= mavlink.MAV_MODE_FLAG_SAFETY_ARMED
    return flags


class TelemetrySender:
    """Sends the autopilot's messages with one pymavlink ``MAVLink`` object (component 1)."""

    def __init__(
        self,
        mav: Any,
        origin: GeoOrigin,
        battery: Battery | None = None,
        announce: Any = None,
        home_ne: tuple[float, float] = (0.0, 0.0),
    ) -> None:
        self.mav = mav
        self.origin = origin
        self.home_ne = home_ne
        self.battery = battery or Battery()
        self.announce = mav if announce is None else announce
        self._builders: dict[str, Callable[[VehicleState], None]] = {
            "HEARTBEAT": self.heartbeat,
            "SYS_STATUS": self.sys_status,
            "BATTERY_STATUS": self.battery_status,
            "EXTENDED_SYS_STATE": self.extended_sys_state,
            "HOME_POSITION": self.home_position,
            "GPS_RAW_INT": self.gps_raw_int,
            "GLOBAL_POSITION_INT": self.global_position_int,
            "LOCAL_POSITION_NED": self.local_position_ned,
            "ATTITUDE": self.attitude,
            "ATTITUDE_QUATERNION": self.attitude_quaternion,
            "ODOMETRY": self.odometry,
            "ALTITUDE": self.altitude,
            "VFR_HUD": self.vfr_hud,
            "AUTOPILOT_VERSION": self.autopilot_version,
            "MISSION_CURRENT": self.mission_current,
            "ORBIT_EXECUTION_STATUS": self.orbit_execution_status,
        }

    def names(self) -> list[str]:
        return list(self._builders)

    def can_send(self, name: str) -> bool:
        return name in self._builders

    def send(self, name: str, state: VehicleState) -> None:
        self._builders[name](state)

    # ------------------------------------------------------------------ builders
    def heartbeat(self, s: VehicleState) -> None:
        status = mavlink.MAV_STATE_ACTIVE if s.armed else mavlink.MAV_STATE_STANDBY
        self.mav.heartbeat_send(
            mavlink.MAV_TYPE_QUADROTOR,
            mavlink.MAV_AUTOPILOT_PX4,
            base_mode(s),
            s.mode.custom_mode,
            status,
        )

    def sys_status(self, s: VehicleState) -> None:
        healthy = SENSORS & ~sum(_FAILED_BITS[f] for f in s.failures if f in _FAILED_BITS)
        if s.fence_breached:
            healthy &= ~mavlink.MAV_SYS_STATUS_GEOFENCE
        b = self.battery.reading()
        self.mav.sys_status_send(
            SENSORS,
            SENSORS,
            healthy,
            200,
            _mv(b.voltage_v),
            -1,
            int(b.remaining_pct),
            0,
            0,
            0,
            0,
            0,
            0,
        )

    def battery_status(self, s: VehicleState) -> None:
        b = self.battery.reading()
        cells = [_mv(b.cell_voltage_v)] * CELL_COUNT + [UNUSED_CELL] * (10 - CELL_COUNT)
        fraction = b.remaining_pct / 100.0
        charge = next(
            (state for limit, state in _CHARGE_STATES if fraction <= limit),
            mavlink.MAV_BATTERY_CHARGE_STATE_OK,
        )
        self.mav.battery_status_send(
            0,
            mavlink.MAV_BATTERY_FUNCTION_ALL,
            mavlink.MAV_BATTERY_TYPE_LIPO,
            UNKNOWN_TEMPERATURE,
            cells,
            -1,
            -1,
            -1,
            int(b.remaining_pct),
            0,
            charge,
        )

    def extended_sys_state(self, s: VehicleState) -> None:
        self.mav.extended_sys_state_send(mavlink.MAV_VTOL_STATE_UNDEFINED, int(s.landed_state))

    def home_position(self, s: VehicleState) -> None:
        """Home (the spawn point: LOCAL_NED ``home_ne``, the origin itself for one vehicle)."""
        o, (north, east) = self.origin, self.home_ne
        lat, lon = o.to_global(north, east)
        self.mav.home_position_send(
            deg_to_e7(lat),
            deg_to_e7(lon),
            _mm(o.alt_amsl_m),
            north,
            east,
            0.0,
            [1.0, 0.0, 0.0, 0.0],
            0.0,
            0.0,
            0.0,
            _us(s.time_s),
        )

    def gps_raw_int(self, s: VehicleState) -> None:
        lat, lon = self.origin.to_global(s.north_m, s.east_m)
        speed = s.ground_speed_mps
        cog = 65535 if speed < 0.5 else _cdeg(math.atan2(s.ve_mps, s.vn_mps))
        gps_off = "gps" in s.failures  # injected failure: no receiver data
        fix = mavlink.GPS_FIX_TYPE_NO_GPS if gps_off else mavlink.GPS_FIX_TYPE_3D_FIX
        self.mav.gps_raw_int_send(
            _us(s.time_s),
            fix,
            deg_to_e7(lat),
            deg_to_e7(lon),
            _mm(self.origin.alt_amsl_m + s.altitude_m),
            70,
            110,
            min(int(speed * 100), 65534),
            cog,
            0 if gps_off else 12,
            _mm(self.origin.alt_amsl_m + s.altitude_m),
            500,
            800,
            200,
            0,
            0,
        )

    def global_position_int(self, s: VehicleState) -> None:
        lat, lon = self.origin.to_global(s.north_m, s.east_m)
        self.mav.global_position_int_send(
            _ms(s.time_s),
            deg_to_e7(lat),
            deg_to_e7(lon),
            _mm(self.origin.alt_amsl_m + s.altitude_m),
            _mm(s.altitude_m),
            _cms(s.vn_mps),
            _cms(s.ve_mps),
            _cms(s.vd_mps),
            _cdeg(s.yaw_rad),
        )

    def local_position_ned(self, s: VehicleState) -> None:
        self.mav.local_position_ned_send(
            _ms(s.time_s), s.north_m, s.east_m, s.down_m, s.vn_mps, s.ve_mps, s.vd_mps
        )

    def attitude(self, s: VehicleState) -> None:
        self.mav.attitude_send(
            _ms(s.time_s), s.roll_rad, s.pitch_rad, s.yaw_rad, 0.0, 0.0, s.yaw_rate_radps
        )

    def attitude_quaternion(self, s: VehicleState) -> None:
        q = _quaternion(s.roll_rad, s.pitch_rad, s.yaw_rad)
        self.mav.attitude_quaternion_send(_ms(s.time_s), *q, 0.0, 0.0, s.yaw_rate_radps)

    def odometry(self, s: VehicleState) -> None:
        """ODOMETRY as PX4's stream sends it: the position in LOCAL_NED, the velocity in the body
        frame (FRD), covariances unknown (NaN). The body frame is turned by yaw alone: the point-mass
        vehicle's roll and pitch are the few degrees its acceleration implies."""
        c, si = math.cos(s.yaw_rad), math.sin(s.yaw_rad)
        unknown = [math.nan] * 21
        self.mav.odometry_send(
            _us(s.time_s),
            mavlink.MAV_FRAME_LOCAL_NED,
            mavlink.MAV_FRAME_BODY_FRD,
            s.north_m,
            s.east_m,
            s.down_m,
            list(_quaternion(s.roll_rad, s.pitch_rad, s.yaw_rad)),
            c * s.vn_mps + si * s.ve_mps,
            -si * s.vn_mps + c * s.ve_mps,
            s.vd_mps,
            0.0,
            0.0,
            s.yaw_rate_radps,
            unknown,
            unknown,
            0,
            mavlink.MAV_ESTIMATOR_TYPE_AUTOPILOT,
        )

    def altitude(self, s: VehicleState) -> None:
        """ALTITUDE: AMSL (also as the monotonic altitude), local (-down), above home; no terrain."""
        amsl = self.origin.alt_amsl_m + s.altitude_m
        self.mav.altitude_send(
            _us(s.time_s), amsl, amsl, -s.down_m, s.altitude_m, math.nan, math.nan
        )

    def vfr_hud(self, s: VehicleState) -> None:
        heading = int(round(math.degrees(s.yaw_rad))) % 360
        throttle = 50 if s.armed and s.in_air else 0
        self.mav.vfr_hud_send(
            s.ground_speed_mps,
            s.ground_speed_mps,
            heading,
            throttle,
            self.origin.alt_amsl_m + s.altitude_m,
            -s.vd_mps,
        )

    def autopilot_version(self, s: VehicleState) -> None:
        # uid2 (MAVLink 2 extension, 18 bytes) as well as uid: MAVSDK 4 reads its hardware uid from uid2
        uid2 = list(UID.to_bytes(8, "big") + bytes([self.mav.srcSystem]) + bytes(9))
        self.mav.autopilot_version_send(
            CAPABILITIES, FLIGHT_SW_VERSION, 0, 0, 0, [0] * 8, [0] * 8, [0] * 8, 0, 0, UID, uid2
        )

    def mission_current(self, s: VehicleState) -> None:
        """MISSION_CURRENT as PX4 streams it: seq, total, mission_state, mission_mode."""
        self.mav.mission_current_send(*s.mission_current)

    def mission_item_reached(self, seq: int) -> None:
        self.mav.mission_item_reached_send(seq)

    def orbit_execution_status(self, s: VehicleState) -> None:
        """Sent only while orbiting (PX4 publishes orbit_status from FlightTaskOrbit)."""
        o = s.orbit
        if o is None:
            return
        lat, lon = self.origin.to_global(o.center_north_m, o.center_east_m)
        self.mav.orbit_execution_status_send(
            _us(s.time_s),
            o.signed_radius_m,
            mavlink.MAV_FRAME_GLOBAL,
            deg_to_e7(lat),
            deg_to_e7(lon),
            self.origin.alt_amsl_m - o.down_m,
        )

    def statustext(self, severity: int, text: str) -> None:
        self.announce.statustext_send(severity, text[:50].encode("ascii", "replace"))


def _mm(m: float) -> int:
    return int(round(m * 1000.0))


_mv = _mm  # volts to millivolts: the same scaling


def _ms(s: float) -> int:
    return int(s * 1000.0) & 0xFFFFFFFF


def _us(s: float) -> int:
    return int(s * 1e6)


def _cms(v: float) -> int:
    return max(-32767, min(32767, int(round(v * 100.0))))


def _cdeg(rad: float) -> int:
    return int(round(math.degrees(rad) * 100.0)) % 36000


def _quaternion(roll: float, pitch: float, yaw: float) -> tuple[float, float, float, float]:
    cr, sr = math.cos(roll / 2), math.sin(roll / 2)
    cp, sp = math.cos(pitch / 2), math.sin(pitch / 2)
    cy, sy = math.cos(yaw / 2), math.sin(yaw / 2)
    return (
        cr * cp * cy + sr * sp * sy,
        sr * cp * cy - cr * sp * sy,
        cr * sp * cy + sr * cp * sy,
        cr * cp * sy - sr * sp * cy,
    )
