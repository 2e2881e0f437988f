"""The timeline check: every event inside the flight, no two overlapping events that
contradict each other.

Rules (windows are ``[start_s, start_s + duration_s)``, ``duration_s = None`` reaching the end
of the flight; windows that only touch do not overlap):

1. Every event starts before the end of the flight and ends no later than it.
2. At most one GNSS *position* fault at a time: outage, jamming, degradation, spoof drift and
   spoof hijack all decide what position the receiver reports (two spoofs included).
3. At most one ``gnss_delay`` and one ``gnss_rate`` at a time (either may overlap a position
   fault).
4. At most one barometer *sensor* fault (drift, glitch, freeze) at a time: each decides the
   sensor's error; at most one weather front at a time (it is ambient and may overlap a sensor
   fault).
5. An IMU axis (sensor and axis) that is stuck may not at the same time be stuck by another
   event or bias-stepped; two saturations of the same sensor may not overlap on a common axis
   (``axis=None`` covers all). Bias steps add up, magnetic anomalies add up.
6. At most one pitot event (blockage, drift, airspeed failure) at a time: each decides the
   airspeed sensor's output.

:func:`timeline_problems` returns the broken rules as records (for callers that word them
their own way); :func:`check_events` raises them as one ``ValueError``.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Literal

from sim.faults.events import (
    BARO_SENSOR_EVENTS,
    GNSS_POSITION_EVENTS,
    PITOT_EVENTS,
    FaultEvent,
    GnssDelay,
    GnssRate,
    ImuBiasStep,
    ImuSaturation,
    ImuStuck,
    WeatherFront,
    event_type_name,
)

__all__ = ["Conflict", "OutsideFlight", "check_events", "timeline_problems"]

Label = Callable[[int], str]
"""How a message names the event at a position of the timeline."""


@dataclass(frozen=True, slots=True)
class OutsideFlight:
    """An event that starts at or after the end of the flight, or ends after it.

    Attributes
    ----------
    index : int
        The event's position in the timeline.
    field : "start_s" or "duration_s"
        The field that puts it outside (a late start, or a window running past the end).
    time_s : float
        The event's start (``field == "start_s"``) or end, s of flight time.
    flight_s : float
        The flight's duration, s.
    """

    index: int
    field: Literal["start_s", "duration_s"]
    time_s: float
    flight_s: float

    def describe(self, label: Label) -> str:
        """The problem in one sentence, the event named by ``label(index)``."""
        if self.field == "start_s":
            return (
                f"{label(self.index)} starts at {self.time_s:g} s, at or after the end of the "
                f"flight ({self.flight_s:g} s)"
            )
        return (
            f"{label(self.index)} ends at {self.time_s:g} s, after the end of the flight "
            f"({self.flight_s:g} s); shorten duration_s or leave it empty for 'until the end'"
        )


@dataclass(frozen=True, slots=True)
class Conflict:
    """Two overlapping events that contradict each other.

    Attributes
    ----------
    first, second : int
        Positions of the two events in the timeline, ``first < second``.
    from_s, to_s : float
        The overlap, s of flight time.
    reason : str
        The rule they break.
    """

    first: int
    second: int
    from_s: float
    to_s: float
    reason: str

    def describe(self, label: Label) -> str:
        """The problem in one sentence, the events named by ``label(index)``."""
        return (
            f"{label(self.first)} and {label(self.second)} overlap from {self.from_s:g} s to "
            f"{self.to_s:g} s: {self.reason}"
        )


def _conflict(a: FaultEvent, b: FaultEvent) -> str | None:
    """Why two overlapping events contradict each other, or None."""
    if isinstance(a, GNSS_POSITION_EVENTS) and isinstance(b, GNSS_POSITION_EVENTS):
        return (
            "at most one GNSS position fault (outage, jamming, degradation, spoof drift, "
            "spoof hijack) may be active at a time"
        )
    for solo in (GnssDelay, GnssRate, WeatherFront):
        if isinstance(a, solo) and isinstance(b, solo):
            return f"two {solo.type_name} events may not overlap"
    if isinstance(a, BARO_SENSOR_EVENTS) and isinstance(b, BARO_SENSOR_EVENTS):
        return (
            "at most one barometer sensor fault (drift, glitch, freeze) may be active at a "
            "time (a weather front may overlap any of them)"
        )
    if isinstance(a, PITOT_EVENTS) and isinstance(b, PITOT_EVENTS):
        return (
            "at most one pitot fault (blockage, drift, airspeed failure) may be active at a "
            "time"
        )
    if isinstance(a, ImuBiasStep | ImuStuck) and isinstance(b, ImuBiasStep | ImuStuck):
        if (
            (isinstance(a, ImuStuck) or isinstance(b, ImuStuck))
            and a.sensor == b.sensor
            and a.axis == b.axis
        ):
            return f"{a.sensor} axis {a.axis} cannot be stuck and biased or stuck twice at once"
    if isinstance(a, ImuSaturation) and isinstance(b, ImuSaturation) and a.sensor == b.sensor:
        if a.axis is None or b.axis is None or a.axis == b.axis:
            return f"two saturation limits on the same {a.sensor} axis may not overlap"
    return None


def timeline_problems(
    events: Sequence[FaultEvent], duration_s: float
) -> list[OutsideFlight | Conflict]:
    """Every broken rule of a timeline (see the module docstring).

    Parameters
    ----------
    events : sequence of FaultEvent
    duration_s : float
        Flight duration, s (> 0).

    Returns
    -------
    list of OutsideFlight | Conflict
        Events outside the flight in timeline order (at most one record per event), then
        the contradicting pairs ordered by their first, then their second event.

    Raises
    ------
    ValueError
        ``duration_s`` is not a finite number > 0, or an item is not a fault event.
    """
    if isinstance(duration_s, bool) or not (
        isinstance(duration_s, int | float) and math.isfinite(duration_s) and duration_s > 0
    ):
        raise ValueError(f"duration_s must be a finite number > 0 (got {duration_s!r})")
    for ev in events:
        event_type_name(ev)
    problems: list[OutsideFlight | Conflict] = []
    windows: list[tuple[float, float]] = []
    for i, ev in enumerate(events):
        end = ev.end_s
        if ev.start_s >= duration_s:
            problems.append(OutsideFlight(i, "start_s", ev.start_s, duration_s))
        elif end is not None and end > duration_s * (1.0 + 1e-12):
            problems.append(OutsideFlight(i, "duration_s", end, duration_s))
        windows.append((ev.start_s, duration_s if end is None else end))
    for i in range(len(events)):
        for j in range(i + 1, len(events)):
            (s1, e1), (s2, e2) = windows[i], windows[j]
            if not (s1 < e2 and s2 < e1):
                continue
            reason = _conflict(events[i], events[j])
            if reason is not None:
                problems.append(Conflict(i, j, max(s1, s2), min(e1, e2), reason))
    return problems


def check_events(events: Sequence[FaultEvent], duration_s: float) -> None:
    """Check a scenario's timeline against the flight's length and for contradictions.

    Parameters
    ----------
    events : sequence of FaultEvent
    duration_s : float
        Flight duration, s (> 0).

    Raises
    ------
    ValueError
        Listing every broken rule (see the module docstring) in one message, each naming the
        events by their position in ``events`` and type name.
    """
    problems = timeline_problems(events, duration_s)
    if problems:
        names = [event_type_name(ev) for ev in events]

        def label(i: int) -> str:
            return f"event {i} ({names[i]})"

        raise ValueError("fault timeline: " + "; ".join(p.describe(label) for p in problems))
