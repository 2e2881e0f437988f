"""The learned pitot position error (``gmdh-pitot``): airspeed error against the flow angles."""

from __future__ import annotations

import math

import numpy as np

from fusion.bridging.registry import make_bridge
from fusion.gmdh import GmdhRegressor
from fusion.pitot_model import OnlinePitotErrorModel, PitotInputs

C_S_PER_RAD = 0.3  # sim.pitot's -pe presets: static error, fraction of q_c per rad


def _error_mps(alpha_rad: float, tas_mps: float) -> float:
    """TAS error of a static-source error ``c_s alpha`` on the impact pressure, m/s."""
    return tas_mps * (math.sqrt(1.0 - C_S_PER_RAD * alpha_rad) - 1.0)


def _fly(model: OnlinePitotErrorModel, rng: np.random.Generator, noise_mps: float,
         error: bool = True) -> None:  # fmt: skip
    """Ten minutes at 1 Hz: the angle of attack swept 0-8 deg (climbs, descents, speed
    changes), TAS 25-35 m/s, small sideslip; the target ``TAS - |a|`` noisy by ``noise_mps``,
    the filter's scale state at the mean error (its prediction ``k |a|``)."""
    k_scale = -0.0105  # the scale state at the mean error: -0.15 per rad at 4 deg
    for k in range(600):
        alpha = math.radians(4.0 + 4.0 * math.sin(2.0 * math.pi * k / 97.0))
        tas = 30.0 - 5.0 * math.sin(2.0 * math.pi * k / 97.0) + rng.normal(0.0, 0.3)
        beta = math.radians(rng.normal(0.0, 1.0))
        y = (_error_mps(alpha, tas) if error else 0.0) + rng.normal(0.0, noise_mps)
        model.observe(k * 1_000_000, PitotInputs(alpha, beta, tas), y,
                      (k_scale if error else 0.0) * tas)


def test_learns_a_position_error_and_corrects_only_inside_its_trained_range() -> None:
    # GIVEN ten minutes of a position error (up to -0.4 m/s) under 0.05 m/s of noise
    model = OnlinePitotErrorModel(GmdhRegressor, describe=lambda m: m.polynomial(4))  # type: ignore[attr-defined]
    _fly(model, np.random.default_rng(1), 0.05)
    st = model.status
    assert st.state == "trained" and st.refits >= 1 and st.polynomial
    assert model.skilled
    # WHEN it predicts the error inside the angles and speeds flown
    errs = []
    for a_deg in np.linspace(0.5, 7.5, 8):
        a = math.radians(float(a_deg))
        tas = 30.0 - 5.0 * (a_deg - 4.0) / 4.0
        e = model.correction_mps(PitotInputs(a, 0.0, tas))
        assert e is not None and model.active
        errs.append(e - _error_mps(a, tas))
    # THEN it is the error's change within 0.05 m/s (the scale state keeps the level; alone it
    # misses the change by up to 0.3 m/s)
    assert np.ptp(errs) < 0.05, errs
    # AND outside the trained angle of attack it predicts nothing (the filter keeps its scale
    # state), and says so
    assert model.correction_mps(PitotInputs(math.radians(14.0), 0.0, 30.0)) is None
    assert not model.active and model.out_of_range == 1
    assert model.correction_mps(PitotInputs(math.nan, 0.0, 30.0)) is None


def test_without_a_position_error_the_skill_gate_stays_shut() -> None:
    # GIVEN the same flight with a pitot that has no position error (the target is noise, the
    # scale state at zero)
    model = OnlinePitotErrorModel(GmdhRegressor)
    _fly(model, np.random.default_rng(2), 0.3, error=False)
    # THEN it fitted, found no skill over the filter's scale state, and corrects nothing
    assert model.status.state == "trained" and not model.skilled
    assert model.correction_mps(PitotInputs(math.radians(4.0), 0.0, 30.0)) is None
    assert model.corrections == 0
    # AND non-finite pairs are not learned
    n = model.status.samples
    model.observe(601_000_000, PitotInputs(math.nan, 0.0, 30.0), 0.0, 0.0)
    model.observe(602_000_000, PitotInputs(0.0, 0.0, 30.0), math.nan, 0.0)
    assert model.status.samples == n


def test_status_before_any_data_and_the_bridge_hands_the_model_over() -> None:
    bridge = make_bridge("gmdh-pitot")
    assert bridge.pitot_model is not None and bridge.airspeed_model is None
    st = bridge.status
    assert (st.method, st.state, st.samples, st.refits, st.active) == (
        "gmdh-pitot", "no inputs", 0, 0, False)
    assert math.isnan(st.model_rmse) and st.model == ""
    assert make_bridge("none").pitot_model is None


def test_in_the_filter_it_learns_with_gnss_and_without_a_position_error_does_no_harm() -> None:
    # GIVEN a short version of the air-data tests' flight (turns, a climb and a descent, an
    # airspeed wave), a pitot with white noise and no position error, GNSS lost for 70 s
    from fusion.filter import NavFilter
    from tests.fusion.test_airspeed import CFG, ERRORS, TAS_NOISE_MPS, WIND, horizontal_error_m
    from tests.helpers.nav_synth import Flight, airspeed_samples, make_scenario, merge, prepare

    turns = [(20.0, 35.0, 0.2), (60.0, 75.0, -0.2), (110.0, 125.0, 0.2), (160.0, 175.0, 0.2)]
    prep = prepare(Flight(duration_s=200.0, speed_mps=30.0, wind_ne_mps=WIND, turns=turns,
                          climbs=[(80.0, 95.0, 3.0), (140.0, 155.0, -3.0)],
                          speed_wave_mps=2.0))  # fmt: skip
    rng = np.random.default_rng(45)
    sc = make_scenario(prep, rng, ERRORS, gnss_outages=[(130.0, 200.0)])
    samples = merge(sc.samples, airspeed_samples(sc, WIND, rng, tas_noise_mps=TAS_NOISE_MPS))
    errs = {}
    for name in ("none", "gmdh-pitot"):
        nav = NavFilter(CFG, bridge=make_bridge(name))
        est = [e for s in samples for e in nav.step(s)]  # type: ignore[arg-type]
        errs[name] = horizontal_error_m(sc, est[-1])
        if name == "gmdh-pitot":
            # THEN it trained on the GNSS part of the flight and reports its polynomial
            st = nav.bridge_status
            assert st.state == "trained" and st.refits >= 1 and st.samples >= 60 and st.model
    # AND without a position error the outage ends within 5 % of the plain air-data filter
    assert errs["gmdh-pitot"] <= 1.05 * errs["none"], errs
