"""The pass-criteria metrics a scenario may name are exactly the numbers the scorer produces."""


from __future__ import annotations

import math
from typing import Any

import numpy as np

from fusion import earth
from hil.tracks import Fixes, HealthSeries, Track
from scenarios.metrics import Window
from scenarios.schema import (
    KNOWN_METRICS,
)
from scenarios.summary import RunInfo, ScoringConfig, build_summary

#: Numbers in summary.json that are not pass criteria: bookkeeping, scoring settings, curves.
NOT_CRITERIA = {
    "schema_version", "seed", "wall_s", "nees.nees_dof", "outages.drift.step_s",
    "outages.drift.horizontal_m", "scoring.reconverge_threshold_m", "scoring.reconverge_hold_s",
    "scoring.bad_fix_m",
    # the fix gaps an outage is made of ([start_s, end_s] pairs), not a figure of merit
    "outages.gaps",
    # a flag (true / false; null for an event without a re-accept check), not a number
    "events.reaccepted_early",
}


def _numeric_paths(node: Any, prefix: str = "") -> set[str]:
    """Dotted paths of the number (or null) leaves; lists of objects fan out like criteria."""
    if isinstance(node, dict):
        out: set[str] = set()
        for key, value in node.items():
            out |= _numeric_paths(value, f"{prefix}.{key}" if prefix else str(key))
        return out
    if isinstance(node, list) and all(isinstance(v, dict) for v in node):
        return set().union(set(), *(_numeric_paths(v, prefix) for v in node))
    if isinstance(node, list) or (isinstance(node, int | float | None)
                                  and not isinstance(node, bool)):
        return {prefix}
    return set()


def _full_summary() -> dict[str, Any]:
    """A scored run that fills every part of summary.json: a 130 s outage, a spoof event and
    one event per other sensor, sigmas, and a health series with every counter and the fixes."""
    t = np.round(np.arange(0.0, 320.0, 0.1), 6)
    n = t.size
    lat0, lon0 = math.radians(47.0), math.radians(8.0)
    r_n, r_e = (float(r) for r in earth.principal_radii(lat0))
    east = 40.0 * t
    err_n = 1.0 + np.clip(t - 100.0, 0.0, 130.0) * (t < 230.0)
    sigma = np.tile([1.0, 1.0, 1.0, 0.1, 0.1, 0.1, 0.01, 0.01, 0.01], (n, 1))

    def track(north: np.ndarray, sig: np.ndarray | None = None) -> Track:
        return Track(t, lat0 + north / r_n, lon0 + east / (r_e * math.cos(lat0)),
                     np.full(n, 500.0), np.zeros((n, 3)), np.zeros((n, 3)), sig)

    truth, est = track(np.zeros(n)), track(err_n, sigma)
    fix_t = t[((t < 100.0) | (t >= 230.0)) & (np.round(t * 10) % 2 == 0)]
    spoof = (fix_t >= 260.0) & (fix_t < 290.0)
    fixes = Fixes(fix_t, lat0 + spoof * 500.0 / r_n, np.interp(fix_t, t, truth.lon_rad),
                  np.full(fix_t.size, 500.0))
    counter = np.searchsorted(fix_t, t, side="right").astype(np.int64)
    rejected = np.searchsorted(fix_t[spoof], t, side="right").astype(np.int64)
    health = HealthSeries(
        t, mode=np.where((t > 101.0) & (t < 230.0), "free-inertial", "gnss"),
        gnss_fused=counter, gnss_rejected=rejected, gnss_resets=counter,
        gnss_quality_rejected=counter, baro_fused=counter, baro_rejected=counter,
        baro_resets=counter, mag_fused=counter, mag_rejected=counter,
        airspeed_blockages=counter, fixes=fixes)
    # one event per sensor, so that every detect_s_by_sensor list has a value
    others = [{"type": name, "start_s": 300.0, "end_s": 310.0} for name in (
        "baro_glitch", "mag_anomaly", "imu_bias_step", "pitot_blockage", "solar_flare")]
    summary, _ = build_summary(
        RunInfo("full", 1, 320.0, 1.0, "none", "ekf"), est, truth, [Window(100.0, 230.0)],
        settle_s=20.0, health={"filter": {"gnss_fused": 1}}, series=health,
        events=[{"type": "gnss_spoof_hijack", "start_s": 260.0, "end_s": 290.0}, *others],
        scoring=ScoringConfig(bad_fix_m=50.0))
    return summary


def test_known_metrics_are_exactly_what_the_scorer_produces() -> None:
    # GIVEN a scored run that fills every section of summary.json
    produced = {p for p in _numeric_paths(_full_summary()) if not p.startswith("health.")}
    # THEN every number in it is either a criterion metric or named as bookkeeping, and every
    # criterion metric the schema accepts is there: adding or renaming a metric in the scorer
    # without updating KNOWN_METRICS (or the reverse) fails here
    assert NOT_CRITERIA <= produced
    assert sorted(produced - NOT_CRITERIA - set(KNOWN_METRICS)) == []
    assert sorted(set(KNOWN_METRICS) - produced) == []
