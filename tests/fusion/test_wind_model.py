"""The learned wind profile (``gmdh-wind``): mean wind against height, learned online."""

from __future__ import annotations

import math

import numpy as np

from fusion.gmdh import GmdhRegressor
from fusion.wind_model import OnlineWindModel

W_REF = np.array([-6.0, 4.0])  # at 150 m
H_REF_M = 150.0
SHEAR = 1.0 / 7.0  # neutral boundary layer


def _profile(h_m: float) -> np.ndarray:
    return W_REF * (h_m / H_REF_M) ** SHEAR


def _climbs(model: OnlineWindModel, rng: np.random.Generator, noise_mps: float) -> None:
    """Five minutes of climbs and descents between 150 and 450 m at 2.5 m/s, the filter's
    mean-wind estimate noisy by ``noise_mps`` per axis (10 Hz epochs)."""
    for k in range(3000):
        t = 0.1 * k
        h = 300.0 - 150.0 * math.cos(2.0 * math.pi * t / 240.0)
        w = _profile(h) + rng.normal(0.0, noise_mps, 2)
        model.observe(round(t * 1e6), h, (float(w[0]), float(w[1])))


def test_learns_a_power_law_shear_and_is_flat_outside_the_heights_flown() -> None:
    # GIVEN five minutes of climbs and descents through a 1/7 power-law profile (the wind
    # grows 17 % from 150 to 450 m: 1.2 m/s here), the estimates noisy by 0.3 m/s
    model = OnlineWindModel(GmdhRegressor, describe=lambda m: m.polynomial(4))  # type: ignore[attr-defined]
    _climbs(model, np.random.default_rng(3), 0.3)
    assert model.status.state == "trained" and "north:" in model.status.polynomial
    # WHEN it predicts inside the heights flown
    errs = []
    for h in np.linspace(170.0, 430.0, 14):
        p = model.predict(float(h))
        assert p is not None
        errs.append(np.abs(np.array(p.wind_ne_mps) - _profile(float(h))))
    # THEN the profile is within 0.25 m/s per axis: a smooth one-input fit of ~600 pairs at
    # 0.3 m/s noise has a standard error of a few cm; the bound leaves room for the fit's
    # polynomial shape and a blocked validation split that holds the last quarter out
    assert np.max(errs) < 0.25, np.max(errs)
    # AND the change it predicts between 150 and 450 m is the profile's (1.2 m/s) within 25 %
    lo, hi = model.predict(160.0), model.predict(440.0)
    assert lo is not None and hi is not None
    change = np.array(hi.wind_ne_mps) - np.array(lo.wind_ne_mps)
    true = _profile(440.0) - _profile(160.0)
    assert np.linalg.norm(change - true) < 0.25 * np.linalg.norm(true), (change, true)
    # AND far outside the heights flown the GMDH neurons are clipped: the profile is flat
    # there, so moving further away moves the wind no more
    a, b = model.predict(1500.0), model.predict(2500.0)
    assert a is not None and b is not None
    assert np.allclose(a.wind_ne_mps, b.wind_ne_mps, atol=1e-9)


def test_predicts_nothing_before_it_has_flown_through_heights() -> None:
    # GIVEN level flight at one height (the profile is unknown: nothing to learn)
    model = OnlineWindModel(GmdhRegressor)
    rng = np.random.default_rng(4)
    for k in range(3000):
        w = W_REF + rng.normal(0.0, 0.3, 2)
        model.observe(k * 100_000, 300.0 + rng.normal(0.0, 2.0), (float(w[0]), float(w[1])))
    # THEN it predicts nothing (the heights span less than min_change_m)
    assert model.predict(300.0) is None
    # AND non-finite pairs are not learned
    model.observe(400_000_000, math.nan, (1.0, 1.0))
    model.observe(400_100_000, 300.0, (math.nan, 1.0))
    assert model.status.samples == 600  # 300 s of pairs kept at 2 per second, no NaN pair


def test_status_before_any_data() -> None:
    st = OnlineWindModel(GmdhRegressor).status
    assert (st.method, st.state, st.samples, st.refits) == ("gmdh-wind", "no inputs", 0, 0)
    assert math.isnan(st.validation_rmse_mps) and st.polynomial == ""
