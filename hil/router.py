"""In-process Zenoh router: ``hilnav up`` needs no separate zenohd.

The ``eclipse-zenoh`` wheel contains the whole Zenoh runtime, so a session opened in ``router``
mode with a TCP listener *is* a router: :class:`hil.bus.Bus` clients connect to its endpoint and
route through it exactly as through zenohd. Multicast scouting is off: only processes told the
endpoint join (nothing leaks onto, or is picked up from, the LAN). The admin space is off, and a
router refuses to listen beyond loopback unless its clients must authenticate (usrpwd or mTLS,
see :class:`hil.bus.security.RouterSecurity`) or ``insecure`` is set.

Example::

    with zenoh_router() as endpoint:                  # "tcp/127.0.0.1:<free port>"
        with Bus(endpoint, vehicle="sim1") as bus:
            ...
"""

from __future__ import annotations

import contextlib
import json
import signal
import socket
import sys
import threading
import time
from collections.abc import Iterator, Sequence
from typing import Final, Self

import zenoh

from hil.bus import validate_endpoint
from hil.bus.security import RouterSecurity

__all__ = ["ZenohRouter", "free_tcp_port", "router_main", "zenoh_router"]

_OPEN_ATTEMPTS: Final = 5


def free_tcp_port(host: str = "127.0.0.1") -> int:
    """A TCP port that was free on ``host`` a moment ago (the OS's pick for port 0)."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind((host, 0))
        return int(s.getsockname()[1])


def _router_config(listen: Sequence[str], security: RouterSecurity) -> zenoh.Config:
    security.check_listen(listen)
    cfg = {
        "mode": "router",
        "listen": {"endpoints": list(listen), "exit_on_failure": True},
        # no multicast discovery; no start-up delay waiting for scouted peers (there are none)
        "scouting": {"multicast": {"enabled": False}, "delay": 0},
        **security.zenoh_config(),
    }
    return zenoh.Config.from_json5(json.dumps(cfg))


class ZenohRouter:
    """A Zenoh router living in this process.

    Parameters
    ----------
    port : int, optional
        TCP port to listen on; None picks a free one (kept across :meth:`close` /
        :meth:`open`, so clients find a restarted router at the same endpoint).
    host : str
        Address to listen on (``"127.0.0.1"``: this machine only; ``"0.0.0.0"``: every
        interface, refused without client authentication unless ``security.insecure``).
    security : RouterSecurity, optional
        Authentication, TLS and access control (default: none, loopback only). With a TLS
        certificate the router listens on ``tls/`` instead of ``tcp/``.

    Notes
    -----
    :meth:`open` raises ``ValueError`` when the port cannot be bound. A router whose port was
    chosen here retries a few other free ports first (another process may grab a port between
    the probe and the bind).
    """

    def __init__(
        self, port: int | None = None, *, host: str = "127.0.0.1",
        security: RouterSecurity | None = None,
    ) -> None:
        if port is not None and not (0 < port < 65536):
            raise ValueError(f"port must be in 1..65535, got {port}")
        self.host = host
        self.security = security or RouterSecurity()
        self.security.check_listen([self.endpoint_at(0)])
        self._pick_port = port is None
        self.port = free_tcp_port(host) if port is None else port
        self._session: zenoh.Session | None = None

    def endpoint_at(self, port: int) -> str:
        """``tcp/<host>:<port>`` (``tls/`` when the router has a certificate)."""
        proto = "tls" if self.security.tls_cert is not None else "tcp"
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"{proto}/{host}:{port}"

    @property
    def endpoint(self) -> str:
        """Where clients connect: ``tcp/<host>:<port>`` (``tls/...`` with a certificate)."""
        return self.endpoint_at(self.port)

    @property
    def is_open(self) -> bool:
        """Whether the router is running."""
        return self._session is not None

    def open(self) -> Self:
        """Start routing (again, after :meth:`close`, on the same port)."""
        if self._session is not None:
            return self
        attempts = _OPEN_ATTEMPTS if self._pick_port else 1
        for attempt in range(attempts):
            try:
                self._session = zenoh.open(_router_config([self.endpoint], self.security))
                return self
            except zenoh.ZError as exc:
                if attempt + 1 == attempts:
                    raise ValueError(
                        f"cannot start a Zenoh router on {self.endpoint}: {exc}"
                    ) from None
                self.port = free_tcp_port(self.host)
        return self  # pragma: no cover - the loop returns or raises

    def close(self) -> None:
        """Stop routing; connected clients lose the router and retry until it is back."""
        session, self._session = self._session, None
        if session is not None:
            session.close()

    def __enter__(self) -> Self:
        return self.open()

    def __exit__(self, *_exc: object) -> None:
        self.close()


@contextlib.contextmanager
def zenoh_router(
    port: int | None = None, *, host: str = "127.0.0.1", security: RouterSecurity | None = None,
) -> Iterator[str]:
    """Run an in-process router for the duration of the ``with`` block; yield its endpoint.

    Parameters
    ----------
    port : int, optional
        TCP port (None: a free one).
    host : str
        Listen address.
    security : RouterSecurity, optional
        Authentication, TLS, access control (see :class:`ZenohRouter`).

    Yields
    ------
    str
        ``"tcp/<host>:<port>"`` for :class:`hil.bus.Bus` ``connect=``.
    """
    with ZenohRouter(port, host=host, security=security) as router:
        yield router.endpoint


def router_main(
    *, listen: str = "tcp/127.0.0.1:7447", duration_s: float | None = None,
    security: RouterSecurity | None = None,
) -> int:
    """Run a router until Ctrl-C / SIGTERM (or ``duration_s``); for ``hilnav router``.

    Parameters
    ----------
    listen : str
        ``tcp/HOST:PORT`` endpoint(s), comma separated.
    duration_s : float, optional
        Stop after this many seconds (None: run until interrupted).
    security : RouterSecurity, optional
        Authentication, TLS, access control; without it only loopback endpoints are allowed.

    Returns
    -------
    int
        0 after a clean stop. Raises ``ValueError`` for a bad endpoint or a busy port.
    """
    endpoints = [validate_endpoint(e.strip()) for e in listen.split(",") if e.strip()]
    if not endpoints:
        raise ValueError("listen needs at least one endpoint, e.g. tcp/127.0.0.1:7447")
    if duration_s is not None and not duration_s > 0.0:
        raise ValueError(f"duration must be > 0 s, got {duration_s}")
    config = _router_config(endpoints, security or RouterSecurity())
    stop = threading.Event()
    previous = None
    if threading.current_thread() is threading.main_thread():
        previous = signal.signal(signal.SIGTERM, lambda *_: stop.set())
    try:
        session = zenoh.open(config)
    except zenoh.ZError as exc:
        raise ValueError(f"cannot start a Zenoh router on {listen}: {exc}") from None
    print(f"zenoh router listening on {', '.join(endpoints)}", file=sys.stderr)
    try:
        deadline = None if duration_s is None else time.monotonic() + duration_s
        while not stop.is_set():
            left = 0.5 if deadline is None else min(0.5, deadline - time.monotonic())
            if left <= 0.0:
                break
            stop.wait(left)
    except KeyboardInterrupt:
        pass
    finally:
        session.close()
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)
    return 0
