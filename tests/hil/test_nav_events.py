"""Navigation events from successive estimates: mode changes, counter-driven faults, the rate
limit, spoofing suspicion; and the simulator's scenario timeline."""

from __future__ import annotations

import dataclasses

from fusion.estimate import Health, NavEstimate
from hil.nav_events import NavEventDetector
from hil.pipeline import SimSetup
from hil.scenario_events import ScenarioTimeline
from sim.faults.events import GnssOutage
from sim.faults.injector import FaultLogEntry
from tests.hil.test_service import _estimate


def _at(t_s: float, mode: str, **health: int) -> NavEstimate:
    est = _estimate(mode=mode)
    return dataclasses.replace(est, time_us=round(t_s * 1e6), health=Health(**health),
                               time_since_gnss_s=0.0)


def test_mode_changes_and_rate_limited_rejections() -> None:
    det = NavEventDetector(min_interval_s=5.0)
    msgs = []
    for t, mode, rej in ((0.0, "initializing", 0), (1.0, "gnss", 0), (2.0, "gnss", 1),
                         (3.0, "gnss", 2), (4.0, "gnss", 3), (8.0, "gnss", 4),
                         (10.0, "dead-reckoning", 4), (20.0, "gnss", 4)):
        msgs += [(e.event, e.severity, e.message, e.detail.get("suppressed"))
                 for e in det.update(_at(t, mode, gnss_rejected=rej))]
    assert msgs == [
        ("mode", "info", "Nav mode: aligning", None),
        ("mode", "notice", "Nav aligned: GNSS", None),
        ("gnss_rejected", "debug", "GNSS fix rejected by the gate", 0),
        # the third fix rejected with none fused between: persistent
        ("gnss_rejections_persist", "warning", "GNSS fixes rejected: 3 in a row", None),
        ("gnss_rejected", "debug", "GNSS fix rejected by the gate", 2),  # 2 held back
        ("mode", "warning", "GNSS lost: dead-reckoning", None),
        ("mode", "notice", "GNSS regained", None),
    ]


def _gate_events(det: NavEventDetector, steps: list[tuple[float, int, int]]) -> list[str]:
    """Feed (t_s, fused total, rejected total) in GNSS mode; the gate episode events."""
    out = []
    for t, fused, rejected in steps:
        est = dataclasses.replace(_at(t, "gnss", gnss_fused=fused, gnss_rejected=rejected))
        out += [f"{e.severity}: {e.message}" for e in det.update(est)
                if e.event in {"gnss_rejections_persist", "gnss_gate_clear"}]
    return out


def test_single_rejections_at_the_false_alarm_rate_raise_no_warning() -> None:
    """GIVEN fixes at 5 Hz with one rejected every 20 s (the 0.5 % a 0.995 gate rejects by
    chance) for 10 min WHEN the detector watches THEN no episode starts, and the single
    rejections are debug events only (the shadow vehicle sends none of them)."""
    det = NavEventDetector()
    steps, fused, rejected = [], 0, 0
    for k in range(1, 3000):
        if k % 100 == 0:
            rejected += 1
        else:
            fused += 1
        steps.append((k * 0.2, fused, rejected))
    assert _gate_events(det, steps) == []
    assert {e.severity for e in det.events if e.event == "gnss_rejected"} == {"debug"}


def test_persistent_rejections_warn_once_and_clear_once() -> None:
    """GIVEN good fixes, then every fix rejected for 4 s (a glitch), then good fixes again
    WHEN the detector watches THEN one warning when the third fix in a row is rejected, one
    "accepted again" notice at the first fused fix 5 s after the last rejection, nothing else."""
    det = NavEventDetector()
    steps, fused, rejected, t = [], 0, 0, 0.0
    for k in range(300):  # 0-30 s good, 30-34 s rejected, 34-60 s good
        t = k * 0.2
        if 30.0 <= t < 34.0:
            rejected += 1
        else:
            fused += 1
        steps.append((t, fused, rejected))
    events = _gate_events(det, steps)
    assert events == ["warning: GNSS fixes rejected: 3 in a row",
                      "notice: GNSS fixes accepted again"]
    persist = next(e for e in det.events if e.event == "gnss_rejections_persist")
    clear = next(e for e in det.events if e.event == "gnss_gate_clear")
    # the last rejection is at 33.8 s
    assert persist.time_us == round(30.4 * 1e6) and clear.time_us == round(38.8 * 1e6)


def test_a_burst_of_rejections_between_fused_fixes_is_an_episode() -> None:
    """GIVEN every other fix rejected (never 3 in a row) WHEN 10 are rejected within 20 s
    THEN that is an episode too."""
    det = NavEventDetector()
    steps, fused, rejected = [], 0, 0
    for k in range(1, 40):
        if k % 2:
            rejected += 1
        else:
            fused += 1
        steps.append((k * 0.2, fused, rejected))
    assert _gate_events(det, steps) == ["warning: GNSS fixes rejected: 10 in 20 s"]


def test_first_estimate_already_aligned_says_aligned() -> None:
    """GIVEN a filter whose first estimate is already aligned (an in-flight start from GNSS)
    WHEN the detector sees it THEN the mode event says so ("Nav aligned: GNSS")."""
    (ev,) = NavEventDetector().update(_at(0.0, "gnss"))
    assert (ev.severity, ev.message) == ("notice", "Nav aligned: GNSS")


def test_scenario_timeline_gnss_windows_and_faults() -> None:
    setup = SimSetup.build(duration_s=60.0, gnss_off=["10:5"])
    setup = dataclasses.replace(setup, faults=(GnssOutage(start_s=20.0, duration_s=3.0),))
    tl = ScenarioTimeline(setup, 0)
    assert tl.due(9_000_000, []) == []
    assert [e[1] for e in tl.due(15_000_000, [])] == ["gnss_off", "gnss_on"]
    log = [FaultLogEntry(20_000_000, "gnss_outage", "start", 0)]
    (ev,) = tl.due(20_000_000, log)
    assert ev[:2] == (20_000_000, "fault_start")
    assert ev[3]["type"] == "gnss_outage" and ev[3]["params"]["duration_s"] == 3.0
    assert tl.due(21_000_000, log) == []  # each entry once
