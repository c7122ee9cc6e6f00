"""A lightweight PX4-style SITL vehicle with a radio payload."""
