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

import socket

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


def free_udp_port(host: str = "127.0.0.1") -> int:
    """A UDP port that was free a moment ago (for tests and embedding)."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind((host, 0))
        return int(s.getsockname()[1])


def _parse_port(text: str, url: str) -> int:
    try:
        port = int(text)
    except ValueError:
        raise ValueError(f"connection {url!r}: port {text!r} is not a number") from None
    if not 0 <= port <= 65535:
        raise ValueError(f"connection {url!r}: port {port} outside 0..65535")
    return port
