"""``hilnav sim ardupilot URL``: ArduPilot SITL flies the aircraft through the JSON physics
interface (part of the composition root; :class:`hil.autopilot.ardupilot.ArduPilotBackend` in
:func:`hil.autopilot.fly_with_autopilot`)."""

from __future__ import annotations

import contextlib
import math
from collections.abc import Callable
from pathlib import Path

from hil.autopilot import AutopilotFlown, fly_with_autopilot
from hil.autopilot.ardupilot import ArduPilotBackend
from hil.autopilot.servos import ServoMap
from hil.live_sim import stop_on_signals
from hil.pipeline import FrameSink, ProgressFn, SimSetup
from hil.tlog import TlogWriter
from scenarios.cli.autopilot_hints import ardupilot_command

__all__ = ["flown_sentence", "fly_ardupilot"]


def fly_ardupilot(
    setup: SimSetup,
    url: str,
    *,
    servo_map_path: Path | None = None,
    mavlink_url: str | None = None,
    record: Path | None = None,
    connect_timeout_s: float = 60.0,
    stall_timeout_s: float = 10.0,
    progress: ProgressFn | None = None,
    on_waiting: Callable[[str], None] | None = None,
    warn: Callable[[str], None] | None = None,
) -> AutopilotFlown:
    """Serve ArduPilot's JSON physics interface at ``url`` and fly ``setup`` in lockstep with
    it; every frame into ``record`` (a ``.tlog``) when given. ValueError: bad input (URL,
    servo map file, timeouts)."""
    for name, value in (("connect timeout", connect_timeout_s), ("stall timeout", stall_timeout_s)):
        if not (math.isfinite(value) and value > 0):  # before anything is opened
            raise ValueError(f"{name} must be > 0 s, got {value}")
    servo_map = ServoMap.load(servo_map_path) if servo_map_path is not None else None
    with contextlib.ExitStack() as stack:
        backend = stack.enter_context(ArduPilotBackend(
            url, servo_map=servo_map, setup=setup, mavlink_url=mavlink_url, warn=warn))
        sink: FrameSink | None = None
        if record is not None:
            record.parent.mkdir(parents=True, exist_ok=True)
            log = stack.enter_context(TlogWriter(record))
            sink = lambda t_us, frame: log.write(frame, t_us)  # noqa: E731
        if on_waiting is not None:
            host, port = backend.local_address
            on_waiting(f"sim: waiting for ArduPilot SITL servo packets on udp {host}:{port}; "
                       "start "
                       + ardupilot_command(setup.flight.start,
                                           "<this host>" if host not in ("127.0.0.1", "::1")
                                           else "127.0.0.1"))
        stop = stack.enter_context(stop_on_signals())
        return fly_with_autopilot(setup, backend, on_frame=sink,
                                  connect_timeout_s=connect_timeout_s,
                                  stall_timeout_s=stall_timeout_s, progress=progress, stop=stop)
    raise AssertionError("unreachable")  # pragma: no cover


def flown_sentence(flown: AutopilotFlown, record: Path | None) -> str:
    """One line on what the flight with ArduPilot did."""
    c = flown.counters
    bad = {k: c[k] for k in ("bad_magic", "bad_size", "wrong_protocol", "pwm_clipped",
                             "pwm_undriven", "repeated_frames", "restarts") if c.get(k)}
    params = (f"; SIM_* parameters sent {c['params_sent']}, acknowledged {c['params_acked']}"
              if "params_sent" in c else "")
    return (f"flew {flown.sim_duration_s:.1f} s simulated with {flown.autopilot} in "
            f"{flown.wall_s:.1f} s ({flown.realtime_factor:.2f}x real time), {flown.steps} "
            f"steps, {flown.frames} frames" + params
            + (f"; {', '.join(f'{k} {v}' for k, v in bad.items())}" if bad else "")
            + (f" -> {record}" if record is not None else ""))
