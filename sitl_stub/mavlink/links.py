"""The vehicle's MAVLink links: PX4 SITL's UDP port pairs, or the connections given with --connect.

PX4 SITL instance N starts one ``mavlink`` module per link (ROMFS/px4fmu_common/init.d-posix/
px4-rc.mavlink): the GCS link ``mavlink start -x -u $((18570+N)) -r 4000000 -f`` (remote port
14550, the module's DEFAULT_REMOTE_PORT_UDP) and the API/offboard link ``mavlink start -x -u
$((14580+N)) -r 4000000 -f -m onboard -o $((14540+N))`` (14549 for every N > 9). Each link binds
its local port, sends to 127.0.0.1:remote and, once a peer on localhost has sent something, talks
to that peer's address and port (mavlink_receiver.cpp, ``set_client_source_initialized``):
MAVSDK's ``udpin://0.0.0.0:14540`` answers the source port, so the vehicle must receive on 14580+N.

Every link carries all telemetry; a reply goes back on the link its request came on (a
:class:`Route` says which link is being answered); each link has its own pymavlink ``MAVLink``
encoder per component, so sequence numbers and signing timestamps rise per link as in PX4.
"""

from __future__ import annotations

import errno
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any

from uavlink.mavlink.connection import datagram_framed, normalize_connection, open_mavlink
from uavlink.mavlink.dialect import mavlink, mavutil

API_LOCAL_PORT = 14580  # + instance: where the API link sends from and receives
API_REMOTE_PORT = 14540  # + instance: MAVSDK's default udpin://0.0.0.0:14540
API_LAST_REMOTE_PORT = 14549  # PX4: instances > 9 share this remote port
GCS_LOCAL_PORT = 18570  # + instance
GCS_REMOTE_PORT = 14550  # QGroundControl / MAVProxy, the same for every instance
LOCALHOST = "127.0.0.1"
MAX_INSTANCE = 254  # system id instance + 1 <= 255


@dataclass(frozen=True)
class LinkSpec:
    """One link: a normalised pymavlink connection string and, for a PX4 port pair, the local
    port it sends from and receives on (pymavlink's udpout cannot choose one)."""

    name: str
    connect: str
    local_port: int | None = None

    def describe(self) -> str:
        if self.local_port is None:
            return self.connect
        remote = self.connect.split(":", 1)[1]
        return f"{self.name} udp {LOCALHOST}:{self.local_port}->{remote}"


def px4_links(instance: int = 0) -> tuple[LinkSpec, LinkSpec]:
    """PX4 SITL instance ``instance``'s API and GCS links."""
    if not 0 <= instance <= MAX_INSTANCE:
        raise ValueError(f"instance must be in 0..{MAX_INSTANCE}, got {instance}")
    api_remote = API_REMOTE_PORT + instance if instance <= 9 else API_LAST_REMOTE_PORT
    return (
        LinkSpec("api", f"udpout:{LOCALHOST}:{api_remote}", API_LOCAL_PORT + instance),
        LinkSpec("gcs", f"udpout:{LOCALHOST}:{GCS_REMOTE_PORT}", GCS_LOCAL_PORT + instance),
    )


def connect_links(urls: Sequence[str]) -> tuple[LinkSpec, ...]:
    """One link per connection URL (any form :func:`normalize_connection` takes)."""
    return tuple(LinkSpec(f"link{i}", normalize_connection(url)) for i, url in enumerate(urls))


class PortPairUdp(mavutil.mavudp):
    """pymavlink's udpout, bound to a local port, that locks on to the first peer that talks to it.

    pymavlink 2.4.50's ``mavudp`` has no source-port option (its udpout socket is bound by the
    kernel on first send), so the socket is bound here before anything is sent.
    """

    def __init__(self, spec: LinkSpec, source_system: int, source_component: int) -> None:
        assert spec.local_port is not None and spec.connect.startswith("udpout:")
        super().__init__(
            spec.connect[len("udpout:") :],
            input=False,
            source_system=source_system,
            source_component=source_component,
        )
        try:
            self.port.bind((LOCALHOST, spec.local_port))
        except OSError:
            self.port.close()
            raise
        self.peer: tuple[str, int] | None = None
        datagram_framed(self)  # as open_mavlink's UDP connections: each datagram whole packets

    def recv(self, n: int | None = None) -> bytes | str:
        try:
            data, addr = self.port.recvfrom(mavutil.UDP_MAX_PACKET_LEN)
        except OSError as e:
            if e.errno in (errno.EAGAIN, errno.EWOULDBLOCK, errno.ECONNREFUSED):
                return ""
            raise
        if self.peer is None:  # PX4 answers the first localhost peer from then on
            self.peer = addr[:2]
            self.destination_addr = self.peer
        return data


class Link:
    """One open link: its pymavlink connection and the autopilot's encoder on it (``mav``)."""

    def __init__(self, spec: LinkSpec, index: int, system_id: int, component_id: int) -> None:
        self.spec = spec
        self.index = index
        if spec.local_port is not None:
            self.conn: Any = PortPairUdp(spec, system_id, component_id)
        else:
            self.conn = open_mavlink(
                spec.connect, source_system=system_id, source_component=component_id
            )
        self.mav = self.conn.mav

    def encoder(self, component_id: int) -> Any:
        """A ``MAVLink`` encoder for another component of the system, sending on this link."""
        return mavlink.MAVLink(self.conn, srcSystem=self.mav.srcSystem, srcComponent=component_id)

    @property
    def fd(self) -> int:
        return self.conn.fd  # changes on a TCP accept: read it each time

    def address(self) -> tuple[str, int]:
        """Local (host, port) of the link's socket."""
        sock = getattr(self.conn, "listen", None) or self.conn.port  # tcpin listens separately
        host, port = sock.getsockname()[:2]
        return str(host), int(port)

    def close(self) -> None:
        self.conn.close()


def open_links(specs: Sequence[LinkSpec], system_id: int, component_id: int) -> list[Link]:
    """Open every link, or none: an OSError (a port in use) closes those already open."""
    links: list[Link] = []
    try:
        for i, spec in enumerate(specs):
            links.append(Link(spec, i, system_id, component_id))
    except OSError as exc:
        for link in links:
            link.close()
        raise OSError(exc.errno, f"{spec.describe()}: {exc.strerror or exc}") from exc
    return links


class Route:
    """Which links a send goes to: all of them, or the one whose request is being answered."""

    def __init__(self) -> None:
        self.answering: int | None = None

    @contextmanager
    def answering_link(self, index: int) -> Iterator[None]:
        self.answering = index
        try:
            yield
        finally:
            self.answering = None

    def targets(self, n_links: int) -> Sequence[int]:
        return range(n_links) if self.answering is None else (self.answering,)


_EVERYONE = Route()


class Fanout:
    """Sends like a pymavlink ``MAVLink`` object (``x_send(...)``) on the links its route picks,
    encoding with each link's own encoder for the component."""

    def __init__(self, encoders: Sequence[Any], route: Route = _EVERYONE) -> None:
        self.encoders = list(encoders)
        self.route = route
        self.srcSystem = self.encoders[0].srcSystem
        self.srcComponent = self.encoders[0].srcComponent

    def everyone(self) -> Fanout:
        """The same encoders, always sending on every link (STATUSTEXT, as PX4's mavlink_log)."""
        return Fanout(self.encoders)

    def send(self, msg: Any) -> None:
        """Send a message built with an ``x_encode`` method (packed anew on each link)."""
        for i in self.route.targets(len(self.encoders)):
            self.encoders[i].send(msg)

    def __getattr__(self, name: str) -> Callable[..., Any]:
        if name.endswith("_encode"):  # builds a message, sends nothing: any encoder will do
            return getattr(self.encoders[0], name)
        if not name.endswith("_send"):
            raise AttributeError(name)

        def send(*args: Any, **kwargs: Any) -> None:
            for i in self.route.targets(len(self.encoders)):
                getattr(self.encoders[i], name)(*args, **kwargs)

        return send
