"""``hilnav sim --live``: the sensor bridge on a real MAVLink link, paced against the wall clock.

The same flight, sensor models and :class:`hil.bridge.SensorBridge` as the lockstep recorder
(same seed, same frames, byte for byte), but every frame also goes out on a
:class:`hil.link.MavlinkLink` (role :meth:`LinkRole.simulator`). Pacing: after each simulator
step the process sleeps until ``wall - wall0 >= (t_sim - t0) / speed``; timestamps on the wire
are always simulated time. When the machine cannot keep up the run simply falls behind (no
frames are skipped); the achieved real-time factor is reported.

Optionally the frames are recorded to a .tlog (``--record``) and truth and sensor samples are
published on Zenoh (``--zenoh``) through :class:`hil.bus.Bus` (never blocks).
"""

from __future__ import annotations

import contextlib
import math
import signal
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from hil.bridge import SensorBridge
from hil.recording import SimRequest
from sim.flight import Flight, FlightEnded
from sim.samples import Truth
from sim.sensors import SensorSuite

__all__ = ["LiveReport", "live_sim"]

_MIN_SLEEP_S = 0.002  # sleeping less than this costs more than it paces


@dataclass(frozen=True)
class LiveReport:
    """Outcome of a live run.

    Attributes
    ----------
    sim_duration_s : simulated seconds flown.
    wall_s : wall-clock seconds from the first step to the last.
    frames : frames produced by the bridge.
    sent : frames the link accepted (``frames - sent`` were dropped by the link, counted there).
    peer_seen : whether a heartbeat from the receiver arrived before the flight started.
    ended : a stall / ground contact that ended the flight early, else None.
    stopped : True when stopped by a signal before the end.
    """

    sim_duration_s: float
    wall_s: float
    frames: int
    sent: int
    peer_seen: bool
    ended: FlightEnded | None
    stopped: bool

    @property
    def realtime_factor(self) -> float:
        """Simulated seconds per wall second."""
        return self.sim_duration_s / self.wall_s if self.wall_s > 0 else math.inf


@contextlib.contextmanager
def stop_on_signals() -> Iterator[threading.Event]:
    """An event set by SIGTERM / SIGINT (main thread only); previous handlers restored."""
    stop = threading.Event()
    if threading.current_thread() is not threading.main_thread():
        yield stop
        return

    def handler(_sig: int, _frame: Any) -> None:
        stop.set()

    previous = {s: signal.signal(s, handler) for s in (signal.SIGTERM, signal.SIGINT)}
    try:
        yield stop
    finally:
        for s, h in previous.items():
            signal.signal(s, h)


def live_sim(
    request: SimRequest,
    url: str,
    *,
    speed: float = 1.0,
    record: Path | None = None,
    zenoh: str | None = None,
    vehicle: str = "sim1",
    signing_key: bytes | None = None,
    wait_peer_s: float = 0.0,
    progress: Callable[[float], None] | None = None,
    stop: threading.Event | None = None,
) -> LiveReport:
    """Fly ``request`` and send its frames to ``url`` at ``speed`` x real time.

    Parameters
    ----------
    request : SimRequest
    url : str
        MAVLink link URL (:class:`hil.link.LinkUrl`), e.g. ``udpout:127.0.0.1:14560``.
    speed : float
        Simulated seconds per wall second (> 0; 1 for hardware).
    record : Path, optional
        Also write every frame to this .tlog (simulated-time stamps).
    zenoh : str, optional
        Router endpoint: publish truth and sensor samples under ``hilnav/<vehicle>/``.
    vehicle : str
        Zenoh vehicle key chunk.
    signing_key : bytes, optional
        32-byte MAVLink 2 signing key.
    wait_peer_s : float
        Before flying, wait up to this long (wall s) for a heartbeat from the receiver, so
        no sample is sent before it listens (0: start at once).
    progress : callable, optional
        Called with simulated seconds flown, about once per simulated second.
    stop : threading.Event, optional
        Set it to stop early (the run ends cleanly, the log is closed).

    Returns
    -------
    LiveReport
    """
    from hil.link import LinkRole, MavlinkLink
    from hil.signing import Signer
    from hil.tlog import TlogWriter

    if not (math.isfinite(speed) and speed > 0):
        raise ValueError(f"speed must be a finite number > 0, got {speed}")
    if not (math.isfinite(wait_peer_s) and wait_peer_s >= 0):
        raise ValueError(f"wait-peer must be >= 0 s, got {wait_peer_s}")
    stop = stop or threading.Event()
    signer = Signer(signing_key) if signing_key is not None else None
    suite = SensorSuite(request.sensors, request.seed, request.flight.rate_hz)
    bridge = SensorBridge(truth_rate_hz=request.truth_rate_hz, gnss_off=request.gnss_off)
    with contextlib.ExitStack() as stack:
        link = stack.enter_context(MavlinkLink(url, LinkRole.simulator(), signer=signer))
        log = None
        if record is not None:
            record.parent.mkdir(parents=True, exist_ok=True)
            log = stack.enter_context(TlogWriter(record))
        bus = None
        if zenoh is not None:
            from hil.bus import Bus

            bus = stack.enter_context(Bus(zenoh, vehicle=vehicle))
        flight = stack.enter_context(Flight(request.flight, request.plan))
        peer_seen = _wait_for_peer(link, wait_peer_s, stop)
        return _fly(flight, suite, bridge, request.duration_s, speed, link, log, bus,
                    progress, stop, peer_seen)
    raise AssertionError("unreachable")  # pragma: no cover (ExitStack does not swallow)


def _wait_for_peer(link: Any, wait_s: float, stop: threading.Event) -> bool:
    deadline = time.monotonic() + wait_s
    while not link.peer_alive and time.monotonic() < deadline and not stop.is_set():
        link.recv(timeout=0.05)  # also sends our heartbeat, which makes a udpin peer learn us
    return bool(link.peer_alive)


def _fly(
    flight: Flight,
    suite: SensorSuite,
    bridge: SensorBridge,
    duration_s: float,
    speed: float,
    link: Any,
    log: Any,
    bus: Any,
    progress: Callable[[float], None] | None,
    stop: threading.Event,
    peer_seen: bool,
) -> LiveReport:
    t0_us = flight.time_us
    end_us = t0_us + round(duration_s * 1e6)
    frames = sent = 0
    ended: FlightEnded | None = None
    next_progress_us = t0_us
    next_tick = 0.0
    wall0 = time.monotonic()
    truth: Truth = flight.truth()
    while truth.time_us < end_us and not stop.is_set():
        try:
            truth = flight.step()
        except FlightEnded as exc:
            ended = exc
            break
        samples = suite.step(truth)
        for time_us, frame in bridge.frames(truth, samples):
            frames += 1
            sent += link.send(frame)
            if log is not None:
                log.write(frame, time_us)
        if bus is not None:
            bus.publish_truth(truth)
            for s in samples:
                bus.publish_sample(s)
        # pace: simulated time runs at `speed` x the wall clock
        ahead = (truth.time_us - t0_us) * 1e-6 / speed - (time.monotonic() - wall0)
        if ahead > _MIN_SLEEP_S:
            link.recv(timeout=ahead)  # sleeps, and keeps heartbeats / peer tracking going
            next_tick = time.monotonic() + 0.1
        elif time.monotonic() >= next_tick:
            link.tick()
            next_tick = time.monotonic() + 0.1
        if progress is not None and truth.time_us >= next_progress_us:
            progress((truth.time_us - t0_us) * 1e-6)
            next_progress_us += 1_000_000
    wall = time.monotonic() - wall0
    return LiveReport((truth.time_us - t0_us) * 1e-6, wall, frames, sent, peer_seen, ended,
                      stop.is_set())
