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
        ("gnss_rejected", "warning", "GNSS fix rejected by the gate", 0),
        ("gnss_rejected", "warning", "GNSS fix rejected by the gate", 2),  # 2 held back
        ("mode", "warning", "GNSS lost: dead-reckoning", None),
        ("mode", "notice", "GNSS regained", None),
    ]


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
