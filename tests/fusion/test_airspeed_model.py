"""fusion.airspeed_model: the online-identified airspeed model (gmdh-airspeed's learner)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from fusion.airspeed_model import AirspeedInputs, OnlineAirspeedModel
from fusion.gmdh import GmdhRegressor

NOISE_MPS = 0.3


def _aircraft(n: int, seed: int) -> tuple[list[AirspeedInputs], np.ndarray, np.ndarray]:
    """A steady-flight point mass: lift n·W = ½ρV²S·(CL0 + k·elevator) sets the airspeed, the
    propeller speed follows throttle and airspeed. Controls wander smoothly (2 Hz samples)."""
    rng = np.random.default_rng(seed)

    def wander(scale: float, tau: float) -> np.ndarray:
        a = math.exp(-0.5 / tau)
        x = np.zeros(n)
        for i in range(1, n):
            x[i] = a * x[i - 1] + math.sqrt(1 - a * a) * rng.normal(0.0, scale)
        return x

    elevator = 0.1 + wander(0.08, 20.0)
    throttle = np.clip(0.6 + wander(0.15, 30.0), 0.0, 1.0)
    density = 1.11 + wander(0.03, 60.0)
    load = 1.0 + np.abs(wander(0.05, 10.0))
    w_over_s = 690.0  # N/m^2, a light single (C172: 10.2 kN on 16.2 m^2)
    cl = 0.35 + 0.9 * elevator
    tas = np.sqrt(2.0 * load * w_over_s / (density * cl))
    rpm = 1.2 + 1.1 * throttle + 0.012 * tas
    inputs = [
        AirspeedInputs(
            throttle=float(throttle[i]), elevator=float(elevator[i]), aileron=0.0,
            rpm_krpm=float(rpm[i]), density_kgpm3=float(density[i]), roll_rad=0.0,
            pitch_rad=0.02, fx_b_mps2=0.0, fz_b_mps2=-9.81 * float(load[i]),
            climb_rate_mps=0.0,
        )
        for i in range(n)
    ]
    measured = tas + rng.normal(0.0, NOISE_MPS, n)
    return inputs, tas, measured


def _model() -> OnlineAirspeedModel:
    return OnlineAirspeedModel(GmdhRegressor, describe=lambda m: m.polynomial(4))


def test_learns_airspeed_from_controls_and_predicts_the_future_with_an_honest_sigma() -> None:
    inputs, tas, measured = _aircraft(1200, seed=3)  # 10 min at 2 Hz
    model = _model()
    for i in range(600):  # learn on the first 5 min
        model.observe(i * 500_000, inputs[i], float(measured[i]))
    assert model.status.state == "trained"
    assert model.status.polynomial.startswith("# GMDH")
    preds = [model.predict(x) for x in inputs[600:]]
    assert all(p is not None for p in preds)
    est = np.array([p.tas_mps for p in preds if p is not None])
    sig = np.array([p.sigma_mps for p in preds if p is not None])
    err = est - tas[600:]
    rmse = float(np.sqrt(np.mean(err**2)))
    # the airspeed wanders by several m/s; "no model" (its mean) errs by its std: the learned
    # model must explain most of that variance on data it never saw
    assert rmse < 0.35 * float(np.std(tas[600:]))
    # the sigma is the held-out error (inflated x1.5, floored at 0.5 m/s): same order as the
    # error actually made on the future, neither hiding it nor swamping it
    assert 0.5 * rmse < float(np.median(sig)) < 6.0 * max(rmse, NOISE_MPS)


def test_no_inputs_reports_it_and_predicts_nothing() -> None:
    model = _model()
    assert model.status.state == "no inputs"
    for i in range(300):
        model.observe(i * 500_000, None, 50.0)
    assert model.status.state == "no inputs"
    assert model.predict(None) is None


def test_non_finite_pairs_are_not_learned_and_non_finite_inputs_not_predicted() -> None:
    inputs, _tas, measured = _aircraft(400, seed=4)
    model = _model()
    bad = AirspeedInputs(*([math.nan] + [0.0] * 9))
    for i in range(400):
        model.observe(i * 500_000, bad if i % 7 == 0 else inputs[i], float(measured[i]))
        model.observe(i * 500_000 + 1, inputs[i], math.inf)
    st = model.status
    assert st.state == "trained"
    assert st.samples == 400 - len(range(0, 400, 7))
    assert model.predict(bad) is None


def test_training_is_decimated_to_its_rate_and_windowed() -> None:
    inputs, _tas, measured = _aircraft(50, seed=5)
    model = OnlineAirspeedModel(GmdhRegressor, train_rate_hz=2.0, window_s=10.0)
    for i in range(50 * 25):  # 50 Hz calls for 25 s
        model.observe(i * 20_000, inputs[i % 50], float(measured[i % 50]))
    # 2 pairs per second kept, 10 s window: 20 or 21 pairs (window edges inclusive)
    assert model.status.samples in (20, 21)


def test_extrapolation_costs_sigma_and_stays_finite() -> None:
    inputs, _tas, measured = _aircraft(600, seed=6)
    model = _model()
    for i in range(600):
        model.observe(i * 500_000, inputs[i], float(measured[i]))
    inside = model.predict(inputs[-1])
    far = model.predict(
        AirspeedInputs(**{**{k: getattr(inputs[-1], k) for k in inputs[-1].__slots__},
                          "elevator": 5.0})
    )
    assert inside is not None and far is not None
    assert far.sigma_mps > 2.0 * inside.sigma_mps
    assert math.isfinite(far.tas_mps)


def test_rejects_bad_settings() -> None:
    with pytest.raises(ValueError, match="validation_fraction"):
        OnlineAirspeedModel(GmdhRegressor, validation_fraction=1.0)


def test_inputs_without_a_known_airspeed_make_the_model_untrained_not_inputless() -> None:
    inputs, _tas, _measured = _aircraft(10, seed=7)
    model = _model()
    for i, x in enumerate(inputs):
        model.observe(i * 500_000, x, math.nan)
    st = model.status
    assert st.state == "untrained" and st.samples == 0
