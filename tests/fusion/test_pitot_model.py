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
    changes), TAS 25-35 m/s, small sideslip; the target noisy by ``noise_mps``."""
    for k in range(600):
        alpha = math.radians(4.0 + 4.0 * math.sin(2.0 * math.pi * k / 97.0))
        tas = 30.0 - 5.0 * math.sin(2.0 * math.pi * k / 97.0) + rng.normal(0.0, 0.3)
        beta = math.radians(rng.normal(0.0, 1.0))
        y = (_error_mps(alpha, tas) if error else 0.0) + rng.normal(0.0, noise_mps)
        model.observe(k * 1_000_000, PitotInputs(alpha, beta, tas), y)


def test_learns_a_position_error_and_corrects_only_inside_its_trained_range() -> None:
    # GIVEN ten minutes of a position error (up to -0.4 m/s) under 0.05 m/s of noise
    model = OnlinePitotErrorModel(GmdhRegressor, describe=lambda m: m.polynomial(4))  # type: ignore[attr-defined]
    _fly(model, np.random.default_rng(1), 0.05)
    st = model.status
    assert st.state == "trained" and st.refits >= 1 and st.polynomial
    assert model.skilled
    # WHEN it corrects inside the angles and speeds flown
    errs = []
    for a_deg in np.linspace(0.5, 7.5, 8):
        a = math.radians(float(a_deg))
        tas = 30.0 - 5.0 * (a_deg - 4.0) / 4.0
        errs.append(model.correction(PitotInputs(a, 0.0, tas)) - _error_mps(a, tas))
        assert model.active
    # THEN the correction is the error within 0.05 m/s
    assert np.max(np.abs(errs)) < 0.05, errs
    # AND outside the trained angle of attack it corrects nothing, and says so
    assert model.correction(PitotInputs(math.radians(14.0), 0.0, 30.0)) == 0.0
    assert not model.active and model.out_of_range == 1
    assert model.correction(PitotInputs(math.nan, 0.0, 30.0)) == 0.0


def test_without_a_position_error_the_skill_gate_stays_shut() -> None:
    # GIVEN the same flight with a pitot that has no position error (the target is noise)
    model = OnlinePitotErrorModel(GmdhRegressor)
    _fly(model, np.random.default_rng(2), 0.3, error=False)
    # THEN it fitted, found no skill over a constant, and corrects nothing
    assert model.status.state == "trained" and not model.skilled
    assert model.correction(PitotInputs(math.radians(4.0), 0.0, 30.0)) == 0.0
    assert model.corrections == 0


def test_status_before_any_data_and_the_bridge_hands_the_model_over() -> None:
    bridge = make_bridge("gmdh-pitot")
    assert bridge.pitot_model is not None and bridge.airspeed_model is None
    st = bridge.status
    assert (st.method, st.state, st.samples, st.refits, st.active) == (
        "gmdh-pitot", "no inputs", 0, 0, False)
    assert math.isnan(st.model_rmse) and st.model == ""
    assert make_bridge("none").pitot_model is None
