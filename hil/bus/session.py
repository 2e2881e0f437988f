"""The Zenoh session of one hilnav process: non-blocking publishing, subscriptions, liveliness,
the configuration queryable.

Publishing never blocks the caller (the filter loop): :meth:`Bus.publish` rate-limits per topic,
serialises, and appends to a bounded queue that a publisher thread drains into Zenoh publishers
declared with congestion control ``DROP``. A full queue drops its *oldest* message (the freshest
estimate matters most) and counts it; :meth:`Bus.stats` reports every counter. (The caller's
thread never puts straight into Zenoh, even when nothing is queued: with ``DROP`` a burst loses
samples (innovations of a lockstep run at ``--speed 1000``); with ``BLOCK`` and one send token
ordering the two paths nothing is lost, but the put takes 0.23-0.38 ms in the filter's thread
against 0.07 ms in the publisher thread, so the estimate reaches a direct subscriber no
sooner.)

Connection: the default is a Zenoh *client* that connects to a router (``hilnav up``'s in-process
router, see :mod:`hil.router`, or zenohd). A Zenoh (1.10) client cannot open a session while no
router is reachable: ``connect/exit_on_failure: false`` only makes *peers and routers* connect
in the background; a client's open blocks for ``connect/timeout_ms`` (forever for -1) and then
fails. So the bus opens its session in the publisher thread, one attempt of
``BusConfig.connect_timeout_s`` at a time, until the router answers; meanwhile publications wait
in the queue (bounded, oldest dropped) and subscriptions, queryables and liveliness tokens are
declared as soon as the session exists. Once open, the Zenoh client reconnects by itself when the
router goes away and comes back, and re-declares everything.

Security (see :mod:`hil.bus.security` and :mod:`hil.bus.auth`): ``security`` logs the session in
(usrpwd) and sets up TLS / mTLS; ``auth_key`` tags every published sample with an HMAC and makes
subscriptions drop samples whose tag is missing, wrong or replayed (counted in
``unauthenticated`` / ``replayed``), so a forged estimate never reaches a callback.
"""

from __future__ import annotations

import json
import threading
import time
from collections import deque
from collections.abc import Callable, Mapping, Sequence
from typing import Any, Literal, Self

import numpy as np
import zenoh

from hil.bus.auth import PayloadAuth, Verdict
from hil.bus.config import BusConfig
from hil.bus.keys import PUBLISHED_TOPICS, Topic, key, validate_endpoint, validate_vehicle
from hil.bus.message import Message, message_from_sample
from hil.bus.payloads import (
    config_reply_payload,
    encode,
    error_payload,
    estimate_payload,
    event_payload,
    fusion_event_payload,
    innovation_payload,
    sample_payload,
    sample_topic,
    status_payload,
    truth_payload,
)
from hil.bus.rate import RateLimiter
from hil.bus.schemas import SCHEMAS
from hil.bus.security import ClientSecurity
from hil.bus.stats import COUNTER_NAMES, BusStats

__all__ = ["Bus", "Declaration"]


class Declaration:
    """A subscription, queryable or liveliness token of a :class:`Bus`.

    Declared as soon as the session exists (immediately if it is open); :meth:`undeclare`
    removes it. Zenoh re-declares it by itself on a router that restarts.
    """

    def __init__(self, bus: Bus, kind: str, key_expr: str, make: Callable[[Any], Any]) -> None:
        self.kind = kind
        self.key_expr = key_expr
        self._bus = bus
        self._make = make
        self._handle: Any = None
        self._undeclared = False

    @property
    def declared(self) -> bool:
        """True once Zenoh holds the declaration."""
        return self._handle is not None

    def _apply(self, session: zenoh.Session) -> None:
        if self._handle is None and not self._undeclared:
            self._handle = self._make(session)

    def undeclare(self) -> None:
        """Remove the declaration (idempotent)."""
        with self._bus._lock:
            self._undeclared = True
            if self in self._bus._declarations:
                self._bus._declarations.remove(self)
            handle, self._handle = self._handle, None
        if handle is not None:
            try:
                handle.undeclare()
            except zenoh.ZError:
                pass  # the session is already closed: nothing left to remove


_Mode = Literal["client", "peer"]


class Bus:
    """Zenoh session of one hilnav process, in the key space of one vehicle.

    Parameters
    ----------
    connect : str, optional
        Router (client mode) or peer (peer mode) endpoint(s), comma separated, e.g.
        ``"tcp/127.0.0.1:7447"``. None is only valid in peer mode: a standalone session
        (in-process publish/subscribe, no network).
    vehicle : str
        The ``<vehicle>`` key chunk of this process's topics.
    mode : {"client", "peer"}
        ``"client"`` (default): talk through a router; the session opens in the background and
        keeps retrying until the router answers, then Zenoh reconnects by itself after a router
        restart. ``"peer"``: connect to ``connect`` directly (Zenoh >= 1.9 routers no longer
        relay between two peers, so two peer-mode buses need a direct link: give one of them a
        ``listen`` endpoint and the other ``connect`` to it). A peer that also connects to a
        router serves both: the router's clients through the router, its direct peers
        without it. Only the endpoints given are used: no multicast or gossip discovery.
    listen : str, optional
        Peer mode only: endpoint(s) to listen on, comma separated (the peer-to-peer
        subscription mode of ``hilnav fusion --zenoh-listen``).
    config : BusConfig, optional
        Rates, queue size, connect timeout.
    security : ClientSecurity, optional
        usrpwd login and TLS / mTLS material (default: an open client).
    auth_key : bytes, optional
        Shared payload key (``HILNAV_ZENOH_KEY``): published samples carry an HMAC tag;
        received samples without a valid tag are dropped and counted; the ``fusion/config``
        queryable answers challenges (see :meth:`verify_fusion`).

    Notes
    -----
    Use as a context manager (or :meth:`open` / :meth:`close`). :meth:`publish` and the
    ``publish_*`` helpers never wait for the network: they may be called from the filter loop.
    Subscription callbacks run on Zenoh's threads: keep them short.
    """

    def __init__(
        self,
        connect: str | None = None,
        *,
        vehicle: str = "sim1",
        mode: _Mode = "client",
        listen: str | None = None,
        config: BusConfig | None = None,
        security: ClientSecurity | None = None,
        auth_key: bytes | None = None,
    ) -> None:
        if mode not in ("client", "peer"):
            raise ValueError(f"mode must be 'client' or 'peer', got {mode!r}")
        self.vehicle = validate_vehicle(vehicle)
        self.mode: _Mode = mode
        self.connect = self._endpoints(connect)
        self.listen = self._endpoints(listen)
        if mode == "client" and not self.connect:
            raise ValueError("client mode needs a router endpoint to connect to (connect=...)")
        if mode == "client" and self.listen:
            raise ValueError("listen endpoints are for peer mode only")
        self.config = config or BusConfig()
        self.security = security or ClientSecurity()
        self.security.check_endpoints(self.connect + self.listen)
        self._auth = PayloadAuth(auth_key) if auth_key is not None else None
        self._keys = {t: key(self.vehicle, t) for t in Topic}
        self._lock = threading.RLock()
        self._cond = threading.Condition(self._lock)
        self._queue: deque[tuple[Topic, str, bytes]] = deque()
        self._declarations: list[Declaration] = []
        self._publishers: dict[str, zenoh.Publisher] = {}
        self._session: zenoh.Session | None = None
        self._thread: threading.Thread | None = None
        self._first_attempt = threading.Event()
        self._stopping = False
        self._closed = False
        self._rate = RateLimiter(self.config)
        self._connected = False
        self._ever_connected = False
        self.last_error: str | None = None
        self.last_rejected: str | None = None
        """Why the last sample was dropped as unauthenticated or replayed (None: none was)."""
        self._c = dict.fromkeys(COUNTER_NAMES, 0)
        self._dropped_by_topic: dict[str, int] = {}

    @staticmethod
    def _endpoints(spec: str | None) -> list[str]:
        if spec is None:
            return []
        return [validate_endpoint(e.strip()) for e in spec.split(",") if e.strip()]

    # ------------------------------------------------------------------- lifecycle
    def __enter__(self) -> Self:
        return self.open()

    def __exit__(self, *_exc: object) -> None:
        self.close()

    def open(self) -> Self:
        """Start the publisher thread and the first session-open attempt; return self.

        Waits for that first attempt only (at most ``config.connect_timeout_s``): with a router
        up, the bus is connected on return; without one, it keeps trying in the background.
        """
        with self._lock:
            if self._closed:
                raise RuntimeError("the bus was closed; create a new one")
            if self._thread is not None:
                return self
            self._thread = threading.Thread(
                target=self._run, name=f"hilnav-bus-{self.vehicle}", daemon=True
            )
            self._thread.start()
        self._first_attempt.wait(self.config.connect_timeout_s + 5.0)
        return self

    def close(self) -> None:
        """Flush what is queued (best effort), undeclare everything, close the session."""
        with self._cond:
            if self._closed:
                return
            self._closed = True
            self._stopping = True
            self._cond.notify_all()
        if self._thread is not None:
            self._thread.join()
        with self._lock:
            declarations = list(self._declarations)
        for d in declarations:
            d.undeclare()
        for p in self._publishers.values():
            try:
                p.undeclare()
            except zenoh.ZError:
                pass
        self._publishers.clear()
        if self._session is not None:
            self._session.close()

    @property
    def authenticated(self) -> bool:
        """Whether samples are tagged and checked with a shared key."""
        return self._auth is not None

    @property
    def session(self) -> zenoh.Session | None:
        """The Zenoh session once open (None while no router has answered yet)."""
        return self._session

    def wait_connected(self, timeout_s: float) -> bool:
        """Block until the session is open and connected, at most ``timeout_s``; return it."""
        deadline = time.monotonic() + timeout_s
        while True:
            if self._session is not None and self._check_connected():
                return True
            if time.monotonic() >= deadline:
                return False
            time.sleep(0.02)

    def stats(self) -> BusStats:
        """Snapshot of the counters (the connection state is checked now)."""
        self._check_connected()
        with self._lock:
            return BusStats(
                connected=self._connected,
                queued=len(self._queue),
                dropped_by_topic=dict(self._dropped_by_topic),
                **self._c,
            )

    # ------------------------------------------------------------------- publishing
    def key(self, topic: Topic | str) -> str:
        """Key of ``topic`` for this bus's vehicle."""
        return key(self.vehicle, topic)

    def due(self, topic: Topic, time_us: int | None = None) -> bool:
        """Whether a message of ``topic`` at ``time_us`` would pass the rate limit (no side
        effect): call it before building an expensive payload."""
        return self._rate.due(topic, time_us)

    def publish(self, topic: Topic, payload: Mapping[str, Any], *, force: bool = False) -> bool:
        """Queue ``payload`` on ``topic`` (never blocks on the network).

        Parameters
        ----------
        topic : Topic
            A published topic (not ``CONFIG`` / ``ALIVE``).
        payload : mapping
            JSON object; ``schema_version`` is added when missing; ``time_us`` (simulated time)
            drives the rate limit when present.
        force : bool
            Bypass the rate limit (e.g. the last status before shutdown).

        Returns
        -------
        bool
            True if queued, False if skipped by the rate limit.

        Raises
        ------
        ValueError
            Unknown topic or a payload that is not valid JSON (NaN, unsupported types).
        RuntimeError
            The bus is not open (use ``with Bus(...)``) or already closed.
        """
        if not isinstance(topic, Topic) or topic not in PUBLISHED_TOPICS:
            raise ValueError(
                f"cannot publish on {topic!r}; published topics: "
                f"{', '.join(t.value for t in PUBLISHED_TOPICS)}"
            )
        if self._thread is None or self._closed:
            raise RuntimeError("the bus is not open: use `with Bus(...) as bus:`")
        time_us = payload.get("time_us") if isinstance(payload, Mapping) else None
        rate_t = int(time_us) if isinstance(time_us, (int, np.integer)) else None
        with self._lock:
            due = force or self._rate.take(topic, rate_t)
        if not due:
            with self._lock:
                self._c["decimated"] += 1
            return False
        data = encode(payload)
        self._enqueue(topic, self._keys[topic], data)
        return True

    def _enqueue(self, topic: Topic, key_expr: str, data: bytes) -> None:
        with self._cond:
            if len(self._queue) >= self.config.queue_size:
                old_topic, _, _ = self._queue.popleft()
                self._c["dropped_queue_full"] += 1
                self._dropped_by_topic[old_topic.value] = (
                    self._dropped_by_topic.get(old_topic.value, 0) + 1
                )
            self._queue.append((topic, key_expr, data))
            self._c["enqueued"] += 1
            self._cond.notify()

    def _publish_built(self, topic: Topic, time_us: int | None, build: Callable[[], dict]) -> bool:
        """Rate-limit first, build the payload only when it will be sent."""
        if not self.due(topic, time_us):
            with self._lock:
                self._c["decimated"] += 1
            return False
        return self.publish(topic, build())

    def publish_truth(self, truth: Any) -> bool:
        """Publish a Truth-like object on ``sim/truth`` (see :func:`truth_payload`)."""
        return self._publish_built(
            Topic.TRUTH, getattr(truth, "time_us", None), lambda: truth_payload(truth)
        )

    def publish_sample(self, sample: Any) -> bool:
        """Publish a sensor sample on ``sensors/<kind>`` (see :func:`sample_payload`)."""
        topic = sample_topic(sample)
        return self._publish_built(
            topic, getattr(sample, "time_us", None), lambda: sample_payload(sample)[1]
        )

    def publish_estimate(self, est: Any) -> bool:
        """Publish a NavEstimate-like object on ``fusion/estimate``."""
        return self._publish_built(
            Topic.ESTIMATE, getattr(est, "time_us", None), lambda: estimate_payload(est)
        )

    def publish_status(
        self,
        est: Any,
        *,
        bridge: Any = None,
        links: Mapping[str, Any] | None = None,
        force: bool = False,
        thermal: Any = None,
    ) -> bool:
        """Publish ``fusion/status`` with this bus's own counters in ``bus``."""
        if not force and not self.due(Topic.STATUS, getattr(est, "time_us", None)):
            with self._lock:
                self._c["decimated"] += 1
            return False
        payload = status_payload(est, bridge=bridge, links=links, bus=self.stats(),
                                 thermal=thermal)
        return self.publish(Topic.STATUS, payload, force=force)

    def publish_error(self, est: Any, truth: Any) -> bool:
        """Publish ``fusion/error`` = estimate - truth (see :func:`error_payload`)."""
        return self._publish_built(
            Topic.ERROR, getattr(est, "time_us", None), lambda: error_payload(est, truth)
        )

    def publish_innovation(
        self,
        time_us: int,
        source: str,
        innovation: Any,
        *,
        S: Any = None,
        test_ratio: float | None = None,
        accepted: bool,
    ) -> bool:
        """Publish one aiding update on ``fusion/innovations``."""
        return self.publish(
            Topic.INNOVATIONS,
            innovation_payload(
                time_us, source, innovation, S=S, test_ratio=test_ratio, accepted=accepted
            ),
        )

    def publish_event(
        self, time_us: int, event: str, message: str = "", detail: Mapping[str, Any] | None = None
    ) -> bool:
        """Publish a scenario event on ``scenario/events``."""
        return self.publish(Topic.EVENTS, event_payload(time_us, event, message, detail))

    def publish_fusion_event(
        self, time_us: int, event: str, severity: str, message: str = "",
        detail: Mapping[str, Any] | None = None,
    ) -> bool:
        """Publish a navigation event on ``fusion/events``."""
        return self.publish(Topic.FUSION_EVENTS,
                            fusion_event_payload(time_us, event, severity, message, detail))

    # ---------------------------------------------------------------- declarations
    def _declare(self, kind: str, key_expr: str, make: Callable[[Any], Any]) -> Declaration:
        if self._closed:
            raise RuntimeError("the bus is closed")
        d = Declaration(self, kind, key_expr, make)
        with self._lock:
            self._declarations.append(d)
            if self._session is not None:
                d._apply(self._session)
        return d

    def _wrap(self, callback: Callable[[Message], object]) -> Callable[[zenoh.Sample], None]:
        auth = self._auth

        def on_sample(sample: zenoh.Sample) -> None:
            key_expr = str(sample.key_expr)
            raw = sample.payload.to_bytes()
            if auth is not None:
                att = sample.attachment
                verdict = auth.verify(key_expr, raw, None if att is None else att.to_bytes())
                if verdict is not Verdict.OK:
                    with self._lock:
                        name = "replayed" if verdict is Verdict.REPLAYED else "unauthenticated"
                        self._c[name] += 1
                        self.last_rejected = f"{verdict.value} sample on {key_expr}"
                    return
            with self._lock:
                self._c["received"] += 1
            try:
                callback(message_from_sample(key_expr, raw))
            except Exception:  # a bad callback must not kill Zenoh's receive thread
                with self._lock:
                    self._c["callback_errors"] += 1

        return on_sample

    def subscribe(
        self,
        topic: Topic | Literal["**"],
        callback: Callable[[Message], object],
        *,
        vehicle: str | None = None,
    ) -> Declaration:
        """Call ``callback(Message)`` for every sample of ``topic`` (``"**"``: all topics).

        ``vehicle`` defaults to this bus's vehicle; ``"*"`` subscribes to every vehicle.
        """
        return self.subscribe_key(key(vehicle or self.vehicle, topic), callback)

    def subscribe_key(self, key_expr: str, callback: Callable[[Message], object]) -> Declaration:
        """Subscribe to any key expression (e.g. ``"hilnav/**"``)."""
        zenoh.KeyExpr(key_expr)  # raises on a malformed key expression, now rather than later
        on_sample = self._wrap(callback)
        return self._declare(
            "subscriber", key_expr, lambda s: s.declare_subscriber(key_expr, on_sample)
        )

    def subscribe_liveliness(
        self,
        callback: Callable[[str, bool], None],
        *,
        vehicle: str | None = None,
        history: bool = True,
    ) -> Declaration:
        """Call ``callback(key, alive)`` when a ``fusion/alive`` token appears or disappears.

        With ``history`` the tokens already present are reported on declaration.
        """
        key_expr = key(vehicle or self.vehicle, Topic.ALIVE)

        def on_sample(sample: zenoh.Sample) -> None:
            try:
                callback(str(sample.key_expr), sample.kind == zenoh.SampleKind.PUT)
            except Exception:
                with self._lock:
                    self._c["callback_errors"] += 1

        return self._declare(
            "liveliness-subscriber",
            key_expr,
            lambda s: s.liveliness().declare_subscriber(key_expr, on_sample, history=history),
        )

    def declare_liveliness(self) -> Declaration:
        """Declare this process's ``fusion/alive`` token (gone when the process or link dies)."""
        key_expr = self.key(Topic.ALIVE)
        return self._declare(
            "liveliness", key_expr, lambda s: s.liveliness().declare_token(key_expr)
        )

    def declare_config_queryable(self, getter: Callable[[], Any]) -> Declaration:
        """Answer queries on ``fusion/config`` with ``getter()`` (mapping or pydantic model).

        The reply is :func:`config_reply_payload`; an exception in ``getter`` becomes a Zenoh
        error reply with its message. With ``auth_key``, a query whose payload is a challenge
        nonce gets a reply tagged for it (see :meth:`verify_fusion`).
        """
        key_expr = self.key(Topic.CONFIG)
        encoding = zenoh.Encoding.APPLICATION_JSON.with_schema(SCHEMAS[Topic.CONFIG]["title"])
        auth = self._auth

        def on_query(query: zenoh.Query) -> None:
            try:
                data = encode(config_reply_payload(self.vehicle, getter()))
            except Exception as exc:
                query.reply_err(f"{type(exc).__name__}: {exc}")
                return
            tag = None
            if auth is not None and query.payload is not None:
                tag = auth.reply_tag(query.payload.to_bytes(), key_expr, data)
            query.reply(key_expr, data, encoding=encoding, attachment=tag)

        return self._declare(
            "queryable", key_expr, lambda s: s.declare_queryable(key_expr, on_query)
        )

    def query_config(self, *, vehicle: str | None = None, timeout_s: float = 2.0) -> dict | None:
        """Ask ``fusion/config`` of ``vehicle``; the decoded reply, or None (no answer).

        With ``auth_key`` only a reply tagged for this query's fresh nonce counts (a forged
        answer from a client without the key is ignored).
        """
        session = self._session
        if session is None:
            return None
        key_expr = key(vehicle or self.vehicle, Topic.CONFIG)
        nonce = PayloadAuth.nonce() if self._auth is not None else None
        for reply in session.get(key_expr, payload=nonce, timeout=timeout_s):
            if reply.ok is None:
                continue
            raw = reply.ok.payload.to_bytes()
            if self._auth is not None and nonce is not None:
                att = reply.ok.attachment
                if not self._auth.verify_reply(nonce, str(reply.ok.key_expr), raw,
                                               None if att is None else att.to_bytes()):
                    with self._lock:
                        self._c["unauthenticated"] += 1
                        self.last_rejected = f"untagged reply on {key_expr}"
                    continue
            decoded = json.loads(raw)
            if isinstance(decoded, dict):
                return decoded
        return None

    def verify_fusion(self, *, vehicle: str | None = None, timeout_s: float = 2.0) -> bool:
        """Whether a holder of the shared key answers ``fusion/config`` of ``vehicle`` now.

        A liveliness token carries no payload and anyone admitted by the router can declare
        one; a challenge (fresh nonce, tagged reply) proves the fusion itself is there.
        Raises ``RuntimeError`` without ``auth_key``.
        """
        if self._auth is None:
            raise RuntimeError("verify_fusion needs the shared key (auth_key)")
        return self.query_config(vehicle=vehicle, timeout_s=timeout_s) is not None

    def fusion_alive(self, *, vehicle: str | None = None, timeout_s: float = 1.0) -> bool:
        """Whether a ``fusion/alive`` token of ``vehicle`` exists now."""
        session = self._session
        if session is None:
            return False
        replies = session.liveliness().get(
            key(vehicle or self.vehicle, Topic.ALIVE), timeout=timeout_s
        )
        return any(r.ok is not None for r in replies)

    # --------------------------------------------------------------- worker thread
    def _zenoh_config(self) -> zenoh.Config:
        timeout_ms = int(self.config.connect_timeout_s * 1000)
        cfg: dict[str, Any] = {
            "mode": self.mode,
            "connect": {
                "endpoints": self.connect,
                "timeout_ms": timeout_ms,
                # peer mode: connect in the background instead of failing the open
                "exit_on_failure": False,
                "retry": {"period_init_ms": 50, "period_max_ms": 1000, "period_increase_factor": 2},
            },
            # explicit endpoints only: no multicast discovery on the LAN, and no gossip (a
            # direct peer of the fusion must not learn the router from it and get each sample
            # twice, or reach hosts it was not pointed at)
            "scouting": {"multicast": {"enabled": False}, "gossip": {"enabled": False}},
            "adminspace": {"enabled": False},
        }
        transport = self.security.transport()
        if self.config.low_latency:
            # Zenoh refuses the low-latency transport with QoS priorities on
            transport["unicast"] = {"lowlatency": True, "qos": {"enabled": False}}
        if transport:
            cfg["transport"] = transport
        if self.mode == "peer":
            cfg["listen"] = {"endpoints": self.listen}
            cfg["scouting"]["delay"] = 50 if self.connect else 0
        return zenoh.Config.from_json5(json.dumps(cfg))

    def _try_open(self) -> None:
        try:
            session = zenoh.open(self._zenoh_config())
        except zenoh.ZError as exc:
            with self._lock:
                self._c["connect_attempts"] += 1
                self.last_error = str(exc)
            return
        with self._lock:
            self._session = session
            for d in self._declarations:
                try:
                    d._apply(session)
                except Exception as exc:  # a bad declaration must not stop the others
                    self.last_error = f"declaring {d.kind} {d.key_expr}: {exc}"
        self._check_connected()

    def _check_connected(self) -> bool:
        session = self._session
        if session is None or session.is_closed():
            return False
        try:
            info = session.info
            up = bool(info.routers_zid()) or (self.mode == "peer" and bool(info.peers_zid()))
        except zenoh.ZError:
            up = False
        if self.mode == "peer" and not self.connect:
            up = True  # standalone: nothing to connect to
        with self._lock:
            if up and not self._connected and self._ever_connected:
                self._c["reconnects"] += 1
            self._ever_connected |= up
            self._connected = up
        return up

    def _publisher(self, session: zenoh.Session, topic: Topic, key_expr: str) -> zenoh.Publisher:
        pub = self._publishers.get(key_expr)
        if pub is None:
            with self._lock:
                pub = self._publishers.get(key_expr)
                if pub is None:
                    pub = session.declare_publisher(
                        key_expr,
                        encoding=zenoh.Encoding.APPLICATION_JSON.with_schema(
                            SCHEMAS[topic]["title"]
                        ),
                        # a slow link must never stall the publisher thread (and so the queue)
                        congestion_control=zenoh.CongestionControl.DROP,
                    )
                    self._publishers[key_expr] = pub
        return pub

    def has_subscribers(self, topic: Topic) -> bool:
        """Whether a subscriber somewhere currently matches ``topic`` of this vehicle.

        False while the session is not open. Zenoh does not send samples nobody subscribes
        to, so a process that must not lose the first messages waits for this.
        """
        session = self._session
        if session is None or self._closed or topic not in PUBLISHED_TOPICS:
            return False
        try:
            status: Any = self._publisher(session, topic, self._keys[topic]).matching_status
        except zenoh.ZError:
            return False
        # the stub says bool, the runtime returns a MatchingStatus with `.matching`
        return bool(getattr(status, "matching", status))

    def _send(self, session: zenoh.Session, batch: Sequence[tuple[Topic, str, bytes]]) -> None:
        sent = errors = 0
        for topic, key_expr, data in batch:
            try:
                tag = None if self._auth is None else self._auth.tag(key_expr, data)
                self._publisher(session, topic, key_expr).put(data, attachment=tag)
                sent += 1
            except zenoh.ZError as exc:
                errors += 1
                self.last_error = str(exc)
        with self._lock:
            self._c["published"] += sent
            self._c["put_errors"] += errors
            if not self._connected:
                self._c["unrouted"] += sent

    def _run(self) -> None:
        check_every_s = 0.25
        next_check = 0.0
        while True:
            if self._session is None:
                with self._lock:
                    if self._stopping:
                        break
                self._try_open()
                self._first_attempt.set()
                if self._session is None:
                    with self._cond:
                        self._cond.wait_for(lambda: self._stopping, timeout=self.config.retry_s)
                    continue
            with self._cond:
                self._cond.wait_for(lambda: self._queue or self._stopping, timeout=check_every_s)
                batch, self._queue = self._queue, deque()
                stopping = self._stopping
            now = time.monotonic()
            if now >= next_check:
                self._check_connected()
                next_check = now + check_every_s
            if batch:
                try:
                    self._send(self._session, batch)
                except Exception as exc:  # keep the thread alive: it is the only drain
                    with self._lock:
                        self._c["put_errors"] += len(batch)
                        self.last_error = f"{type(exc).__name__}: {exc}"
            if stopping:
                break
        self._first_attempt.set()
