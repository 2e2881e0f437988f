"""The simulator side of an autopilot in the loop: one loop, any protocol backend.

A backend speaks one autopilot's simulator protocol (PX4's simulator MAVLink interface,
ArduPilot's SITL JSON interface) and turns what the autopilot commands into a control vector
in PX4's HIL_ACTUATOR_CONTROLS order and signs (its actuator / servo map does that), which is
what :meth:`sim.flight.Flight.command` takes. :func:`fly_with_autopilot` runs the
:class:`hil.pipeline.SimChain` of a setup with ``FlightConfig.control = "external"``:

1. ``backend.wait_connected``: until the autopilot is there (PX4: connected and sending
   heartbeats; ArduPilot: its first servo packet has arrived).
2. every step: ``backend.controls(timeout)`` -> ``flight.command`` -> one simulator step ->
   every frame of the step to ``on_frame`` (the same HIL_SENSOR / HIL_GPS / truth frames a
   lockstep recording has: hilnav's own fusion and the ``.tlog`` take them) ->
   ``backend.send(step)`` (what this autopilot is sent: MAVLink frames for PX4, a JSON state
   line for ArduPilot).

Lockstep (``speed=None``, SITL): the simulator never runs ahead of the autopilot; a step waits
for the autopilot's next controls, and ``stall_timeout_s`` wall seconds without them end the
run as stalled (:attr:`AutopilotFlown.stalled` names the simulated time). Paced (``speed``
given, HITL over serial): simulated time runs at ``speed`` x the wall clock; the newest
controls are flown, and the run ends as stalled after ``stall_timeout_s`` without any.
"""

from __future__ import annotations

import dataclasses
import math
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Protocol

from hil.pipeline import FrameSink, ProgressFn, SimChain, SimSetup, SimStep
from sim.faults import FaultLogEntry
from sim.flight import FlightEnded

__all__ = ["AutopilotBackend", "AutopilotFlown", "DenialStep", "fly_with_autopilot"]


class AutopilotBackend(Protocol):
    """One autopilot's simulator protocol (see the module docstring)."""

    name: str
    """Who is flying, for reports: ``"PX4"``, ``"ArduPilot"``."""

    def wait_connected(self, timeout_s: float, stop: threading.Event) -> bool:
        """Block until the autopilot is connected (False: not within ``timeout_s`` wall s)."""
        ...

    def controls(self, timeout_s: float) -> Sequence[float] | None:
        """The autopilot's next control vector (PX4 order and signs, at most 16 values), or
        None when none arrived within ``timeout_s`` wall seconds."""
        ...

    def send(self, step: SimStep) -> None:
        """Send the autopilot what it sees after ``step``."""
        ...

    def counters(self) -> dict[str, int]:
        """Protocol counters for the scorecard (packets, bad packets, reconnects...)."""
        ...


@dataclass(frozen=True)
class DenialStep:
    """One step of a denial the autopilot simulates itself (a parameter it was asked to set at
    ``time_s`` of simulated time) and what became of it: ``status`` is ``"acknowledged"``
    (its PARAM_VALUE said so), ``"rejected"`` (it answered another value),
    ``"unacknowledged"`` (sent, no answer in time), ``"not sent"`` (the link did not take it
    in time) or ``"not due"`` (the flight ended before ``time_s``)."""

    time_s: float
    name: str
    value: float
    status: str

    @property
    def took(self) -> bool:
        """The autopilot applied this step."""
        return self.status == "acknowledged"


@dataclass(frozen=True)
class AutopilotFlown:
    """What a flight with an autopilot in the loop produced besides its frames.

    ``stalled``: the autopilot stopped sending controls (a sentence with the simulated time),
    else None. ``ended``: a stall / ground contact of the aircraft (the flight's own end).
    ``clipped_controls``: control values out of range (clipped) or not finite (ignored).
    ``trim_released_s``: simulated time the autopilot first reported itself armed, ending the
    trim hold (:mod:`hil.autopilot.arming`); None when it never did or its backend cannot see
    it. ``problems``: sentences on what the backend could not do for the scenario (a GNSS
    denial the autopilot did not acknowledge, naming the parameter and the link); a run with
    problems has failed.
    """

    autopilot: str
    connected: bool
    sim_duration_s: float
    wall_s: float
    steps: int
    frames: int
    ended: FlightEnded | None
    stalled: str | None
    stopped: bool
    clipped_controls: int
    counters: dict[str, int] = field(default_factory=dict)
    fault_log: list[FaultLogEntry] = field(default_factory=list)
    """The fault injector's event starts and ends (as :attr:`hil.pipeline.Flown.fault_log`)."""
    fault_counters: dict[str, int] = field(default_factory=dict)
    trim_released_s: float | None = None
    problems: tuple[str, ...] = ()
    denial: tuple[DenialStep, ...] | None = None
    """Each step of the scenario's denial the autopilot simulates itself (ArduPilot's SIM_*
    parameters) and whether it took it; None when the denial is in the sensor stream it is
    sent (PX4), which always reaches it."""

    @property
    def realtime_factor(self) -> float:
        """Simulated seconds per wall second."""
        return self.sim_duration_s / self.wall_s if self.wall_s > 0 else math.inf


def fly_with_autopilot(
    setup: SimSetup,
    backend: AutopilotBackend,
    *,
    on_frame: FrameSink | None = None,
    speed: float | None = None,
    connect_timeout_s: float = 60.0,
    stall_timeout_s: float = 10.0,
    progress: ProgressFn | None = None,
    on_step: Callable[[SimStep], None] | None = None,
    stop: threading.Event | None = None,
) -> AutopilotFlown:
    """Fly ``setup`` with the autopilot behind ``backend`` at the controls.

    ``setup.flight.control`` is set to ``"external"`` here. ``speed`` None: lockstep;
    else simulated seconds per wall second (HITL: 1). ``on_step`` sees every step after it is
    sent (scenario events, Zenoh publishing). ValueError for a bad speed or timeout.
    """
    if speed is not None and not (math.isfinite(speed) and speed > 0):
        raise ValueError(f"speed must be a finite number > 0, got {speed}")
    for name, value in (("connect timeout", connect_timeout_s), ("stall timeout", stall_timeout_s)):
        if not (math.isfinite(value) and value > 0):
            raise ValueError(f"{name} must be > 0 s, got {value}")
    stop = stop or threading.Event()
    flight_config = setup.flight.model_copy(update={"control": "external"})
    setup = dataclasses.replace(setup, flight=flight_config)
    frames = steps = clipped = 0
    stalled: str | None = None
    wall0 = time.monotonic()
    with SimChain(setup) as chain:
        assert chain.flight is not None
        flight = chain.flight
        connected = backend.wait_connected(connect_timeout_s, stop)
        if not connected:
            return AutopilotFlown(backend.name, False, 0.0, time.monotonic() - wall0, 0, 0, None,
                                  None, stop.is_set(), 0, backend.counters(),
                                  problems=_problems(backend), denial=_denial(backend))
        wall0 = time.monotonic()
        t0_us = chain.start_us
        next_progress_us = t0_us
        last_controls_wall = wall0
        chain_steps = chain.steps()
        while not stop.is_set():
            if speed is None:
                controls = backend.controls(stall_timeout_s)
                if controls is None:
                    stalled = _stall_sentence(backend.name, stall_timeout_s, chain.time_us - t0_us)
                    break
                clipped += flight.command(controls)
            else:
                controls = backend.controls(0.0)
                now = time.monotonic()
                if controls is not None:
                    clipped += flight.command(controls)
                    last_controls_wall = now
                elif now - last_controls_wall > stall_timeout_s:
                    stalled = _stall_sentence(backend.name, stall_timeout_s, chain.time_us - t0_us)
                    break
            step = next(chain_steps, None)
            if step is None:
                break
            steps += 1
            if on_frame is not None:
                for time_us, frame in step.frames:
                    on_frame(time_us, frame)
            frames += len(step.frames)
            backend.send(step)
            if on_step is not None:
                on_step(step)
            if speed is not None:
                due = wall0 + (step.truth.time_us - t0_us) * 1e-6 / speed
                ahead = due - time.monotonic()
                if ahead > 0:
                    stop.wait(ahead)
            if progress is not None and step.truth.time_us >= next_progress_us:
                progress((step.truth.time_us - t0_us) * 1e-6)
                next_progress_us += 1_000_000
        return AutopilotFlown(
            backend.name, True, chain.sim_duration_s, time.monotonic() - wall0, steps, frames,
            chain.ended, stalled, stop.is_set(), clipped, backend.counters(),
            list(chain.fault_log), chain.fault_counters,
            trim_released_s=getattr(backend, "trim_released_s", None),
            problems=_problems(backend), denial=_denial(backend),
        )
    raise AssertionError("unreachable")  # pragma: no cover


def _problems(backend: AutopilotBackend) -> tuple[str, ...]:
    """The backend's ``problems()`` (optional in the protocol: a backend without one has
    none), asked once the flight is over."""
    problems = getattr(backend, "problems", None)
    return tuple(problems()) if callable(problems) else ()


def _denial(backend: AutopilotBackend) -> tuple[DenialStep, ...] | None:
    """The backend's ``denial()`` (optional: None, the denial is in the sensor stream)."""
    denial = getattr(backend, "denial", None)
    steps = denial() if callable(denial) else None
    return None if steps is None else tuple(steps)


def _stall_sentence(name: str, timeout_s: float, elapsed_us: int) -> str:
    return (f"{name} sent no controls for {timeout_s:g} s (simulated time "
            f"{elapsed_us * 1e-6:.2f} s): the simulator held and ended the run")
