"""MAV_FRAME: the frame sets both ends read (https://mavlink.io/en/messages/common.html#MAV_FRAME),
declared once: which frames carry latitude/longitude, which altitude each gives, and the float and
int pairs of the mission items (MISSION_ITEM's degrees, MISSION_ITEM_INT's degrees * 1e7).

The world of the SITL vehicle is flat at home, so a terrain frame's altitude is a height above home,
as a relative one is.
"""

from __future__ import annotations

GLOBAL = 0  # MAV_FRAME_GLOBAL: lat/lon, altitude AMSL
LOCAL_NED = 1  # MAV_FRAME_LOCAL_NED
GLOBAL_RELATIVE_ALT = 3  # MAV_FRAME_GLOBAL_RELATIVE_ALT: altitude above home
GLOBAL_INT = 5  # MAV_FRAME_GLOBAL_INT
GLOBAL_RELATIVE_ALT_INT = 6  # MAV_FRAME_GLOBAL_RELATIVE_ALT_INT
GLOBAL_TERRAIN_ALT = 10  # MAV_FRAME_GLOBAL_TERRAIN_ALT: altitude above ground
GLOBAL_TERRAIN_ALT_INT = 11  # MAV_FRAME_GLOBAL_TERRAIN_ALT_INT

AMSL_FRAMES = frozenset({GLOBAL, GLOBAL_INT})
RELATIVE_ALT_FRAMES = frozenset(
    {GLOBAL_RELATIVE_ALT, GLOBAL_RELATIVE_ALT_INT, GLOBAL_TERRAIN_ALT, GLOBAL_TERRAIN_ALT_INT}
)
GLOBAL_FRAMES = AMSL_FRAMES | RELATIVE_ALT_FRAMES  # x/y are latitude/longitude
# the mission items' global frames (PX4 stores and sends these two pairs, MAVLink's mission service)
TO_INT_FRAME = {GLOBAL: GLOBAL_INT, GLOBAL_RELATIVE_ALT: GLOBAL_RELATIVE_ALT_INT}
TO_FLOAT_FRAME = {v: k for k, v in TO_INT_FRAME.items()}


def deg_to_e7(deg: float) -> int:
    """Degrees as MAVLink's int32 degrees * 1e7 (the *_INT messages' latitude/longitude; 1e-7 degree
    is about 1 cm), rounded to the nearest."""
    return int(round(deg * 1e7))


def e7_to_deg(value: float) -> float:
    """MAVLink's degrees * 1e7 as degrees: a division, correctly rounded (``* 1e-7`` is not)."""
    return value / 1e7


def height_above_home_m(z_m: float, frame: int, home_amsl_m: float) -> float:
    """The height above home of a global frame's altitude ``z_m`` (AMSL or above home/ground)."""
    return z_m - home_amsl_m if frame in AMSL_FRAMES else z_m
