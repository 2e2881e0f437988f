"""``hilnav sim --live``: the sensor streamer on a real MAVLink link, paced against the wall clock.

The same flight, sensor models and :class:`hil.streamer.SensorStreamer` as the lockstep recorder
(same seed, same frames, byte for byte), but every frame also goes out on a
:class:`hil.link.MavlinkLink` (role :meth:`LinkRole.simulator`). Pacing: after each simulator
step the process sleeps until ``wall - wall0 >= (t_sim - t0) / speed``; timestamps on the wire
are always simulated time. When the machine cannot keep up the run simply falls behind (no
frames are skipped); the achieved real-time factor is reported.

Lockstep pacing against the fusion service (``--lockstep``)
    UDP has no flow control: a fusion service that cannot keep up at ``--speed`` loses frames
    once its receive buffer overflows. With ``lockstep`` the simulator also waits for the
    receiver: it announces the request in its HEARTBEAT (``custom_mode`` =
    :data:`hil.link.LOCKSTEP_CUSTOM_MODE`; its autopilot is ``MAV_AUTOPILOT_INVALID``, so no
    ground station gives the value a meaning), the fusion service answers every processed
    batch with TIMESYNC (``ts1`` = simulated time in ns of the newest sample its filter has
    processed, see :mod:`hil.service`), and the simulator never runs more than
    ``lockstep_window_s`` of simulated time ahead of that acknowledgement. The run then goes
    as fast as the slower of ``speed`` and the fusion, and nothing is dropped for lack of
    buffer space, whatever the speed. At the end of the flight the simulator waits until the
    last frame is acknowledged, so when it exits the fusion has processed everything. No
    acknowledgement progress for ``lockstep_timeout_s`` wall seconds (fusion stopped, wrong
    URL) ends the run with ``LiveReport.stalled``.

Scenario events (:class:`hil.scenario_events.ScenarioTimeline`: GNSS windows, fault
boundaries) also go out as STATUSTEXT from the truth component, text ``SIM: <event>``, severity
NOTICE, when they happen; the fusion service relays them to its ground stations (its shadow
vehicle). They are the live stream's only frames a lockstep recording does not have.

Optionally the frames are recorded to a .tlog (``--record``) and truth, sensor samples and the
scenario events are published on Zenoh (``--zenoh``) through :class:`hil.bus.Bus` (never
blocks).
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

from hil.bus.security import BusAccess
from hil.codec import mavlink2
from hil.pipeline import SimChain, SimSetup
from hil.scenario_events import ScenarioTimeline
from sim.flight import FlightEnded
from sim.samples import ActuatorSample, RpmSample

__all__ = ["LiveReport", "live_sim"]

_MIN_SLEEP_S = 0.002  # sleeping less than this costs more than it paces
_EVENT_SEVERITY = int(mavlink2.MAV_SEVERITY_NOTICE)  # scenario events' STATUSTEXT


@dataclass(frozen=True)
class LiveReport:
    """Outcome of a live run.

    Attributes
    ----------
    sim_duration_s : simulated seconds flown.
    wall_s : wall-clock seconds from the first step to the last.
    frames : frames produced by the sensor streamer.
    sent : frames the link accepted (``frames - sent`` were dropped by the link, counted there).
    peer_seen : whether a heartbeat from the receiver arrived before the flight started.
    ended : a stall / ground contact that ended the flight early, else None.
    stopped : True when stopped by a signal before the end.
    lockstep_wait_s : wall seconds spent waiting for the fusion's acknowledgements.
    stalled : lockstep only: the acknowledgements stopped coming (the run was ended).
    """

    sim_duration_s: float
    wall_s: float
    frames: int
    sent: int
    peer_seen: bool
    ended: FlightEnded | None
    stopped: bool
    lockstep_wait_s: float = 0.0
    stalled: bool = False

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
    request: SimSetup,
    url: str,
    *,
    speed: float = 1.0,
    record: Path | None = None,
    zenoh: str | None = None,
    vehicle: str = "sim1",
    signing_key: bytes | None = None,
    bus_access: BusAccess | None = None,
    wait_peer_s: float = 0.0,
    lockstep: bool = False,
    lockstep_window_s: float = 0.25,
    lockstep_timeout_s: float = 10.0,
    progress: Callable[[float], None] | None = None,
    on_send: Callable[[int, bytes], None] | None = None,
    stop: threading.Event | None = None,
) -> LiveReport:
    """Fly ``request`` and send its frames to ``url`` at ``speed`` x real time.

    Parameters
    ----------
    request : SimSetup
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
    bus_access : BusAccess, optional
        Zenoh login / TLS and the shared payload key for ``zenoh``.
    wait_peer_s : float
        Before flying, wait up to this long (wall s) for a heartbeat from the receiver, so
        no sample is sent before it listens (0: start at once; with ``lockstep``, 0 means
        ``lockstep_timeout_s``).
    lockstep : bool
        Never run more than ``lockstep_window_s`` of simulated time ahead of the fusion
        service's acknowledgement (see the module docstring).
    lockstep_window_s : float
        Simulated seconds the simulator may be ahead of the acknowledged time (> 0).
    lockstep_timeout_s : float
        Wall seconds without acknowledgement progress after which the run ends as stalled.
    progress : callable, optional
        Called with simulated seconds flown, about once per simulated second.
    on_send : callable, optional
        ``on_send(time_us, frame)`` right before each frame is handed to the link (the
        instrumentation hook of ``bench/live_latency.py``); keep it cheap.
    stop : threading.Event, optional
        Set it to stop early (the run ends cleanly, the log is closed).

    Returns
    -------
    LiveReport
    """
    from hil.link import LOCKSTEP_CUSTOM_MODE, LinkRole, MavlinkLink
    from hil.signing import Signer
    from hil.tlog import TlogWriter

    if not (math.isfinite(speed) and speed > 0):
        raise ValueError(f"speed must be a finite number > 0, got {speed}")
    if not (math.isfinite(wait_peer_s) and wait_peer_s >= 0):
        raise ValueError(f"wait-peer must be >= 0 s, got {wait_peer_s}")
    if not (math.isfinite(lockstep_window_s) and lockstep_window_s > 0):
        raise ValueError(f"lockstep-window must be > 0 s, got {lockstep_window_s}")
    if not (math.isfinite(lockstep_timeout_s) and lockstep_timeout_s > 0):
        raise ValueError(f"lockstep-timeout must be > 0 s, got {lockstep_timeout_s}")
    stop = stop or threading.Event()
    signer = Signer(signing_key) if signing_key is not None else None
    chain = SimChain(request)
    with contextlib.ExitStack() as stack:
        link = stack.enter_context(MavlinkLink(url, LinkRole.simulator(), signer=signer))
        if lockstep:
            link.set_heartbeat_state(custom_mode=LOCKSTEP_CUSTOM_MODE)
        log = None
        if record is not None:
            record.parent.mkdir(parents=True, exist_ok=True)
            log = stack.enter_context(TlogWriter(record))
        bus = None
        if zenoh is not None:
            from hil.bus import Bus

            access = bus_access or BusAccess()
            bus = stack.enter_context(Bus(zenoh, vehicle=vehicle, security=access.security,
                                          auth_key=access.auth_key))
        stack.enter_context(chain)
        if lockstep and wait_peer_s == 0.0:
            wait_peer_s = lockstep_timeout_s
        peer_seen = _wait_for_peer(link, wait_peer_s, stop)
        gate = (
            _Lockstep(chain.start_us, lockstep_window_s, lockstep_timeout_s) if lockstep else None
        )
        return _fly(chain, speed, link, log, bus, progress, on_send, gate, stop, peer_seen)
    raise AssertionError("unreachable")  # pragma: no cover (ExitStack does not swallow)


def _wait_for_peer(link: Any, wait_s: float, stop: threading.Event) -> bool:
    deadline = time.monotonic() + wait_s
    while not link.peer_alive and time.monotonic() < deadline and not stop.is_set():
        link.recv(timeout=0.05)  # also sends our heartbeat, which makes a udpin peer learn us
    return bool(link.peer_alive)


class _Lockstep:
    """The simulator's side of lockstep pacing: the newest acknowledged simulated time."""

    def __init__(self, start_us: int, window_s: float, timeout_s: float) -> None:
        from hil.link import TIMESYNC_ID

        self._timesync_id = TIMESYNC_ID
        self.acked_us = start_us  # the first window may go out before any acknowledgement
        self.window_us = round(window_s * 1e6)
        self.timeout_s = timeout_s
        self.waited_s = 0.0

    def absorb(self, msgs: list[Any]) -> None:
        """Take the acknowledgements (TIMESYNC, ``ts1`` in ns) among received messages."""
        for m in msgs:
            if m.get_msgId() == self._timesync_id:
                self.acked_us = max(self.acked_us, int(m.ts1) // 1000)

    def wait(self, time_us: int, link: Any, stop: threading.Event, *, window_us: int | None = None
             ) -> bool:
        """Block until ``time_us`` is within the window (default ``self.window_us``) of the
        acknowledged time; False when the acknowledgements stopped (no progress for
        ``timeout_s``)."""
        window = self.window_us if window_us is None else window_us
        if time_us - self.acked_us <= window:
            return True
        t0 = time.monotonic()
        deadline = t0 + self.timeout_s
        try:
            while time_us - self.acked_us > window and not stop.is_set():
                now = time.monotonic()
                if now >= deadline:
                    return False
                before = self.acked_us
                self.absorb(link.recv(timeout=min(deadline - now, 0.05)))
                if self.acked_us > before:
                    deadline = time.monotonic() + self.timeout_s
            return True
        finally:
            self.waited_s += time.monotonic() - t0


def _fly(
    chain: SimChain,
    speed: float,
    link: Any,
    log: Any,
    bus: Any,
    progress: Callable[[float], None] | None,
    on_send: Callable[[int, bytes], None] | None,
    gate: _Lockstep | None,
    stop: threading.Event,
    peer_seen: bool,
) -> LiveReport:
    t0_us = last_us = chain.start_us
    timeline = ScenarioTimeline(chain.setup, t0_us)
    assert chain.streamer is not None  # the chain is open
    encoder = chain.streamer.encoder
    frames = sent = 0
    stalled = False
    next_progress_us = t0_us
    next_tick = 0.0
    wall0 = time.monotonic()
    for step in chain.steps():
        if stop.is_set():
            break
        truth, samples = step.truth, step.samples
        last_us = truth.time_us
        for time_us, frame in step.frames:
            frames += 1
            if on_send is not None:
                on_send(time_us, frame)
            sent += link.send(frame)
            if log is not None:
                log.write(frame, time_us)
        for event in timeline.due(truth.time_us, chain.fault_log):
            frame = encoder.statustext(_EVENT_SEVERITY, f"SIM: {event[2]}")
            frames += 1
            sent += link.send(frame)
            if log is not None:
                log.write(frame, truth.time_us)
            if bus is not None:
                bus.publish_event(*event)
        if bus is not None:
            bus.publish_truth(truth)
            for s in samples:
                if not isinstance(s, ActuatorSample | RpmSample):  # no Zenoh topic for these
                    bus.publish_sample(s)
        # pace: simulated time runs at `speed` x the wall clock. recv() returns early when a
        # message arrives (heartbeats, lockstep acknowledgements), so sleep in a loop.
        due = wall0 + (truth.time_us - t0_us) * 1e-6 / speed
        ahead = due - time.monotonic()
        if ahead > _MIN_SLEEP_S:
            while ahead > _MIN_SLEEP_S:
                msgs = link.recv(timeout=ahead)  # keeps heartbeats / peer tracking going
                if gate is not None:
                    gate.absorb(msgs)
                ahead = due - time.monotonic()
            next_tick = time.monotonic() + 0.1
        elif time.monotonic() >= next_tick:
            link.tick()
            next_tick = time.monotonic() + 0.1
        if gate is not None and not gate.wait(truth.time_us, link, stop):
            stalled = True
            break
        if progress is not None and truth.time_us >= next_progress_us:
            progress((truth.time_us - t0_us) * 1e-6)
            next_progress_us += 1_000_000
    if gate is not None and not stalled and not stop.is_set():
        # the end: return once the fusion has processed every frame sent
        stalled = not gate.wait(last_us, link, stop, window_us=0)
    wall = time.monotonic() - wall0
    ended: FlightEnded | None = chain.ended
    return LiveReport((last_us - t0_us) * 1e-6, wall, frames, sent, peer_seen, ended,
                      stop.is_set(), 0.0 if gate is None else gate.waited_s, stalled)
