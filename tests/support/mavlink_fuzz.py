"""Shared pieces of the MAVLink fuzz tests: bounded Hypothesis settings and packet mutations."""

from __future__ import annotations

from hypothesis import HealthCheck, settings
from hypothesis import strategies as st

FUZZ = settings(
    max_examples=200,
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)

# (which packet, where to flip, the xor mask, junk appended): see :func:`corrupt`
mutation = st.tuples(
    st.integers(0, 11), st.integers(0, 10_000), st.integers(1, 255), st.binary(max_size=8)
)


def corrupt(pkt: bytes, pos: int, flip: int) -> bytes:
    """Flip one byte (never a no-op) somewhere after the start marker."""
    i = 1 + pos % (len(pkt) - 1)
    b = bytearray(pkt)
    b[i] ^= flip
    return bytes(b)
