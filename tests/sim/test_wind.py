"""Tests of the wind in the JSBSim adapter (sim.flight): the steady wind, the altitude profile
(power-law shear or a table), the true wind in the truth, and the guidance law flying the
racetrack in a crosswind (every turn completes)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from pydantic import ValidationError

from sim.flight import Flight, FlightConfig, suggested_start
from sim.guidance import GuidanceGains
from sim.plans import load_plan

# The track loop's tolerance: the waypoint law commands an intercept of atan(cross / L) with
# the lookahead L = max(250 m, 8 s x 50 m/s) = 400 m; a cross-track error of L tan(1 deg)
# (7.0 m) is where it commands 1 deg, the tolerance a turn leg is completed to.
_G = GuidanceGains()
_LOOKAHEAD_M = max(_G.min_lookahead_m, _G.lookahead_s * 50.0)
_TRACK_TOL_M = _LOOKAHEAD_M * math.tan(math.radians(1.0))
# The track loop is second order: x'' + k x' + (V k / L) x = 0 (course rate k times the course
# error, cross-track rate V times it), with k = 0.25 1/s, V = 50 m/s, L = 400 m:
# omega_n = 0.18 rad/s, zeta = 0.71, decay time 1 / (zeta omega_n) = 8 s. A leg is scored from
# 60 s after it began (7.5 decay times: the intercept transient is down to 6e-4).
_SETTLE_S = 60.0


def _config(**kw: object) -> FlightConfig:
    return FlightConfig(aircraft="c172x", rate_hz=100.0, start=suggested_start("c172x"), seed=3,
                        **kw)  # type: ignore[arg-type]


def test_truth_carries_the_true_wind() -> None:
    with Flight(_config(wind_ned_mps=(5.0, -3.0, 0.5)), load_plan("cruise")) as f:
        truths = [f.step() for _ in range(300)]
    for t in truths:
        np.testing.assert_allclose(t.wind_ned_mps, (5.0, -3.0, 0.5), atol=1e-9)
        # the air-relative velocity is the ground velocity minus the wind
        assert np.linalg.norm(t.v_ned_mps - t.wind_ned_mps) == pytest.approx(
            t.airspeed_mps, abs=1e-6)


def test_turbulence_shows_in_the_true_wind() -> None:
    with Flight(_config(wind_ned_mps=(5.0, -3.0, 0.0), turbulence=0.3),
                load_plan("cruise")) as f:
        wind = np.array([f.step().wind_ned_mps for _ in range(3000)])
    assert np.all(np.isfinite(wind))
    assert np.std(wind[:, 0]) > 0.1 and np.std(wind[:, 2]) > 0.05


def test_power_law_shear_follows_the_altitude() -> None:
    # climb-descent changes altitude by hundreds of metres: the wind must follow
    # w(h) = w_ref (h / h_ref)^(1/7), h_ref the start altitude (1000 m above ground)
    p = 1.0 / 7.0
    cfg = _config(wind_ned_mps=(8.0, -4.0, 0.0), wind_shear_exponent=p)
    with Flight(cfg, load_plan("climb-descent")) as f:
        rows = []
        for _ in range(240):
            t = f.run_for(1.0)
            rows.append((t.alt_msl_m, *t.wind_ned_mps))
    a = np.array(rows)
    assert np.ptp(a[:, 0]) > 100.0  # the plan did change altitude
    # the wind of a step is set from the altitude one step (10 ms, < 3 cm of climb) before
    scale = (a[:, 0] / 1000.0) ** p
    np.testing.assert_allclose(a[:, 1], 8.0 * scale, atol=1e-4)
    np.testing.assert_allclose(a[:, 2], -4.0 * scale, atol=1e-4)


def test_wind_table_interpolates_and_is_validated() -> None:
    cfg = _config(wind_table=((500.0, 0.0, 2.0), (1500.0, 10.0, 2.0)))
    assert cfg.wind_varies_with_altitude
    assert cfg.wind_at(1000.0, 1000.0) == pytest.approx((5.0, 2.0, 0.0))
    assert cfg.wind_at(100.0, 100.0) == pytest.approx((0.0, 2.0, 0.0))  # constant below
    assert cfg.wind_at(9000.0, 9000.0) == pytest.approx((10.0, 2.0, 0.0))  # and above
    with pytest.raises(ValidationError, match="increase"):
        _config(wind_table=((500.0, 0.0, 0.0), (500.0, 1.0, 0.0)))
    with pytest.raises(ValidationError, match="replaces"):
        _config(wind_ned_mps=(3.0, 0.0, 0.0), wind_table=((500.0, 0.0, 0.0),))
    # without a profile, nothing is set per step (the zero-wind flight is untouched)
    assert not _config(wind_ned_mps=(3.0, 0.0, 0.0)).wind_varies_with_altitude
    assert not _config(wind_shear_exponent=0.2).wind_varies_with_altitude


def _fly_racetrack(cfg: FlightConfig, duration_s: float) -> tuple[int, np.ndarray]:
    """Legs completed and the cross-track errors (m) on the straights, from _SETTLE_S after
    each straight began, sampled every second."""
    plan = load_plan("racetrack")
    with Flight(cfg, plan) as f:
        g = f.guidance
        where, began, p0 = (g.leg_index, g.lap), 0.0, (0.0, 0.0)
        changes, cross = 0, []
        for _ in range(round(duration_s)):
            f.run_for(1.0)
            s = f._guidance_input(f.time_s)  # the position the law itself sees
            if (g.leg_index, g.lap) != where:
                changes, where, began, p0 = changes + 1, (g.leg_index, g.lap), f.time_s, (
                    s.north_m, s.east_m)
            leg = plan.legs[g.leg_index]
            if leg.kind == "waypoint" and f.time_s - began >= _SETTLE_S:
                assert leg.x_m is not None and leg.y_m is not None
                dn, de = leg.x_m - p0[0], leg.y_m - p0[1]  # frame "start", heading 0: NED
                length = math.hypot(dn, de)
                cross.append((dn * (s.east_m - p0[1]) - de * (s.north_m - p0[0])) / length)
    return changes, np.array(cross)


@pytest.mark.parametrize(
    ("wind", "turbulence"),
    [((5.0, -3.0, 0.0), 0.0),  # a wind across the first turn
     ((0.0, 12.0, 0.0), 0.4),  # a strong pure crosswind with turbulence
     ((-8.5, 8.5, 0.0), 0.4)],
)
def test_racetrack_turns_complete_and_legs_are_tracked_in_crosswind(
    wind: tuple[float, float, float], turbulence: float
) -> None:
    # a lap: two 4 km straights (80-100 s at 50 m/s +- the wind) and two 180-degree turns at
    # 25 deg of bank (34 s in the air mass); 320 s holds a lap, so all four legs must end
    changes, cross = _fly_racetrack(_config(wind_ned_mps=wind, turbulence=turbulence), 320.0)
    assert changes >= 4, f"only {changes} legs completed: a turn stalled"
    assert cross.size >= 20
    if turbulence == 0.0:
        assert np.abs(cross).max() < _TRACK_TOL_M, np.abs(cross).max()
    else:  # gusts move the aircraft off the line and back: the RMS is held, not every sample
        assert np.sqrt(np.mean(cross**2)) < _TRACK_TOL_M, np.sqrt(np.mean(cross**2))
