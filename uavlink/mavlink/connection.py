"""Connection strings: pymavlink's forms, MAVSDK-style URLs and the SPEC's bare port.

Accepted (all normalised to what ``pymavlink.mavutil.mavlink_connection`` takes):

- ``udpout:HOST:PORT`` / ``udpout://HOST:PORT``: send to HOST:PORT (PX4 SITL's GCS link does this);
- ``udp:HOST:PORT``, ``udpin:HOST:PORT``, ``udpin://HOST:PORT``, ``udp://HOST:PORT``: listen;
  replies go to every peer that has sent something;
- ``udp:PORT``, ``udpin:PORT``, ``udp://:PORT``: listen on 0.0.0.0:PORT (pymavlink refuses a bare
  port with "UDP ports must be specified as host:port");
- ``tcp:HOST:PORT`` / ``tcp://HOST:PORT`` / ``tcpout://``: connect; ``tcpin:HOST:PORT`` /
  ``tcpin://HOST:PORT``: listen.
"""

from __future__ import annotations

import contextlib
import io
import logging
import random
import socket
from typing import Any

from uavlink.mavlink.rejects import drop_unfinished_frame

log = logging.getLogger(__name__)

_LISTEN = {"udp": "udpin", "udpin": "udpin", "tcpin": "tcpin"}
_SEND = {"udpout": "udpout", "tcp": "tcp", "tcpout": "tcp"}


def normalize_connection(url: str) -> str:
    """The pymavlink form of ``url``; ValueError (one line) when it is not understood."""
    text = str(url).strip()
    scheme, sep, rest = text.partition(":")
    scheme = scheme.lower()
    if not sep or scheme not in _LISTEN and scheme not in _SEND:
        raise ValueError(
            f"unsupported connection {url!r}: use udp:HOST:PORT, udpout:HOST:PORT, udp:PORT, "
            "udpin://HOST:PORT, udpout://HOST:PORT, tcp:HOST:PORT or tcpin:HOST:PORT"
        )
    if rest.startswith("//"):
        rest = rest[2:]
    host, colon, port_text = rest.rpartition(":")
    if not colon:
        host, port_text = "", rest
    port = _parse_port(port_text, url)
    listen = scheme in _LISTEN
    if not host:
        if not listen:
            raise ValueError(f"connection {url!r} sends, so it needs HOST:PORT")
        host = "0.0.0.0"
    if port == 0 and not listen:
        raise ValueError(f"connection {url!r} needs a destination port in 1..65535")
    return f"{(_LISTEN if listen else _SEND)[scheme]}:{host}:{port}"


# Ports free_udp_port picks from: below Linux's default ephemeral range (32768-60999,
# /proc/sys/net/ipv4/ip_local_port_range) and macOS's and IANA's (49152-65535), above the ports
# PX4 SITL and ground stations use (14540-14580, 14550, 18570). A port the kernel hands out for
# bind(("", 0)) or an unbound sendto comes from the ephemeral range, so it cannot take a port
# picked here in the moment between the pick and its bind (a flight's listening port was once
# taken that way).
_PICK_PORTS = range(20000, 32768)
_PICK_TRIES = 64


def is_listening(url: str) -> bool:
    """Whether a normalised ``url`` listens (``udpin``, ``tcpin``) rather than connects or sends."""
    return url.partition(":")[0] in _LISTEN.values()


def open_mavlink(url: str, **kwargs: Any) -> Any:
    """``pymavlink.mavutil.mavlink_connection(url, **kwargs)`` for a normalised ``url``, less three of
    its habits. Its UDP listen binds with SO_REUSEADDR, so a second listener on a port another
    process (or another link of the same fleet) holds opens without error and never hears a packet
    (Linux hands each datagram to one of them): the port is first bound alone, which fails with
    EADDRINUSE as it should. A refused TCP connect prints its retries on stdout: they go to the
    debug log. And its UDP parser carries an unfinished frame into the next datagram: a UDP
    connection reads each datagram as whole packets (:func:`datagram_framed`). OSError as pymavlink
    raises it."""
    from uavlink.mavlink.dialect import mavutil  # MAVLink 2, whatever was imported before

    scheme, _, rest = url.partition(":")
    if scheme == "udpin":
        host, _, port = rest.rpartition(":")
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as alone:
            alone.bind((host, int(port)))
    said = io.StringIO()
    try:
        with contextlib.redirect_stdout(said):
            conn = mavutil.mavlink_connection(url, **kwargs)
        if isinstance(conn, mavutil.mavudp):
            datagram_framed(conn)
        return conn
    finally:
        if said.getvalue().strip():
            log.debug("pymavlink on %s: %s", url, " / ".join(said.getvalue().split("\n")).strip())


def datagram_framed(conn: Any) -> None:
    """Make a pymavlink UDP connection read each datagram as whole packets: its parser drops the
    frame the last datagram left unfinished before it reads the next (``drop_unfinished_frame``)."""
    read = conn.recv

    def recv(n: int | None = None) -> Any:
        data = read(n)
        if data:
            drop_unfinished_frame(conn.mav)
        return data

    conn.recv = recv


def free_udp_port(host: str = "127.0.0.1") -> int:
    """A UDP port that was free a moment ago (for tests and embedding), outside the kernel's
    ephemeral ports where one is free there (``_PICK_PORTS``), else any the kernel gives."""
    return free_udp_ports(1, host)[0]


def free_udp_ports(count: int, host: str = "127.0.0.1") -> list[int]:
    """``count`` distinct UDP ports, each picked as :func:`free_udp_port` picks one."""
    rng = random.SystemRandom()  # not the seeded streams: a port is no part of a result
    ports: list[int] = []
    for _ in range(_PICK_TRIES * count):
        if len(ports) == count:
            return ports
        port = rng.choice(_PICK_PORTS)
        if port not in ports and _bound_port(host, port) is not None:
            ports.append(port)
    while len(ports) < count:  # every try taken: the kernel's picks
        kernel_port = _bound_port(host, 0)
        if kernel_port is not None and kernel_port not in ports:
            ports.append(kernel_port)
    return ports


def _bound_port(host: str, port: int) -> int | None:
    """The port a UDP socket bound to ``(host, port)`` got (0: the kernel picks), or None when
    that port is taken; the socket is closed again."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        try:
            s.bind((host, port))
        except OSError:
            return None
        return int(s.getsockname()[1])


def _parse_port(text: str, url: str) -> int:
    try:
        port = int(text)
    except ValueError:
        raise ValueError(f"connection {url!r}: port {text!r} is not a number") from None
    if not 0 <= port <= 65535:
        raise ValueError(f"connection {url!r}: port {port} outside 0..65535")
    return port
