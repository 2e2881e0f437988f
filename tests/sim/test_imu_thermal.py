"""sim.imu_thermal: die temperature (air, lag, warm-up, heater), the thermal bias curve with its
knee and hysteresis, per-unit draws, and the sensor suite with a thermal IMU."""

from __future__ import annotations

import math

import numpy as np
import pytest
from pydantic import ValidationError

from sim import presets
from sim.atmosphere import temperature_from_altitude
from sim.imu_thermal import (
    KELVIN_AT_0_C,
    THERMAL_STEP_S,
    ImuThermalConfig,
    ImuThermalModel,
    ImuThermalPart,
    ThermalUnit,
    static_curve,
)
from sim.samples import BaroSample, GnssFix, ImuSample
from sim.sensors import SensorSuite
from tests.sim.test_sensors import stationary_truth

S = 1_000_000  # µs per s


def _part(**update: float) -> ImuThermalPart:
    part = presets.imu_thermal_preset("bmi088")
    assert part is not None
    return part.model_copy(update=update)


def _model(seed: int = 3, sea_level_dt_k: float = 0.0, **config: object) -> ImuThermalModel:
    part = config.pop("part", _part())
    cfg = ImuThermalConfig(part=part, preset="bmi088", **config)  # type: ignore[arg-type]
    return ImuThermalModel(cfg, np.random.default_rng(seed), sea_level_dt_k)


def _air_k(alt_m: float, day_dt_k: float = 0.0) -> float:
    h_gp = 6356766.0 * alt_m / (6356766.0 + alt_m)
    return float(temperature_from_altitude(h_gp, day_dt_k))


def test_die_follows_a_step_in_the_air_with_the_case_time_constant() -> None:
    # GIVEN an IMU without self-heating in equilibrium at 0 m, WHEN the aircraft is suddenly at
    # 3000 m (19.5 K colder air), THEN the die closes 1 - 1/e of the gap after one time constant
    tau = 600.0
    m = _model(part=_part(self_heating_k=0.0, ambient_time_constant_s=tau))
    m.step(0, 0.0)
    t_start = m.die_temperature_k
    assert t_start == pytest.approx(_air_k(0.0))
    m.step(round(tau * S), 3000.0)
    air = _air_k(3000.0)
    assert m.air_temperature_k == pytest.approx(air)
    # the first thermal step still saw the old air; the rest of the interval the new one
    expected = air + (t_start - air) * math.exp(-(tau - THERMAL_STEP_S) / tau) * math.exp(
        -THERMAL_STEP_S / tau) + 0.0
    assert m.die_temperature_k == pytest.approx(expected, abs=0.02)
    assert m.die_temperature_k - air == pytest.approx((t_start - air) / math.e, rel=2e-3)


def test_warm_up_after_power_on_rises_by_the_self_heating_with_its_time_constant() -> None:
    m = _model(part=_part(self_heating_k=10.0, warmup_time_constant_s=240.0))
    m.step(0, 1000.0)
    air = _air_k(1000.0)
    assert m.die_temperature_k == pytest.approx(air)  # powered on at the start: cold die
    m.step(240 * S, 1000.0)
    assert m.die_temperature_k - air == pytest.approx(10.0 * (1.0 - 1.0 / math.e), rel=1e-6)
    m.step(3600 * S, 1000.0)
    assert m.die_temperature_k - air == pytest.approx(10.0, abs=1e-4)
    # powered on 240 s before the start: already part-way up
    early = _model(part=_part(self_heating_k=10.0, warmup_time_constant_s=240.0),
                   power_on_s=-240.0)
    early.step(0, 1000.0)
    assert early.die_temperature_k - air == pytest.approx(10.0 * (1.0 - 1.0 / math.e))


def test_cold_soak_hot_day_and_heater_failure() -> None:
    air = _air_k(1000.0, 15.0) + 10.0
    hot = _model(sea_level_dt_k=15.0, ambient_offset_k=10.0)
    hot.step(0, 1000.0)
    assert hot.air_temperature_k == pytest.approx(air)
    cold = _model(start_temperature_c=-20.0, part=_part(self_heating_k=0.0))
    cold.step(0, 1000.0)
    assert cold.case_temperature_k == pytest.approx(-20.0 + KELVIN_AT_0_C)
    cold.step(600 * S, 1000.0)
    assert -20.0 + KELVIN_AT_0_C < cold.die_temperature_k < _air_k(1000.0)
    # a heater holds the case at its set point until it fails, then the case cools to the air
    heated = _model(part=_part(self_heating_k=0.0), heater_setpoint_c=55.0, heater_fails_at_s=300.0)
    heated.step(0, 1000.0)
    assert heated.case_temperature_k == pytest.approx(55.0 + KELVIN_AT_0_C)
    heated.step(299 * S, 1000.0)
    assert heated.case_temperature_k == pytest.approx(55.0 + KELVIN_AT_0_C)
    heated.step(300 * S + 900 * S, 1000.0)  # one case time constant after the failure
    gap0 = 55.0 + KELVIN_AT_0_C - _air_k(1000.0)
    assert heated.case_temperature_k - _air_k(1000.0) == pytest.approx(gap0 / math.e, rel=2e-3)


def test_heating_and_cooling_branches_differ_at_the_same_temperature() -> None:
    # GIVEN a unit whose bias has hysteresis and no rate term, WHEN its die is swept up and back
    # down slowly (climb, descend), THEN at one temperature the two branches differ by 2·eta
    part = _part(self_heating_k=0.0, ambient_time_constant_s=20.0,
                 gyro_rate_dps_per_k_per_min=0.0, accel_rate_mg_per_k_per_min=0.0,
                 gyro_hysteresis_dps=0.05)
    m = _model(seed=11, part=part)
    ref_k = part.reference_temperature_c + KELVIN_AT_0_C
    up: list[tuple[float, np.ndarray]] = []
    down: list[tuple[float, np.ndarray]] = []
    t_us = 0
    for alt in [*np.linspace(4000.0, 0.0, 401), *np.linspace(0.0, 4000.0, 401)]:
        for _ in range(20):  # 2 s per 10 m: the die keeps up with the air
            m.step(t_us, float(alt))
            t_us += round(THERMAL_STEP_S * S)
        branch = up if m.rate_k_per_s > 0 else down
        branch.append((m.die_temperature_k, np.array(m.bias)))
    t_mid = 0.5 * (up[0][0] + up[-1][0])
    b_up = min(up, key=lambda r: abs(r[0] - t_mid))
    b_dn = min(down, key=lambda r: abs(r[0] - t_mid))
    assert abs(b_up[0] - b_dn[0]) < 0.1
    gap = b_up[1] - b_dn[1]
    # the static curve is the same on both branches; what differs is 2·eta
    static_gap = static_curve(m.unit, b_up[0], ref_k) - static_curve(m.unit, b_dn[0], ref_k)
    np.testing.assert_allclose(gap - static_gap, 2.0 * m.unit.hysteresis, rtol=1e-6, atol=1e-12)
    assert np.all(np.abs(m.unit.hysteresis[3:]) > 0.0)


def test_rate_term_acts_only_while_the_temperature_changes() -> None:
    part = _part(gyro_hysteresis_dps=0.0, accel_hysteresis_mg=0.0)
    m = _model(seed=5, part=part)
    m.step(0, 1000.0)
    m.step(120 * S, 1000.0)  # warming
    ref_k = part.reference_temperature_c + KELVIN_AT_0_C
    warming = np.array(m.bias) - static_curve(m.unit, m.die_temperature_k, ref_k)
    np.testing.assert_allclose(warming, m.unit.rate * m.rate_k_per_s, rtol=1e-9, atol=1e-15)
    assert m.rate_k_per_s > 0.01
    m.step(20_000 * S, 1000.0)  # settled
    settled = np.array(m.bias) - static_curve(m.unit, m.die_temperature_k, ref_k)
    assert np.max(np.abs(settled)) < 1e-9


def test_curve_has_a_knee_and_is_zero_at_the_calibration_temperature() -> None:
    m = _model(seed=2)
    ref_k = 25.0 + KELVIN_AT_0_C
    np.testing.assert_allclose(static_curve(m.unit, ref_k, ref_k), 0.0, atol=1e-18)
    t = np.linspace(-40.0, 85.0, 251) + KELVIN_AT_0_C
    g = static_curve(m.unit, t, ref_k)
    slope = np.gradient(g, t, axis=0)
    # the slope changes by about s1 across the knee (tanh), unlike a straight line
    np.testing.assert_allclose(slope.max(axis=0) - slope.min(axis=0),
                               np.abs(m.unit.slope_knee), rtol=0.1)


def test_units_are_drawn_per_seed_deterministically() -> None:
    part = _part()
    a = ThermalUnit.draw(part, np.random.default_rng(7))
    b = ThermalUnit.draw(part, np.random.default_rng(7))
    c = ThermalUnit.draw(part, np.random.default_rng(8))
    for name in ("slope_far", "slope_knee", "knee_k", "width_k", "hysteresis", "rate"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
        assert not np.array_equal(getattr(a, name), getattr(c, name))
    # the slopes' spread follows the part's figure (1σ of the far slope = 0.85 × tempco)
    units = [ThermalUnit.draw(part, np.random.default_rng(s)) for s in range(400)]
    far = np.array([u.slope_far[3:] for u in units]).ravel()
    assert np.std(far) == pytest.approx(0.85 * math.radians(0.015), rel=0.1)


def test_reported_temperature_is_quantised_and_updated_as_the_part_does() -> None:
    m = _model(seed=4)
    reports: list[tuple[int, float]] = []
    for k in range(0, 200 * 30):  # 30 s at 200 Hz
        t = k * 5000
        m.step(t, 1000.0)
        reports.append((t, m.reported_temperature_k))
    values = np.array([r[1] for r in reports]) - KELVIN_AT_0_C
    n = (values - 23.0) / 0.125
    np.testing.assert_allclose(n, np.round(n), atol=1e-9)
    changes = [reports[i][0] for i in range(1, len(reports)) if reports[i][1] != reports[i - 1][1]]
    assert changes and all((c % 1_280_000) == 0 for c in changes)
    assert abs(values[-1] - (m.die_temperature_k - KELVIN_AT_0_C)) < 0.0625 + 4.0  # + offset


def test_config_rejects_bad_values() -> None:
    with pytest.raises(ValidationError, match="power_on_s"):
        ImuThermalConfig(part=_part(), power_on_s=10.0)
    with pytest.raises(ValidationError, match="gyro_tempco_dps_per_k"):
        _part(gyro_tempco_dps_per_k=-1.0)
    with pytest.raises(ValueError, match="valid choices: adis1646x, bmi088"):
        presets.imu_thermal_preset("bmi089")
    assert presets.imu_thermal_preset("off") is None


def _suite_samples(thermal: ImuThermalConfig | None, seconds: float = 2.0) -> list[object]:
    cfg = presets.suite_config("consumer-mems").model_copy(update={"imu_thermal": thermal})
    suite = SensorSuite(cfg, seed=9, sim_rate_hz=200.0)
    out: list[object] = []
    for k in range(round(200 * seconds)):
        out.extend(suite.step(stationary_truth(k)))
    return out


def test_a_thermal_imu_leaves_the_other_sensors_streams_unchanged() -> None:
    thermal = ImuThermalConfig(part=_part(), preset="bmi088", start_temperature_c=-20.0)
    plain = _suite_samples(None)
    hot = _suite_samples(thermal)
    assert len(plain) == len(hot)
    for a, b in zip(plain, hot, strict=True):
        assert type(a) is type(b)
        if isinstance(a, GnssFix | BaroSample):
            assert repr(a) == repr(b)
    imu_a = [s for s in plain if isinstance(s, ImuSample)]
    imu_b = [s for s in hot if isinstance(s, ImuSample)]
    # the IMU moved by the thermal bias (far from the 25 °C calibration at -20 °C)
    diff = np.mean([b.angular_rate_b_rps - a.angular_rate_b_rps
                    for a, b in zip(imu_a, imu_b, strict=True)], axis=0)
    assert np.max(np.abs(diff)) > math.radians(0.05)
    assert imu_b[0].temperature_k == pytest.approx(-20.0 + KELVIN_AT_0_C, abs=4.0)
    assert imu_a[0].temperature_k == stationary_truth(0).temperature_k


def test_default_suite_stream_is_the_one_before_the_thermal_generator_existed() -> None:
    # spawn(6) gives the same first five children as spawn(5): the IMU stream of a suite
    # without a thermal model is the reference IMU model's on the first child
    from sim.imu import ImuModel
    cfg = presets.suite_config("consumer-mems")
    suite = SensorSuite(cfg, seed=9, sim_rate_hz=200.0)
    ref = ImuModel(cfg.imu, np.random.default_rng(np.random.SeedSequence(9).spawn(5)[0]), 200.0)
    np.testing.assert_array_equal(suite.imu.turn_on_bias, ref.turn_on_bias)
    np.testing.assert_array_equal(suite.imu.transfer, ref.transfer)
