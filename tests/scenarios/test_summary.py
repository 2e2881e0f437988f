"""Settling fitted to a short log (scenarios.summary.fit_settling): the GNSS-on figures are
never silently empty, and a request that fits is applied unchanged."""

from __future__ import annotations

import numpy as np
import pytest

from scenarios.metrics import Window
from scenarios.summary import MIN_SCORED_FRACTION, fit_settling

DT_S = 0.02  # 50 Hz estimates


def _times(duration_s: float) -> np.ndarray:
    return np.arange(0.0, duration_s + DT_S / 2, DT_S)


def test_a_settle_that_fits_is_applied_unchanged() -> None:
    s = fit_settling(60.0, _times(600.0), [Window(300.0, 360.0)])
    assert s.applied_s == 60.0 and s.warning is None
    # GNSS on: 60-300 s and 420-600 s
    assert s.scored_s == pytest.approx(240.0 + 180.0, abs=2 * DT_S)
    assert s.span_s == pytest.approx(600.0)


def test_a_settle_longer_than_the_log_leaves_half_of_it() -> None:
    """20 s without outages, 60 s asked: scored(a) = 20 - a, so a = 10 s (to 1 ms, rounded
    down so that at least half stays)."""
    s = fit_settling(60.0, _times(20.0), [])
    assert s.applied_s == pytest.approx(10.0, abs=2e-3) and s.applied_s <= 10.0 + DT_S
    assert s.scored_s >= MIN_SCORED_FRACTION * 20.0 - DT_S
    assert s.warning is not None and "--settle 60 s is longer than the log allows" in s.warning


def test_outages_count_in_the_fit() -> None:
    """20 s with GNSS off from 10 s to the end: 10 s of GNSS; settling after the start eats
    it from the front, so half of it is left with a = 5 s."""
    s = fit_settling(60.0, _times(20.0), [Window(10.0, 20.0)])
    assert s.applied_s == pytest.approx(5.0, abs=2 * DT_S)
    assert s.scored_s == pytest.approx(5.0, abs=2 * DT_S)


def test_no_gnss_on_time_is_said() -> None:
    s = fit_settling(5.0, _times(20.0), [Window(0.0, 25.0)])
    assert s.applied_s == 0.0 and s.scored_s == 0.0
    assert s.warning is not None and "no GNSS-on time" in s.warning
    assert set(s.as_dict()) == {"requested_s", "applied_s", "span_s", "scored_s", "warning"}
