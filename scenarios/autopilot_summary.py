"""The ``autopilot`` section of ``summary.json``: the autopilot's own estimate, scored beside
hilnav's through the same denial.

The autopilot's track (:meth:`hil.autopilot.telemetry.AutopilotTelemetry.estimate_track`) goes
through the one scorer, :func:`scenarios.summary.build_summary`, with the *same* truth, GNSS
outage windows (the gaps of the sensor stream both estimators saw), settling time and scenario
events as hilnav's estimate: per-outage horizontal / vertical errors, CEP, drift, re-convergence
and the GNSS-on accuracy including attitude are computed by the same code. No NEES: the
autopilot reports no covariance of its 9 navigation errors (PX4's ESTIMATOR_STATUS has 1-sigma
horizontal / vertical accuracies, ArduPilot's EKF_STATUS_REPORT "variances" are normalised
innovation test ratios): those are kept in ``health.estimator.max``, not turned into a
consistency figure. The run's pass criteria are hilnav's; the autopilot's figures are reported,
not judged.

Only what the autopilot was really denied is an outage of the autopilot: PX4 is denied through
the sensor stream it is sent (every window is), ArduPilot through SIM_* parameters over its
MAVLink port, so a GNSS window in which a step of its denial was not acknowledged (or that had
no step at all: no MAVLink port) is listed in ``outages_not_denied`` and scored as GNSS-on
time, never as an outage. The section also says from when the autopilot's estimate is scored
(``estimate_from_s``: its first valid position) and when its trim hold ended
(``trim_released_s``: it armed).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from hil.autopilot import AutopilotFlown
from hil.autopilot.backend import DenialStep
from hil.autopilot.telemetry import AutopilotTelemetry
from hil.tracks import Track
from scenarios.event_metrics import EventWindow
from scenarios.metrics import Errors, Window
from scenarios.summary import RunInfo, build_summary

__all__ = ["AUTOPILOT_METRIC_KEYS", "ScoredAutopilot", "autopilot_section", "score_flown",
           "split_denied"]

#: The keys of hilnav's summary that the autopilot section repeats for the autopilot.
AUTOPILOT_METRIC_KEYS = ("outages", "gnss_on", "events", "scoring")


@dataclass(frozen=True)
class ScoredAutopilot:
    """The section and what it was computed from (``errors`` None: nothing was scored)."""

    section: dict[str, Any]
    track: Track | None
    errors: Errors | None


def autopilot_section(
    source: str,
    track: Track | None,
    truth: Track,
    outages: list[Window],
    *,
    link: Mapping[str, Any],
    counters: Mapping[str, int],
    stalled: str | None,
    connected: bool,
    health: Mapping[str, Any] | None = None,
    settle_s: float = 60.0,
    events: Sequence[EventWindow | Mapping[str, Any]] = (),
    problem: str | None = None,
    extra: Mapping[str, Any] | None = None,
) -> ScoredAutopilot:
    """Score the autopilot's ``track`` against ``truth`` with hilnav's scorer.

    Parameters
    ----------
    source : ``"PX4"`` or ``"ArduPilot"`` (the backend's name).
    track : the autopilot's estimate on the simulated time axis; None when its telemetry held
        none (``problem`` says why).
    truth, outages, settle_s, events : exactly what hilnav's estimate was scored with.
    link : where the simulator met the autopilot and where its telemetry came from.
    counters : protocol and telemetry counters.
    stalled : the stall sentence of the run, None when the autopilot kept flying.
    connected : whether the autopilot ever connected.
    health : :meth:`~hil.autopilot.telemetry.AutopilotTelemetry.health`.
    extra : further keys of the section (:func:`score_flown`'s).

    Returns
    -------
    ScoredAutopilot
        ``section``: ``{source, link, connected, stalled, counters, health, nees: None,
        outages, gnss_on, events, scoring}`` (the metric keys None when nothing was scored,
        with ``problem``).
    """
    section: dict[str, Any] = {
        "source": source,
        "link": dict(link),
        "connected": connected,
        "stalled": stalled,
        "counters": dict(counters),
        "health": dict(health or {}),
        "nees": None,
        "problem": problem,
        **(extra or {}),
    }
    if track is None or track.time_s.size == 0:
        section.update(dict.fromkeys(AUTOPILOT_METRIC_KEYS))
        return ScoredAutopilot(section, None, None)
    info = RunInfo(scenario="", seed=None, sim_duration_s=0.0, wall_s=0.0, bridge="",
                   altitude="")
    summary, err = build_summary(info, track, truth, outages, settle_s=settle_s,
                                 events=events)
    section.update({k: summary[k] for k in AUTOPILOT_METRIC_KEYS})
    section["samples"] = int(err.time_s.size)
    return ScoredAutopilot(section, track, err)


def score_flown(
    flown: AutopilotFlown,
    telemetry: AutopilotTelemetry | None,
    truth: Track | None,
    outages: list[Window],
    *,
    link: Mapping[str, Any],
    settle_s: float,
    events: Sequence[EventWindow | Mapping[str, Any]] = (),
) -> ScoredAutopilot:
    """The section of a flight with an autopilot (:func:`hil.autopilot.fly_with_autopilot`)
    whose telemetry ``telemetry`` recorded (None: none was recorded): its counters (the
    backend's, ``clipped_controls``, ``steps``, ``telemetry_*``), health and estimate scored
    against ``truth`` (None: no truth, nothing scored) by :func:`autopilot_section`."""
    counters = {**flown.counters, "clipped_controls": flown.clipped_controls,
                "steps": flown.steps}
    denied, not_denied = split_denied(outages, flown.denial)
    extra: dict[str, Any] = {
        "trim_released_s": flown.trim_released_s,
        "estimate_from_s": None if telemetry is None else telemetry.estimate_from_s,
        "denial": None if flown.denial is None else [
            {"time_s": d.time_s, "name": d.name, "value": d.value, "status": d.status}
            for d in flown.denial],
        "outages_not_denied": [{"start_s": w.start_s, "end_s": w.end_s} for w in not_denied],
    }
    track: Track | None = None
    health: dict[str, Any] | None = None
    problem: str | None = None
    if telemetry is None:
        problem = "no telemetry link to record its estimate from"
    else:
        counters.update({f"telemetry_{k}": v for k, v in telemetry.counters().items()})
        health = telemetry.health()
        try:
            track = telemetry.estimate_track()
        except ValueError as exc:
            problem = str(exc)
        if telemetry.error is not None:
            problem = f"telemetry recorder stopped: {telemetry.error}"
    if truth is None:
        track, problem = None, problem or "the flight produced no truth to score against"
    z = np.zeros(0)
    return autopilot_section(
        flown.autopilot, track, truth if truth is not None else Track(z, z, z, z, z, z),
        denied, link=link, counters=counters, stalled=flown.stalled,
        connected=flown.connected, health=health, settle_s=settle_s, events=events,
        problem=problem, extra=extra)


#: Seconds around a GNSS window's start (the gap begins at the last fix before the denial) in
#: which the step that denies it is due.
_STEP_LEAD_S = 1.0


def split_denied(outages: list[Window], denial: Sequence[DenialStep] | None,
                 ) -> tuple[list[Window], list[Window]]:
    """The GNSS outage windows the autopilot was denied, and those it was not.

    ``denial`` None: the denial is in the sensor stream (PX4), every window was. Else a window
    was denied when at least one step of the denial is due at its start (within
    ``_STEP_LEAD_S``) and the autopilot took every such step.
    """
    if denial is None:
        return list(outages), []
    denied: list[Window] = []
    not_denied: list[Window] = []
    for w in outages:
        steps = [d for d in denial if abs(d.time_s - w.start_s) <= _STEP_LEAD_S]
        (denied if steps and all(d.took for d in steps) else not_denied).append(w)
    return denied, not_denied
