"""scenarios.autopilot_summary.score_flown: what the section says when there is nothing to
score (no telemetry link, no truth), and that the flight's counters are kept."""

from __future__ import annotations

import numpy as np

from hil.autopilot import AutopilotFlown
from hil.tracks import Track
from scenarios.autopilot_summary import AUTOPILOT_METRIC_KEYS, score_flown


def _flown(stalled: str | None = None) -> AutopilotFlown:
    return AutopilotFlown("ArduPilot", True, 12.0, 3.0, 1200, 5000, None, stalled, False, 4,
                          {"steps_answered": 1200})


def _truth() -> Track:
    t = np.linspace(0.0, 12.0, 13)
    z = np.zeros_like(t)
    return Track(t, z, z, z + 1000.0, np.zeros((13, 3)), np.zeros((13, 3)))


def test_without_a_telemetry_link_the_section_says_why_nothing_was_scored() -> None:
    s = score_flown(_flown(), None, _truth(), [], link={"telemetry": None}, settle_s=1.0)
    sec = s.section
    assert sec["problem"] == "no telemetry link to record its estimate from"
    assert all(sec[k] is None for k in AUTOPILOT_METRIC_KEYS) and s.errors is None
    assert sec["counters"] == {"steps_answered": 1200, "clipped_controls": 4, "steps": 1200}
    assert sec["connected"] and sec["stalled"] is None and sec["source"] == "ArduPilot"


def test_a_stalled_flight_without_truth_is_reported_not_scored() -> None:
    s = score_flown(_flown("ArduPilot sent no controls for 10 s"), None, None, [], link={},
                    settle_s=1.0)
    assert s.section["stalled"] == "ArduPilot sent no controls for 10 s"
    assert s.section["outages"] is None and s.track is None
