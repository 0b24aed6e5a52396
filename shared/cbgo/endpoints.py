"""Listening endpoints: whether a process can listen where it is told to, and who can reach it.

A Zenoh endpoint reads ``PROTOCOL/HOST:PORT`` (``tcp/127.0.0.1:7447``, ``tls/[::]:7447``),
optionally followed by ``?metadata`` or ``#config``. This module answers three questions before
a session is opened, so that the answer is a sentence with the fix instead of a Zenoh error:

- can it listen there? (`check_can_listen`: the port may be taken, the address not this host's);
- who can reach it? (`exposed_without_tls`: an endpoint on a non-loopback address without TLS
  lets every host that reaches this one publish on the cell's keys, ``robot/act`` included).
"""

from __future__ import annotations

import errno
import ipaddress
import json
import re
import socket
from dataclasses import dataclass

from cbgo.errors import ConfigError

STREAM_PROTOCOLS = ("tcp", "tls", "ws")
DATAGRAM_PROTOCOLS = ("udp", "quic")
SECURE_PROTOCOLS = ("tls", "quic")
EXPOSURE_FIX = ("listen on loopback (the default, tcp/127.0.0.1:7447) where every process "
                "runs on this host; across hosts, use TLS and the router's access control: "
                "`cbgo certs make`, then deploy/compose.tls.yaml or the files in deploy/tls/ "
                "(deploy/README.md, \"Security: TLS and access control\")")


@dataclass(frozen=True)
class Endpoint:
    """One parsed endpoint.

    Attributes:
        text: the endpoint as written.
        protocol: ``tcp``, ``tls``, ``udp``, ...
        host: the address or host name, without brackets ("" for none).
        port: the port (0: any free one).
    """

    text: str
    protocol: str
    host: str
    port: int

    @property
    def secure(self) -> bool:
        """Whether the protocol encrypts and authenticates (TLS, QUIC)."""
        return self.protocol in SECURE_PROTOCOLS


def parse(text: str) -> Endpoint | None:
    """Returns the endpoint's parts, or None for one without HOST:PORT (a Unix socket)."""
    protocol, _, address = text.partition("/")
    address = re.split(r"[?#]", address, maxsplit=1)[0]
    host, _, port = address.rpartition(":")
    if not protocol or not port.isdigit():
        return None
    return Endpoint(text, protocol, host.strip("[]"), int(port))


def _addresses(host: str) -> list[str]:
    """The IP addresses a host name or address stands for ([] when it does not resolve)."""
    try:
        return [info[4][0] for info in socket.getaddrinfo(host or "0.0.0.0", None)]
    except (OSError, UnicodeError):
        return []


def is_loopback(endpoint: Endpoint) -> bool:
    """Whether only processes on this host can reach the endpoint."""
    addresses = _addresses(endpoint.host)
    return bool(addresses) and all(ipaddress.ip_address(a.split("%")[0]).is_loopback
                                   for a in addresses)


def exposed_without_tls(endpoints: list[str]) -> list[str]:
    """Returns the endpoints that other hosts can reach and that are not TLS."""
    out = []
    for text in endpoints:
        endpoint = parse(text)
        if endpoint is not None and not endpoint.secure and not is_loopback(endpoint):
            out.append(text)
    return out


def exposure_warning(endpoints: list[str]) -> str | None:
    """Returns the warning for endpoints open to other hosts without TLS (None: there are none)."""
    exposed = exposed_without_tls(endpoints)
    if not exposed:
        return None
    return (f"listening on {', '.join(exposed)} without TLS: every host that can reach this "
            "one can publish on this cell's keys, cbgo/robot/act and cbgo/robot/stop included. "
            f"Keep it to a network you trust, or {EXPOSURE_FIX}")


def check_can_listen(endpoints: list[str], option: str = "--listen", hint: str = "") -> None:
    """Binds each endpoint's port for a moment, to fail with the fix before Zenoh would.

    Args:
        endpoints: the endpoints the process is about to listen on.
        option: the flag that sets them, named in the message.
        hint: a sentence added to a busy port's message (what the user may want instead).

    Raises:
        ConfigError: a port is taken, or an address is not one of this host's.
    """
    for text in endpoints:
        endpoint = parse(text)
        if endpoint is None or endpoint.port == 0:
            continue
        if endpoint.protocol in STREAM_PROTOCOLS:
            kind = socket.SOCK_STREAM
        elif endpoint.protocol in DATAGRAM_PROTOCOLS:
            kind = socket.SOCK_DGRAM
        else:
            continue
        problem = _bind_problem(endpoint, kind)
        if problem is not None:
            raise ConfigError(_cannot_listen(endpoint, problem, option, hint))


def _bind_problem(endpoint: Endpoint, kind: int) -> OSError | None:
    try:
        infos = socket.getaddrinfo(endpoint.host or "0.0.0.0", endpoint.port, type=kind)
    except (OSError, UnicodeError) as e:
        return OSError(errno.EADDRNOTAVAIL, f"{endpoint.host!r} does not resolve ({e})")
    family, _, _, _, address = infos[0]
    with socket.socket(family, kind) as probe:
        # As the listener itself will: a port whose last connection lingers in TIME_WAIT is
        # free to listen on.
        probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            probe.bind(address)
        except OSError as e:
            return e
    return None


def _cannot_listen(endpoint: Endpoint, error: OSError, option: str, hint: str) -> str:
    where = f"cannot listen on {endpoint.text}"
    if error.errno == errno.EADDRINUSE:
        return (f"{where}: port {endpoint.port} is in use (another cbgo router or `cbgo up`?"
                f" `cbgo ls --connect {local_endpoint(endpoint.text)}` shows what runs there)."
                f" {hint + ' ' if hint else ''}Choose a free port with {option} "
                f"{endpoint.protocol}/{endpoint.host or '127.0.0.1'}:PORT")
    if error.errno in (errno.EADDRNOTAVAIL, errno.EAFNOSUPPORT):
        return (f"{where}: {endpoint.host} is not an address of this host ({error.strerror});"
                f" give one of its addresses with {option}, e.g. {option} "
                f"{endpoint.protocol}/127.0.0.1:{endpoint.port}")
    if error.errno == errno.EACCES:
        return (f"{where}: port {endpoint.port} needs privileges; choose a port above 1023 "
                f"with {option}")
    return f"{where}: {error.strerror or error}; choose another endpoint with {option}"


def local_endpoint(listen: str) -> str:
    """Returns the endpoint a process on this host dials to reach a listener on `listen`."""
    endpoint = parse(listen)
    if endpoint is None:
        return listen
    host = endpoint.host
    if host in ("", "0.0.0.0"):
        host = "127.0.0.1"
    elif host == "::":
        host = "::1"
    return f"{endpoint.protocol}/{f'[{host}]' if ':' in host else host}:{endpoint.port}"


def listen_endpoints(conf) -> list[str]:
    """Returns the endpoints a `zenoh.Config` will listen on (none for a client)."""
    try:
        mode = json.loads(conf.get_json("mode")) or "peer"
        value = json.loads(conf.get_json("listen/endpoints"))
    except Exception:  # zenoh raises ZError for a key it does not know  # noqa: BLE001
        return []
    if isinstance(value, dict):  # Zenoh's per-mode defaults
        value = value.get(mode, [])
    return [str(v) for v in value] if isinstance(value, list) and mode != "client" else []
