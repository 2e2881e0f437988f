"""Health check of a deployment over its bus: router reachable, fusion token, samples flowing."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Sequence

import pydantic
import zenoh

from hil.bus.config import BusConfig
from hil.bus.keys import Topic
from hil.bus.message import Message
from hil.bus.security import ClientSecurity
from hil.bus.session import Bus

__all__ = ["check_bus"]


def check_bus(
    connect: str,
    vehicle: str = "sim1",
    *,
    alive: bool = False,
    keys: Sequence[str] = (),
    timeout_s: float = 5.0,
    report: Callable[[str], object] | None = None,
    security: ClientSecurity | None = None,
    auth_key: bytes | None = None,
) -> int:
    """Check a running deployment through its Zenoh router; return the exit code.

    Parameters
    ----------
    connect : str
        Router endpoint, e.g. ``tcp/zenohd:7447``.
    vehicle : str
        Vehicle whose ``fusion/alive`` token ``alive`` asks for.
    alive : bool
        Require the fusion service's liveliness token.
    keys : sequence of str
        Key expressions on which a sample must arrive within ``timeout_s``.
    timeout_s : float
        Overall time budget, s.
    report : callable, optional
        Receives one line saying why the check failed (nothing is printed here).
    security : ClientSecurity, optional
        usrpwd / TLS / mTLS identity for the router.
    auth_key : bytes, optional
        Shared payload key: then ``alive`` also needs the fusion to answer a challenge (a
        token declared by anyone else is reported as unverified), and only correctly tagged
        samples count on ``keys``.

    Returns
    -------
    int
        0 healthy (the router answers, and the token exists / a sample arrived on every key),
        1 unhealthy, 2 bad input (an endpoint or vehicle that is not valid).
    """
    say = report if report is not None else _silent
    try:
        return _check(connect, vehicle, alive=alive, keys=keys, timeout_s=timeout_s, say=say,
                      security=security, auth_key=auth_key)
    except (ValueError, pydantic.ValidationError) as exc:
        say(f"error: {exc}")
        return 2
    except zenoh.ZError as exc:  # a key expression zenoh refuses (bad input, not ill health)
        say(f"error: {exc}")
        return 2


def _silent(_line: str) -> None:
    pass


def _check(
    connect: str,
    vehicle: str,
    *,
    alive: bool,
    keys: Sequence[str],
    timeout_s: float,
    say: Callable[[str], object],
    security: ClientSecurity | None,
    auth_key: bytes | None,
) -> int:
    deadline = time.monotonic() + timeout_s
    seen: dict[str, threading.Event] = {k: threading.Event() for k in keys}
    config = BusConfig(connect_timeout_s=min(max(timeout_s, 0.1), 60.0))
    with Bus(connect, vehicle=vehicle, config=config, security=security,
             auth_key=auth_key) as bus:
        for k, ev in seen.items():

            def on_sample(_msg: Message, ev: threading.Event = ev) -> None:
                ev.set()

            bus.subscribe_key(k, on_sample)
        if not bus.wait_connected(max(deadline - time.monotonic(), 0.0)):
            say(f"no router at {connect}")
            return 1
        if alive and not bus.fusion_alive(timeout_s=max(deadline - time.monotonic(), 0.1)):
            say(f"no {bus.key(Topic.ALIVE)} token")
            return 1
        if (alive and bus.authenticated
                and not bus.verify_fusion(timeout_s=max(deadline - time.monotonic(), 0.1))):
            say(f"{bus.key(Topic.ALIVE)} token present but no fusion holding the key answered "
                "the challenge on fusion/config: forged token?")
            return 1
        for k, ev in seen.items():
            if not ev.wait(max(deadline - time.monotonic(), 0.0)):
                rejected = bus.stats().unauthenticated + bus.stats().replayed
                say(f"nothing on {k} within {timeout_s} s"
                    + (f" ({rejected} unauthenticated samples dropped: {bus.last_rejected})"
                       if rejected else ""))
                return 1
    return 0
