"""The thermal strategies: temperature screening, the calibration polynomial, the blind
filter's noise, the temperature-coefficient states and the learned bias model."""

from __future__ import annotations

import math

import numpy as np
import pytest

from fusion.config import FilterConfig
from fusion.estimate import HealthCounters
from fusion.filter import NavFilter
from fusion.state_layout import layout_for, with_thermal
from fusion.thermal.bias_model import ThermalBiasModel
from fusion.thermal.screen import TemperatureScreen
from fusion.thermal.tuning import ThermalCalibration, ThermalPolynomial, ThermalTuning
from sim.samples import ImuSample
from tests.helpers.nav_synth import Flight, SensorErrors, make_scenario

_Z = (0.0, 0.0, 0.0)


def test_screen_rejects_and_counts_bad_temperatures() -> None:
    # GIVEN a screen with a 1 K/s slew limit and a 1.28 s update period
    c = HealthCounters()
    scr = TemperatureScreen(ThermalTuning(stuck_updates=3, stuck_min_s=1.0), c)
    # WHEN it reads a good value, a NaN, an out-of-range value, a jump and a stuck stream
    assert scr.add(0, 300.0)
    assert not scr.add(10_000, math.nan)
    assert not scr.add(20_000, 400.0)
    assert not scr.add(1_000_000, 320.0)  # 20 K in 1 s
    assert scr.add(2_000_000, 300.5)
    for k in range(1, 10):  # the same reading for 9 s > 3 x 1.28 s
        scr.add(2_000_000 + k * 1_000_000, 300.5)
    # THEN each is counted once and the last good temperature holds
    assert (c.temperature_nan, c.temperature_out_of_range, c.temperature_jump,
            c.temperature_stuck) == (1, 1, 1, 1)  # fmt: skip
    assert not scr.good and scr.temperature_k == 300.5
    assert scr.add(20_000_000, 301.0) and scr.good


def _cal(source: str, cal_temp: float | None) -> ThermalCalibration:
    g = ((1e-3, 0.0, 0.0), (1e-4, 2e-4, 0.0), (1e-6, 0.0, 0.0), (1e-8, 0.0, 0.0))
    a = ((0.01, 0.0, 0.0), (1e-3, 0.0, 0.0), _Z, _Z)
    rng = {"t_ref_k": 298.15, "t_min_k": 283.15, "t_max_k": 333.15, "cal_temp_k": cal_temp}
    return ThermalCalibration(source=source,  # type: ignore[arg-type]
                              gyro=ThermalPolynomial(coeffs=g, **rng),
                              accel=ThermalPolynomial(coeffs=a, **rng))  # fmt: skip


def test_calibration_polynomial_px4_absolute_ardupilot_relative_and_clamped() -> None:
    px4 = _cal("px4", None)
    g, a = px4.offsets(308.15)  # x = 10 K
    assert g[0] == pytest.approx(1e-3 + 1e-3 + 1e-4 + 1e-5)
    assert g[1] == pytest.approx(2e-3) and a[0] == pytest.approx(0.02)
    # clamped to t_max: 60 degC reads as 60, 80 degC too
    assert px4.offsets(353.15) == px4.offsets(333.15)
    ap = _cal("ardupilot", 298.15)
    g0, a0 = ap.offsets(298.15)
    assert g0 == (0.0, 0.0, 0.0) and a0 == (0.0, 0.0, 0.0)
    assert ap.offsets(308.15)[0][0] == pytest.approx(1e-3 + 1e-4 + 1e-5)


def test_blind_noise_admits_the_thermal_drift() -> None:
    base = FilterConfig().process_noise()
    th = ThermalTuning(mode="blind")
    blind = FilterConfig(thermal=th).process_noise()
    qg, _ = th.thermal_rate_density()
    # the random walk's density grew by exactly (tempco rate)^2 horizon
    dq = 2 * (blind.gyro_bias_sigma**2 - base.gyro_bias_sigma**2) / base.gyro_bias_tau_s
    assert dq == pytest.approx(qg)
    assert math.sqrt(qg * th.horizon_s) == pytest.approx(
        th.gyro_tempco_rps_per_k * th.rate_k_per_s * th.horizon_s)
    # off: the datasheet noise, nothing else, and no thermal machinery in the filter
    assert FilterConfig(thermal=ThermalTuning(mode="off")).process_noise() == base
    assert NavFilter()._thermal is None


def test_cal_mode_needs_a_calibration() -> None:
    with pytest.raises(ValueError, match="calibration"):
        ThermalTuning(mode="cal")


def test_thermal_layout_appends_six_states() -> None:
    lay = with_thermal(layout_for("ins16"))
    assert lay.n == 22 and lay.KA == 16 and lay.KG == 19 and lay.has_thermal
    assert layout_for("ins35+gnss+air+therm").n == 49
    nav = NavFilter(FilterConfig(thermal=ThermalTuning(mode="states")))
    assert nav.layout.name == "ins16+therm"


def _thermal_scenario(k_gz: float, seconds: float) -> tuple[list[object], float]:
    """A flight with a gyro-z bias linear in a warming die temperature; its samples and the
    temperature at the end."""
    rng = np.random.default_rng(3)
    fl = Flight(duration_s=seconds, turns=[(60.0, 90.0, 0.05), (150.0, 180.0, -0.05)])
    sc = make_scenario(fl, rng, SensorErrors.from_config(FilterConfig()), imu_rate_hz=50.0,
                       mag_rate_hz=None)
    out: list[object] = []
    t_end = 0.0
    for s in sc.samples:
        if isinstance(s, ImuSample):
            ts = s.time_us * 1e-6
            temp = 293.15 + 15.0 * (1.0 - math.exp(-ts / 200.0))
            q = round(temp / 0.125) * 0.125  # quantised as the part does
            w = s.angular_rate_b_rps + np.array([0.0, 0.0, k_gz * (temp - 293.15)])
            s = ImuSample(s.time_us, s.dt_s, s.specific_force_b_mps2, w, q)
            t_end = temp
        out.append(s)
    return out, t_end


def test_tempco_states_learn_the_coefficient_of_a_warming_gyro() -> None:
    # GIVEN a gyro z bias that moves 0.015 deg/s per K while the die warms by 15 K
    k = math.radians(0.015)
    samples, _ = _thermal_scenario(k, 240.0)
    nav = NavFilter(FilterConfig(thermal=ThermalTuning(mode="states")))
    # WHEN the filter with temperature-coefficient states runs with GNSS
    for s in samples:
        nav.step(s)
    # THEN it learned the coefficient (to a third) and counted no bad temperature
    th = nav._thermal
    assert th is not None
    assert th.tempco_gyro[2] == pytest.approx(k, rel=0.35)
    assert nav.health.temperature_jump == 0 and nav.health.temperature_nan == 0


def test_learned_bias_model_predicts_inside_its_range_only() -> None:
    model = ThermalBiasModel(refit_period_s=5.0, min_samples=20, horizon_s=30.0, margin_k=1.0)
    for i in range(400):
        t_us = i * 1_280_000
        temp = 293.15 + 10.0 * (1.0 - math.exp(-i / 150.0))
        rate = 10.0 / 150.0 / 1.28 * math.exp(-i / 150.0)
        b = 1e-4 * (temp - 293.15) + 2e-6 * (temp - 293.15) ** 2
        model.add(t_us, temp, rate, (0.0, 0.0, 0.0, 0.0, 0.0, b))
    assert model.refits > 0
    st = model.status
    assert st.state == "trained" and "gz:" in st.polynomial
    # the gate has seen the gyro z model win its held-out trials
    assert st.on_axes[5]
    p = model.predict(298.15, 5.0 / 150.0 / 1.28)  # on the warm-up curve
    assert p is not None and p[5] == pytest.approx(1e-4 * 5 + 2e-6 * 25, rel=0.2)
    assert model.predict(st.t_max_k + 2.0, 0.0) is None


def test_bad_temperatures_in_the_filter_are_counted_and_the_tempco_feed_holds() -> None:
    # GIVEN the coefficient states with a known coefficient, and a stream whose temperature
    # turns NaN, jumps and leaves the range
    cfg = FilterConfig(thermal=ThermalTuning(mode="states"))
    # no rest detection: nothing but the temperature moves the bias here
    cfg = cfg.model_copy(update={"zero_motion": cfg.zero_motion.model_copy(
        update={"enabled": False})})
    nav = NavFilter(cfg)
    th = nav._thermal
    assert th is not None
    th.tempco_gyro[2] = 1e-4
    nav.initialize(1_000_000, 0.8, 0.15, 500.0, np.zeros(3), np.array([1.0, 0.0, 0.0, 0.0]))
    th.start()
    f = np.array([0.0, 0.0, -9.80665])
    temps = [300.0, 300.2, math.nan, math.nan, 330.0, 500.0, 300.4]
    biases = []
    t_us = 1_000_000
    for temp in temps:  # each reading held for 1.3 s of 100 Hz samples, as a part updates it
        for _ in range(130):
            t_us += 10_000
            nav.step(ImuSample(t_us, 0.01, f, np.zeros(3), temp))
        nom = nav.nominal_state
        assert nom is not None
        biases.append(nom.gyro_bias_b_rps[2])
    h = nav.health
    # THEN each bad reading is counted once, the bias moved only with the good ones
    assert (h.temperature_nan, h.temperature_jump, h.temperature_out_of_range) == (1, 1, 1)
    assert biases[1] == pytest.approx(1e-4 * 0.2)
    assert biases[2] == biases[3] == biases[4] == biases[5] == biases[1]
    assert biases[6] == pytest.approx(1e-4 * 0.4)


def test_cal_mode_removes_the_polynomial_before_the_filter() -> None:
    from fusion.thermal.link import ThermalLink

    cal = _cal("px4", None)
    tuning = ThermalTuning(mode="cal", calibration=cal)
    link = ThermalLink(tuning, layout_for("ins16"), HealthCounters())
    s = ImuSample(10_000, 0.01, np.array([0.0, 0.0, -9.8]), np.array([0.01, 0.0, 0.0]), 308.15)
    out = link.pre(s)
    g, a = cal.offsets(308.15)
    np.testing.assert_allclose(out.angular_rate_b_rps, [0.01 - g[0], -g[1], -g[2]])
    np.testing.assert_allclose(out.specific_force_b_mps2, [-a[0], -a[1], -9.8 - a[2]])
    # a NaN temperature: the correction of the last good one holds
    out2 = link.pre(ImuSample(20_000, 0.01, s.specific_force_b_mps2, s.angular_rate_b_rps,
                              math.nan))
    np.testing.assert_allclose(out2.angular_rate_b_rps, out.angular_rate_b_rps)


def test_learned_bias_model_window_spans_minutes_when_the_temperature_updates_every_sample(
) -> None:
    # GIVEN a part whose temperature changes with every 100 Hz sample (noise in the last bit)
    model = ThermalBiasModel(refit_period_s=1e9)  # no refit: only the window is under test
    rng = np.random.default_rng(3)
    for i in range(600 * 100):  # WHEN 10 min of samples with GNSS good
        t_us = i * 10_000
        temp = 293.15 + 8.0 * (1.0 - math.exp(-i / 24_000.0)) + 0.003 * rng.standard_normal()
        model.add(t_us, temp, 0.0, (0.0, 0.0, 0.0, 0.0, 0.0, 1e-4 * (temp - 293.15)))
    # THEN the training window covers at least 9 of those minutes, not the last seconds
    assert model.window_span_s >= 540.0


def test_the_learner_keeps_pairing_while_a_coarse_reading_holds() -> None:
    from fusion.thermal.link import ThermalLink

    # GIVEN a 0.1 K part whose reading changes only every ~20 s, and the learned model
    model = ThermalBiasModel()
    link = ThermalLink(ThermalTuning(mode="blind"), layout_for("ins16"), HealthCounters(),
                       model)  # fmt: skip
    link.start()
    f = np.array([0.0, 0.0, -9.8])
    # WHEN 5 min of 100 Hz samples go through with GNSS good
    for i in range(300 * 100):
        t_us = i * 10_000
        temp = 300.0 + 0.1 * (i // 2000)
        link.pre(ImuSample(t_us, 0.01, f, np.zeros(3), temp))
        link.bias_step(True, t_us, (_Z, _Z))
    # THEN it stored a pair about every second, not one per changed reading (15)
    assert model.status.samples >= 290


def test_a_coarse_reading_that_holds_on_a_per_sample_part_is_not_stuck() -> None:
    # GIVEN a 0.1 K sensor updated with every 100 Hz sample, its die warming slowly
    c = HealthCounters()
    scr = TemperatureScreen(ThermalTuning(quantum_k=0.1, update_period_s=0.01), c)
    # WHEN each reading holds for 10 s before the last bit moves
    for i in range(60 * 100):
        scr.add(i * 10_000, 300.0 + 0.1 * (i // 1000))
    # THEN nothing is counted as stuck and the latest reading stands
    assert c.temperature_stuck == 0 and scr.good and scr.temperature_k == pytest.approx(300.5)


def test_gate_trials_score_nothing_outside_the_trained_range() -> None:
    # GIVEN a steady warm-up (0.02 K/s): every held-out trial ends 2.4 K above the range its
    # model was trained on, where the outage prediction says nothing (margin 1 K)
    model = ThermalBiasModel(refit_period_s=30.0, min_samples=40, horizon_s=120.0, margin_k=1.0)
    for i in range(400):
        temp = 293.15 + 0.02 * i
        b = 1e-4 * (temp - 293.15)
        model.add(i * 1_000_000, temp, 0.02, (0.0, 0.0, 0.0, 0.0, 0.0, b))
    # THEN the model was fitted, but no trial was scored with an extrapolated prediction,
    # so the gate holds every axis off (1.00x of the filter underneath)
    assert model.refits > 0
    assert all(len(s) == 0 for s in model.gate.scores)
    assert not any(model.status.on_axes)
