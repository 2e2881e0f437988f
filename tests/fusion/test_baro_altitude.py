"""Tests for fusion.altitude's barometric modules: standard atmosphere, QNH, P4 calibration,
altimeter, baro monitor."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import physconst as pc
from fusion.altitude.altimeter import BaroAltimeter, BaroAltimeterConfig
from fusion.altitude.atmosphere import (
    BIAS_PER_PRESSURE_M_PER_PA,
    P_MAX_PA,
    P_MIN_PA,
    calibrated_altitude_m,
    geometric_from_geopotential,
    geopotential_from_geometric,
    isa_pressure_pa,
    isa_temperature_k,
    nonstandard_scale_bias,
    p4_sea_level_conditions,
    pressure_altitude_m,
    qnh_altitude_m,
    scale_from_temperature,
)
from fusion.altitude.baro_monitor import BaroMonitor, BaroMonitorConfig
from fusion.altitude.calibration import BaroCalibration, BaroCalibrationConfig
from sim import atmosphere as atm

# US Standard Atmosphere 1976, Table I (layer bases, geopotential altitude): pressure and
# temperature. Our constants (R = 287.05287, g0) reproduce them to a few ppm; the residual comes
# from the table's R*/M0 and its rounding.
US76_LAYER_BASES = [
    (0.0, 101325.0, 288.15),
    (11000.0, 22632.06, 216.65),
    (20000.0, 5474.889, 216.65),
    (32000.0, 868.0187, 228.65),
    (47000.0, 110.9063, 270.65),
]
# US Standard Atmosphere 1976, geometric altitude table (5 significant digits).
US76_GEOMETRIC = [(1000.0, 8.9876e4), (3000.0, 7.0121e4), (5000.0, 5.4048e4), (10000.0, 2.6500e4)]


@pytest.mark.parametrize(("h_gp", "p_tab", "t_tab"), US76_LAYER_BASES)
def test_standard_atmosphere_matches_us76_layer_table(h_gp: float, p_tab: float, t_tab: float):
    assert isa_pressure_pa(h_gp) == pytest.approx(p_tab, rel=1e-5)
    assert isa_temperature_k(h_gp) == pytest.approx(t_tab, abs=1e-9)
    # and the inverse lands on the tabulated altitude (0.01 m for a few-ppm pressure residual)
    assert pressure_altitude_m(p_tab) == pytest.approx(h_gp, abs=0.05)


@pytest.mark.parametrize(("z_m", "p_tab"), US76_GEOMETRIC)
def test_standard_atmosphere_matches_us76_geometric_table(z_m: float, p_tab: float):
    p = isa_pressure_pa(geopotential_from_geometric(z_m))
    assert p == pytest.approx(p_tab, rel=6e-5)  # half a unit in the 5th digit
    h = geometric_from_geopotential(pressure_altitude_m(p_tab))
    assert h == pytest.approx(z_m, abs=0.5)


def test_geopotential_difference_is_16_cm_at_1_km():
    assert 1000.0 - geopotential_from_geometric(1000.0) == pytest.approx(0.157, abs=0.001)
    assert geometric_from_geopotential(geopotential_from_geometric(8848.0)) == (
        pytest.approx(8848.0, abs=1e-9)
    )


@settings(max_examples=200, deadline=None)
@given(st.floats(min_value=-4999.0, max_value=46999.0))
def test_pressure_altitude_inverts_isa_pressure(h_gp: float):
    assert pressure_altitude_m(isa_pressure_pa(h_gp)) == pytest.approx(h_gp, abs=1e-6)


@settings(max_examples=200, deadline=None)
@given(
    h=st.floats(min_value=-300.0, max_value=9000.0),
    d_t=st.floats(min_value=-30.0, max_value=30.0),
    d_p=st.floats(min_value=-4000.0, max_value=4000.0),
)
def test_inverse_matches_simulator_forward_model(h: float, d_t: float, d_p: float):
    # The simulator builds pressure from geopotential altitude in P4's non-standard atmosphere;
    # the fusion-side inverse must return the same altitude (no model error beyond the sensor).
    p = float(atm.pressure_from_altitude(h, d_t, d_p))
    s, b = nonstandard_scale_bias(d_t, d_p)
    assert calibrated_altitude_m(pressure_altitude_m(p), s, b) == pytest.approx(h, abs=1e-6)
    t = float(atm.temperature_from_altitude(h, d_t, d_p))
    assert scale_from_temperature(t, pressure_altitude_m(p)) == pytest.approx(s, abs=1e-12)


@pytest.mark.parametrize(
    "bad", [0.0, -1.0, math.nan, math.inf, -math.inf, 50.0, 2.0e5, P_MAX_PA * 1.001]
)
def test_bad_pressure_raises_naming_the_field(bad: float):
    with pytest.raises(ValueError, match="pressure_pa"):
        pressure_altitude_m(bad)
    with pytest.raises(ValueError, match="pressure_pa"):
        BaroAltimeter().altitude_m(bad)


def test_model_range_limits_are_the_simulators():
    assert P_MIN_PA == pytest.approx(atm.P_MIN_PA, rel=1e-12)
    assert P_MAX_PA == pytest.approx(atm.P_MAX_PA, rel=1e-12)
    assert pressure_altitude_m(P_MIN_PA) == pytest.approx(47000.0, abs=1e-6)
    assert pressure_altitude_m(P_MAX_PA) == pytest.approx(-5000.0, abs=1e-6)


def test_qnh_altimeter_reads_zero_at_qnh_and_first_order_p4_bias():
    qnh = 102325.0  # +10 hPa
    assert qnh_altitude_m(qnh, qnh) == 0.0
    assert qnh_altitude_m(90000.0, pc.ISA_P0_PA) == pytest.approx(
        pressure_altitude_m(90000.0))
    # Against the simulator's atmosphere with the same sea-level pressure offset: the QNH
    # altimeter is P4's bias to first order (0.3 m at 1 km per the atmosphere docstring).
    for h in (0.0, 1000.0, 3000.0):
        p = float(atm.pressure_from_altitude(h, 0.0, qnh - pc.ISA_P0_PA))
        assert qnh_altitude_m(p, qnh) == pytest.approx(h, abs=1.0)
    alt = BaroAltimeter(BaroAltimeterConfig(mode="qnh", qnh_pa=qnh))
    p = float(atm.pressure_from_altitude(1000.0, 0.0, 1000.0))
    assert alt.altitude_m(p) == pytest.approx(
        geometric_from_geopotential(qnh_altitude_m(p, qnh))
    )


def test_qnh_mode_without_setting_and_absurd_qnh_are_rejected():
    with pytest.raises(ValueError, match="qnh_pa"):
        BaroAltimeter(BaroAltimeterConfig(mode="qnh"))
    with pytest.raises(ValueError, match="qnh_pa"):
        BaroAltimeterConfig(qnh_pa=50000.0)
    with pytest.raises(ValueError, match="qnh_pa"):
        qnh_altitude_m(90000.0, 1013.25)  # hPa instead of Pa


def test_unknown_config_keys_are_rejected():
    with pytest.raises(ValueError, match="qnh_hpa"):
        BaroAltimeterConfig(qnh_hpa=1013.0)  # type: ignore[call-arg]


def test_p4_eq4_temperature_is_sound_but_its_pressure_is_not():
    # In a perfectly standard atmosphere at 1 km, P4 eq. 4 returns the standard sea-level
    # temperature, but a sea-level pressure 5.5 hPa low (-46 m of bias): documented flaw.
    p, t = isa_pressure_pa(1000.0), isa_temperature_k(1000.0)
    ti, pi = p4_sea_level_conditions(p, t)
    assert ti == pytest.approx(pc.ISA_T0_K, abs=1e-9)
    assert pi - pc.ISA_P0_PA == pytest.approx(-549.0, abs=2.0)
    assert BIAS_PER_PRESSURE_M_PER_PA * (pi - pc.ISA_P0_PA) == pytest.approx(-45.7, abs=0.3)


def _climb(
    d_t: float,
    d_p: float,
    rng: np.random.Generator | None = None,
    gnss_sigma: float = 0.0,
    baro_sigma_pa: float = 0.0,
    n: int = 600,
) -> list[tuple[float, float, float, float]]:
    """(time, geometric MSL height, pressure, temperature) along a 200 -> 2200 m climb."""
    out = []
    for k in range(n):
        h = 200.0 + 2000.0 * k / (n - 1)
        h_gp = float(atm.geopotential_from_geometric(h))
        p = float(atm.pressure_from_altitude(h_gp, d_t, d_p))
        t = float(atm.temperature_from_altitude(h_gp, d_t, d_p))
        if rng is not None:
            h += gnss_sigma * rng.standard_normal()
            p += baro_sigma_pa * rng.standard_normal()
        out.append((k * 1.0, h, p, t))
    return out


def test_calibration_recovers_known_dt_dp_noise_free():
    d_t, d_p = 12.0, 900.0
    alt = BaroAltimeter()
    for t, h, p, temp in _climb(d_t, d_p):
        alt.calibrate(h, p, temp, time_s=t, sigma_m=0.5)
    cal = alt.calibration
    assert cal.sea_level_dt_k == pytest.approx(d_t, abs=0.05)
    assert cal.sea_level_dp_pa == pytest.approx(d_p, abs=2.0)
    # and the altimeter then reads the true geometric height
    p = float(atm.pressure_from_altitude(atm.geopotential_from_geometric(1500.0), d_t, d_p))
    assert alt.altitude_m(p) == pytest.approx(1500.0, abs=0.05)


def test_calibration_with_noise_is_consistent_with_its_covariance():
    d_t, d_p = -8.0, -1200.0
    rng = np.random.default_rng(7)
    cal_cfg = BaroCalibrationConfig(bias_random_walk_m_per_rth_s=0.001)
    alt = BaroAltimeter(BaroAltimeterConfig(calibration=cal_cfg))
    for t, h, p, temp in _climb(d_t, d_p, rng, gnss_sigma=2.0, baro_sigma_pa=1.0, n=1200):
        alt.calibrate(h, p, temp, time_s=t, sigma_m=2.0)
    cal = alt.calibration
    (pss, _), (_, pbb) = cal.covariance
    s_true, b_true = nonstandard_scale_bias(d_t, d_p)
    # 4-sigma consistency of the estimate with its own covariance
    assert abs(cal.scale - s_true) < 4.0 * math.sqrt(pss)
    assert abs(cal.bias_m - b_true) < 4.0 * math.sqrt(pbb)
    assert cal.sea_level_dt_k == pytest.approx(d_t, abs=1.0)
    assert cal.sea_level_dp_pa == pytest.approx(d_p, abs=40.0)


def test_temperature_gives_scale_without_altitude_change():
    # Level flight at 1500 m: GNSS alone cannot separate s from b; the temperature can.
    d_t, d_p = 15.0, 0.0
    cfg = BaroAltimeterConfig(
        calibration=BaroCalibrationConfig(use_temperature=True, temperature_sigma_k=0.5)
    )
    alt = BaroAltimeter(cfg)
    h_gp = float(atm.geopotential_from_geometric(1500.0))
    p = float(atm.pressure_from_altitude(h_gp, d_t, d_p))
    temp = float(atm.temperature_from_altitude(h_gp, d_t, d_p))
    for k in range(200):
        alt.calibrate(1500.0, p, temp, time_s=float(k), sigma_m=1.0)
    assert alt.calibration.sea_level_dt_k == pytest.approx(d_t, abs=0.2)
    assert alt.altitude_m(p) == pytest.approx(1500.0, abs=0.05)


def test_geoid_undulation_is_handled_explicitly():
    # P4's 60 m: GNSS gives ellipsoidal height; N = +60 m. Declared honestly, the calibration
    # recovers the atmosphere; fed as if MSL, 60 m land in b (≈ 7 hPa of fake pressure offset).
    d_t, d_p, n_geoid = 5.0, 300.0, 60.0
    honest, naive = BaroAltimeter(), BaroAltimeter()
    for t, h, p, temp in _climb(d_t, d_p):
        honest.calibrate(
            h + n_geoid,
            p,
            temp,
            time_s=t,
            sigma_m=0.5,
            reference="ellipsoid",
            geoid_undulation_m=n_geoid,
        )
        naive.calibrate(h + n_geoid, p, temp, time_s=t, sigma_m=0.5)
    assert honest.calibration.sea_level_dp_pa == pytest.approx(d_p, abs=2.0)
    fake_dp = naive.calibration.sea_level_dp_pa - d_p
    assert fake_dp == pytest.approx(n_geoid / BIAS_PER_PRESSURE_M_PER_PA, rel=0.02)
    assert fake_dp / 100.0 == pytest.approx(7.2, abs=0.2)  # hPa


def test_freeze_stops_learning_and_gate_rejects_outliers():
    alt = BaroAltimeter()
    data = _climb(0.0, 500.0, n=200)
    for t, h, p, temp in data[:100]:
        alt.calibrate(h, p, temp, time_s=t, sigma_m=1.0)
    cal = alt.calibration
    s0, b0 = cal.scale, cal.bias_m
    alt.freeze()
    t, h, p, temp = data[100]
    upd = alt.calibrate(h + 30.0, p, temp, time_s=t, sigma_m=1.0)
    assert not upd.accepted and not upd.rejected
    assert (cal.scale, cal.bias_m) == (s0, b0)
    alt.unfreeze()
    upd = alt.calibrate(h + 100.0, p, temp, time_s=t, sigma_m=1.0)  # 100 m GNSS glitch
    assert upd.rejected and cal.n_rejected == 1
    assert (cal.scale, cal.bias_m) == (s0, b0)
    upd = alt.calibrate(h, p, temp, time_s=t + 1.0, sigma_m=1.0)
    assert upd.accepted


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"sigma_m": 0.0}, "sigma_m"),
        ({"sigma_m": math.nan}, "sigma_m"),
        ({"sigma_m": 1.0, "reference": "geoid"}, "reference"),
    ],
)
def test_calibration_bad_arguments(kwargs: dict, field: str):
    with pytest.raises(ValueError, match=field):
        BaroCalibration().update(100.0, 100.0, 0.0, **kwargs)


def test_calibration_non_finite_height_raises():
    with pytest.raises(ValueError, match="finite"):
        BaroCalibration().update(math.nan, 100.0, 0.0, sigma_m=1.0)


def test_p4_setup_learns_no_bias_from_gnss():
    cfg = BaroCalibrationConfig(use_gnss=False)
    cal = BaroCalibration(cfg)
    for k in range(50):
        upd = cal.update(500.0, 400.0, float(k), sigma_m=1.0)
        assert not upd.rejected and upd.delta_altitude_m == 0.0
    assert (cal.scale, cal.bias_m) == (0.0, 0.0)


# ---- monitor --------------------------------------------------------------------------------


@pytest.mark.parametrize("bad", [0.0, -100.0, math.nan, math.inf, 10.0, 3.0e5])
def test_monitor_counts_out_of_range_pressure(bad: float):
    mon = BaroMonitor()
    assert mon.check(bad, 0.0) is None
    assert mon.health.range_errors == 1 and mon.health.samples == 1
    assert mon.check(90000.0, 0.04) == pytest.approx(pressure_altitude_m(90000.0))


def test_monitor_detects_a_frozen_sensor_and_its_recovery():
    mon = BaroMonitor(BaroMonitorConfig(freeze_time_s=2.0))
    used = [mon.check(90000.0, 0.04 * k) is not None for k in range(100)]  # 4 s identical
    # accepted until 2 s of identical readings, rejected afterwards
    assert all(used[:50]) and not any(used[51:])
    assert mon.health.freeze_events == 1 and mon.health.frozen
    assert mon.check(90001.0, 4.0) is not None
    assert not mon.health.frozen and mon.health.freeze_events == 1


def test_monitor_does_not_flag_a_live_noisy_sensor():
    mon = BaroMonitor()
    rng = np.random.default_rng(3)
    # 1.2 Pa noise quantised to 1 Pa at 25 Hz for 60 s (an MS5611 at rest)
    for k in range(1500):
        mon.check(float(round(90000.0 + 1.2 * rng.standard_normal())), 0.04 * k)
    assert mon.health.freeze_events == 0 and mon.health.frozen_samples == 0


def test_monitor_gate_and_rejection_duration():
    mon = BaroMonitor(BaroMonitorConfig(gate_m=5.0))
    assert mon.gate(104.9, 100.0, 0.0)
    assert not mon.gate(106.0, 100.0, 1.0)
    assert not mon.gate(106.0, 100.0, 3.5)
    assert mon.rejecting_for_s(3.5) == pytest.approx(2.5)
    assert mon.health.gate_rejections == 2 and mon.health.rejecting
    assert mon.gate(101.0, 100.0, 4.0)
    assert mon.rejecting_for_s(4.0) == 0.0 and mon.health.accepted == 2


def test_calibration_snapshot_restore_round_trip():
    cal = BaroCalibration()
    state = cal.snapshot()
    for k in range(20):
        cal.update(1000.0 + k, 990.0 + k, float(k), sigma_m=2.0)
    assert cal.bias_m != state[1]
    cal.restore(state)
    assert cal.snapshot() == state
