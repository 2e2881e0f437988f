"""The child processes of the live-latency bench, each started as ``live_latency.py --role R``.

The simulator with send stamps, the socket-hop probes, the light recording sender, the fusion
with stage stamps and the estimate subscribers. Every stamp is ``time.monotonic_ns()``: all
processes run on one machine and read the same clock.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from typing import Any

import numpy as np
from _live_common import HIL_SENSOR_ID, START_TIMEOUT_S


def sender_main(args: argparse.Namespace) -> int:
    """Child: ``live_sim`` (as ``hilnav sim --live``) stamping HIL_SENSOR send times."""
    from hil.live_sim import live_sim, stop_on_signals
    from hil.pipeline import SimSetup

    stamps: list[tuple[int, int]] = []

    def on_send(time_us: int, frame: bytes) -> None:
        if frame[7] == HIL_SENSOR_ID and frame[8] == 0 and frame[9] == 0:
            stamps.append((time_us, time.monotonic_ns()))

    request = SimSetup.build(plan="racetrack", duration_s=args.duration, seed=args.seed)
    with stop_on_signals() as stop:
        report = live_sim(request, args.url, speed=args.speed, zenoh=args.zenoh,
                          vehicle=args.vehicle, wait_peer_s=60.0, on_send=on_send, stop=stop)
    Path(args.stamps).write_text(json.dumps({
        "stamps": stamps, "frames": report.frames, "sent": report.sent,
        "wall_s": report.wall_s, "realtime_factor": report.realtime_factor,
    }))
    return 0


def udp_hop_main(args: argparse.Namespace) -> int:
    """Child: HIL_SENSOR frames at 200 Hz whose ``time_usec`` is their monotonic send time."""
    from hil.codec import Encoder
    from hil.link import LinkRole, MavlinkLink
    from sim.samples import ImuSample

    enc = Encoder()
    with MavlinkLink(args.url, LinkRole.simulator()) as link:
        deadline = time.monotonic() + 60.0
        while not link.peer_alive and time.monotonic() < deadline:
            link.recv(0.05)
        t_next = time.monotonic()
        for _ in range(args.count):
            t_next += 0.005
            while (ahead := t_next - time.monotonic()) > 0:
                link.recv(ahead)
            imu = ImuSample(time.monotonic_ns() // 1000, 0.005, np.array([0.0, 0.0, -9.8]),
                            np.zeros(3))
            link.send(enc.sensors(imu))
    return 0


def replay_main(args: argparse.Namespace) -> int:
    """Child: send a recording's frames at ``speed`` x their time stamps (no JSBSim)."""
    from hil.link import LinkRole, MavlinkLink
    from hil.tlog import read_tlog

    frames = list(read_tlog(args.tlog))
    with MavlinkLink(args.url, LinkRole.simulator()) as link:
        deadline = time.monotonic() + 60.0
        while not link.peer_alive and time.monotonic() < deadline:
            link.recv(0.05)
        t0 = frames[0][0]
        wall0 = time.monotonic()
        sent = 0
        for t, frame in frames:
            ahead = wall0 + (t - t0) * 1e-6 / args.speed - time.monotonic()
            if ahead > 0.002:
                link.recv(ahead)
            sent += link.send(frame)
        wall = time.monotonic() - wall0
    print(json.dumps({"frames": len(frames), "sent": sent, "wall_s": wall,
                      "achieved_realtime_factor": (frames[-1][0] - t0) * 1e-6 / wall}))
    return 0


def raw_udp_main(args: argparse.Namespace) -> int:
    """Child: plain UDP datagrams carrying their monotonic send time, 200 Hz."""
    import socket

    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        time.sleep(0.5)
        for _ in range(args.count):
            sock.sendto(str(time.monotonic_ns()).encode(), ("127.0.0.1", int(args.url)))
            time.sleep(0.005)
        sock.sendto(b"end", ("127.0.0.1", int(args.url)))
    return 0


def zenoh_client_config(endpoint: str) -> Any:
    import zenoh

    return zenoh.Config.from_json5(json.dumps({
        "mode": "client", "connect": {"endpoints": [endpoint]},
        "scouting": {"multicast": {"enabled": False}}}))


def raw_zenoh_main(args: argparse.Namespace) -> int:
    """Child: plain zenoh-python puts carrying their monotonic send time, 25 Hz."""
    import zenoh

    session = zenoh.open(zenoh_client_config(args.zenoh))
    try:
        pub = session.declare_publisher("bench/raw")
        time.sleep(1.0)
        for _ in range(args.count):
            pub.put(str(time.monotonic_ns()))
            time.sleep(0.04)
        time.sleep(0.3)
    finally:
        session.close()
    return 0


def zenoh_hop_main(args: argparse.Namespace) -> int:
    """Child: ``scenario/events`` samples at 25 Hz carrying their monotonic publish time."""
    from hil.bus import Bus, Topic

    listen = args.url if args.peer else None  # p2p: this process listens, the bench connects
    with Bus(None if args.peer else args.zenoh, vehicle=args.vehicle,
             mode="peer" if args.peer else "client", listen=listen) as bus:
        deadline = time.monotonic() + 60.0
        while not bus.has_subscribers(Topic.EVENTS) and time.monotonic() < deadline:
            time.sleep(0.05)
        for _ in range(args.count):
            bus.publish_event(time.monotonic_ns() // 1000, "note", "latency probe")
            time.sleep(0.04)
        time.sleep(0.5)
    return 0


def fusion_main(argv: list[str]) -> int:
    """Child: ``hilnav fusion ARGS`` with time stamps of the estimate path's stages.

    ``--trace FILE`` (first) names where the stamps go at exit; the rest are ``hilnav fusion``'s
    arguments. Stamped (``time.monotonic_ns()``, wrapped around the service's own methods, so
    the same stamps work on a base revision's code): a HIL_SENSOR message returned by the
    input link's ``recv`` (reader thread), the filter thread starting on it (``_handle``), an
    estimate accepted by ``Bus.publish_estimate`` (entry, payload built, JSON encoded,
    return), the publisher thread, or the caller's thread when the bus is idle,
    handing it to Zenoh (``Bus._send`` entry and return; in publication order). Cost: one
    clock read and a list append per stamp (< 1 us).
    """
    import hil
    from hil.bus import Bus, Topic
    from hil.link import MavlinkLink
    from hil.service import FusionService
    from scenarios.cli.app import app

    trace_path = Path(argv[1])
    clock = time.monotonic_ns
    rx: list[tuple[int, int]] = []  # (HIL_SENSOR time_usec, link.recv returned)
    start: list[tuple[int, int]] = []  # (HIL_SENSOR time_usec, filter thread starts on it)
    pub: list[tuple[int, int, int]] = []  # (estimate time_us, publish entry, return)
    put: list[tuple[int, int]] = []  # (publisher thread: _send entry, return) per estimate

    recv, handle = MavlinkLink.recv, FusionService._handle
    publish_estimate, send = Bus.publish_estimate, Bus._send

    def traced_recv(self: Any, timeout: float = 0.0) -> list[Any]:
        out = recv(self, timeout)
        now = clock()
        rx.extend((int(m.time_usec), now) for m in out if m.get_msgId() == HIL_SENSOR_ID)
        return out

    def traced_handle(self: Any, msg: Any) -> Any:
        if msg.get_msgId() == HIL_SENSOR_ID:
            start.append((int(msg.time_usec), clock()))
        return handle(self, msg)

    def traced_publish_estimate(self: Any, est: Any) -> bool:
        t0 = clock()
        ok = publish_estimate(self, est)
        if ok:
            pub.append((int(est.time_us), t0, clock()))
        return ok

    def traced_send(self: Any, session: Any, batch: Any, *args: Any) -> None:
        t0 = clock()
        send(self, session, batch, *args)
        t1 = clock()
        put.extend((t0, t1) for topic, _, _ in batch if topic is Topic.ESTIMATE)

    import hil.bus.session as session_module

    build_estimate, encode = session_module.estimate_payload, session_module.encode
    built: list[tuple[int, int]] = []  # (estimate payload built, JSON encoded) per estimate

    def traced_estimate_payload(est: Any) -> dict[str, Any]:
        payload = build_estimate(est)
        built.append((clock(), 0))
        return payload

    def traced_encode(payload: Any) -> bytes:
        data = encode(payload)
        if built and built[-1][1] == 0:
            built[-1] = (built[-1][0], clock())
        return data

    session_module.estimate_payload = traced_estimate_payload
    session_module.encode = traced_encode
    MavlinkLink.recv = traced_recv  # type: ignore[method-assign]
    FusionService._handle = traced_handle  # type: ignore[method-assign]
    Bus.publish_estimate = traced_publish_estimate  # type: ignore[method-assign]
    Bus._send = traced_send  # type: ignore[method-assign,assignment]
    code = 0
    try:
        app(argv[2:], prog_name="hilnav")
    except SystemExit as exc:
        code = int(exc.code or 0)
    finally:
        trace_path.write_text(json.dumps({"code_from": str(Path(hil.__file__).parent.parent),
                                          "rx": rx, "start": start, "pub": pub, "put": put,
                                          "built": built}))
    return code


def subscriber_main(args: argparse.Namespace) -> int:
    """Child: stamp each ``fusion/estimate`` arrival (routed client or direct peer) in the
    callback, after ``hil.bus`` decoded its JSON (as ``hilnav monitor`` gets it), and also when
    the sample reaches ``hil.bus``'s decode (``message_from_sample``; side file ``.raw``)."""
    import hil.bus.session as session_module
    from hil.bus import Bus, BusConfig, Message, Topic

    arrivals: list[tuple[int, int]] = []  # (estimate time_us, arrival ns)
    decoded: list[tuple[int, int]] = []  # (estimate time_us, ns when handed to JSON decode)
    decode = session_module.message_from_sample

    def traced_decode(key_expr: str, raw: bytes) -> Message:
        now = time.monotonic_ns()
        m = decode(key_expr, raw)
        if m.payload is not None and "time_us" in m.payload:
            decoded.append((int(m.payload["time_us"]), now))
        return m

    session_module.message_from_sample = traced_decode

    def on_estimate(m: Message) -> None:
        now = time.monotonic_ns()
        if m.payload is not None:
            arrivals.append((int(m.payload["time_us"]), now))

    with Bus(args.zenoh, vehicle=args.vehicle, mode="peer" if args.peer else "client",
             config=BusConfig(low_latency=args.low_latency)) as bus:
        bus.subscribe(Topic.ESTIMATE, on_estimate)
        if not bus.wait_connected(START_TIMEOUT_S):
            return 1
        Path(args.stamps + ".ready").write_text("ready")
        deadline = time.monotonic() + args.max_wall
        while time.monotonic() < deadline:
            time.sleep(0.2)
            if arrivals and time.monotonic_ns() - arrivals[-1][1] > 3e9:
                break  # the flight is over
    Path(args.stamps + ".raw").write_text(json.dumps(decoded))
    Path(args.stamps).write_text(json.dumps(arrivals))
    return 0
