"""fusion._update (the compiled Phi fill of the covariance time update) against its Python
reference, ``ErrorModel._fill`` packed and ``put`` into Phi: the same bits in every entry of Phi
(-0.0 and 0.0 differ), NaN where the reference gives NaN, the same exception where it raises
(the kernel declines and the reference runs), for every layout family.

NaN payloads and signs are not compared (tests/fusion/test_strapdown_kernel.py says why). The
kernel must be built for these tests: pip builds it when a C compiler is installed
(docs/development.md, "Compiled kernels")."""

from __future__ import annotations

import math
import os
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import fusion.error_model as em
from fusion import earth
from fusion.rotations import dcm_from_quat
from physconst.kernel import python_forced
from tests.fusion.test_error_model import NOISE
from tests.helpers.kernels import compiled_kernel, require_built

kernel = compiled_kernel("fusion._update")

LAYOUTS = ["ins16", "ins22+gnss", "ins35", "ins35+gnss+air"]
MODELS = {name: em.ErrorModel(em.layout_for(name), NOISE) for name in LAYOUTS}


@pytest.fixture(autouse=True)
def _kernel_built() -> None:
    require_built(kernel, "fusion._update", "the compiled Phi fill and process noise")


def bits(a: np.ndarray) -> list[Any]:
    """Every entry's bytes, NaN as one value."""
    return ["nan" if math.isnan(v) else np.float64(v).tobytes() for v in a.ravel().tolist()]


def outcome(model: em.ErrorModel, compiled: bool, args: tuple[Any, ...],
            monkeypatch: pytest.MonkeyPatch) -> tuple[str, Any]:
    """Phi (a fresh copy and the scratch matrix) from the kernel or from the reference."""
    # NaN / inf inputs are the point here: numpy's warnings about them are expected (errstate)
    with monkeypatch.context() as m, np.errstate(all="ignore"):
        m.setattr(em, "_kernel", kernel if compiled else None)
        try:
            fresh = model.first_order_transition(*args)
            scratch = model.first_order_transition(*args, scratch=True)
        except (ValueError, ZeroDivisionError, TypeError) as e:
            return type(e).__name__, str(e)
    return "ok", (bits(fresh), bits(scratch))


def assert_same(name: str, args: tuple[Any, ...], monkeypatch: pytest.MonkeyPatch) -> str:
    model = MODELS[name]
    got = outcome(model, True, args, monkeypatch)
    want = outcome(model, False, args, monkeypatch)
    assert got == want, (name, args)
    return got[0]


def finite(lo: float, hi: float) -> st.SearchStrategy[float]:
    return st.floats(lo, hi, allow_nan=False, allow_infinity=False)


def vec(lo: float, hi: float) -> st.SearchStrategy[tuple[float, float, float]]:
    return st.tuples(finite(lo, hi), finite(lo, hi), finite(lo, hi))


ANY = st.floats()  # every double: NaN, inf, -0.0, subnormals
ANY3 = st.tuples(ANY, ANY, ANY)


def test_kernel_is_bound_and_used_unless_the_reference_is_forced() -> None:
    forced = python_forced(os.environ)
    assert em.KERNEL == ("python" if forced else "c")
    assert (em._kernel is None) == forced


def test_matches_the_reference_on_a_seeded_sweep(monkeypatch: pytest.MonkeyPatch) -> None:
    """Flight-like operating points, latitudes up to the poles, every layout family."""
    rng = np.random.default_rng(20261203)
    for i in range(200):
        name = LAYOUTS[i % len(LAYOUTS)]
        q = rng.normal(size=4)
        q /= np.linalg.norm(q)
        args = (
            float(rng.uniform(-1.57, 1.57)), float(rng.uniform(-500.0, 2e4)),
            tuple(rng.normal(size=3) * 80.0), dcm_from_quat(tuple(q.tolist())),
            tuple(rng.normal(size=3) * 5.0), float(10.0 ** rng.uniform(-3.0, -1.0)),
            tuple(rng.normal(size=3) * 5.0), tuple(rng.normal(size=3) * 0.3),
        )  # fmt: skip
        args = tuple(tuple(float(x) for x in a) if isinstance(a, tuple) else a for a in args)
        assert assert_same(name, args, monkeypatch) == "ok"


@settings(max_examples=60, deadline=None)
@given(
    st.sampled_from(LAYOUTS), ANY, ANY, ANY3, st.tuples(*[ANY] * 9), ANY3, ANY, ANY3, ANY3,
)
def test_matches_the_reference_on_any_doubles(
    name: str, lat: float, alt: float, v: Any, c_nb: Any, f_n: Any, dt: float, f_b: Any,
    w_b: Any,
) -> None:
    """NaN, inf, zeros and subnormals anywhere: the same bits, NaN positions or exception."""
    with pytest.MonkeyPatch.context() as mp:
        assert_same(name, (lat, alt, v, c_nb, f_n, dt, f_b, w_b), mp)


@pytest.mark.parametrize("terms", [
    earth.LocalTerms(6.4e6, 6.4e6, 9.8, 1.0, 0.0),  # cos(lat) = 0: s / c
    earth.LocalTerms(6.4e6, 6.4e6, 9.8, 1.0, 1e-170),  # c * c underflows to 0
    earth.LocalTerms(0.0, 6.4e6, 9.8, 0.5, 0.8),  # rho_n = 0
    earth.LocalTerms(6.4e6, -0.0, 9.8, 0.5, 0.8),  # rho_e = -0
    earth.LocalTerms(1e-200, 6.4e6, 9.8, 0.5, 0.8),  # rho_n * rho_n underflows
])  # fmt: skip
def test_zero_divisors_raise_as_the_reference(
    terms: earth.LocalTerms, monkeypatch: pytest.MonkeyPatch
) -> None:
    args = (0.5, 100.0, (50.0, 1.0, -2.0), dcm_from_quat((1.0, 0.0, 0.0, 0.0)),
            (0.1, 0.2, -9.8), 0.01, (0.1, 0.2, -9.8), (0.01, 0.0, 0.0), terms)  # fmt: skip
    assert assert_same("ins35+gnss+air", args, monkeypatch) == "ZeroDivisionError"
    phi = MODELS["ins16"].first_order_transition(0.5, 100.0, (50.0, 1.0, -2.0),
                                                 dcm_from_quat((1.0, 0.0, 0.0, 0.0)),
                                                 (0.1, 0.2, -9.8), 0.01, scratch=True)
    before = phi.copy()
    assert kernel.transition_fill(
        phi, MODELS["ins16"]._var_idx, terms, (1.0, 2.0), (50.0, 1.0, -2.0),
        dcm_from_quat((1.0, 0.0, 0.0, 0.0)), (0.1, 0.2, -9.8), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0),
        0.01, 1.0, False, False,
    ) is False  # fmt: skip
    assert phi.tobytes() == before.tobytes()  # nothing written


@pytest.mark.parametrize("odd", ["int", "numpy", "list", "short"])
def test_other_input_types_take_the_reference(odd: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """ints, numpy scalars, lists, wrong lengths: the kernel declines, the reference computes
    (or raises) exactly as before."""
    v: Any = (50.0, 1.0, -2.0)
    dt: Any = 0.01
    if odd == "int":
        dt = 1
    elif odd == "numpy":
        v = (np.float64(50.0), 1.0, -2.0)
    elif odd == "list":
        v = [50.0, 1.0, -2.0]
    else:
        v = (50.0, 1.0)
    args = (0.5, 100.0, v, dcm_from_quat((1.0, 0.0, 0.0, 0.0)), (0.1, 0.2, -9.8), dt)
    assert assert_same("ins35+gnss+air", args, monkeypatch) in {"ok", "ValueError"}


def test_bad_buffers_are_errors_not_silent_writes() -> None:
    model = MODELS["ins16"]
    terms = earth.local_terms(0.5, 100.0)
    call = (terms, (1.0, 2.0), (50.0, 1.0, -2.0), dcm_from_quat((1.0, 0.0, 0.0, 0.0)),
            (0.1, 0.2, -9.8), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), 0.01, 1.0, False, False)
    n = model.layout.n
    with pytest.raises(TypeError):
        kernel.transition_fill(np.zeros((n, n), dtype=np.float32), model._var_idx, *call)
    with pytest.raises(ValueError):  # read-only
        ro = np.zeros((n, n))
        ro.flags.writeable = False
        kernel.transition_fill(ro, model._var_idx, *call)
    with pytest.raises(ValueError):  # index of another layout
        kernel.transition_fill(np.zeros((n, n)), MODELS["ins35"]._var_idx, *call)
    with pytest.raises(IndexError):
        kernel.transition_fill(np.zeros((4, 4)), model._var_idx, *call)
    with pytest.raises(TypeError):
        kernel.transition_fill(np.zeros((n, n)), model._var_idx)


# ------------------------------------------------------------------ add_process_noise
def noise_outcome(model: em.ErrorModel, compiled: bool, P: np.ndarray, args: tuple[Any, ...],
                  monkeypatch: pytest.MonkeyPatch) -> tuple[str, Any]:
    out = P.copy()
    with monkeypatch.context() as m, np.errstate(all="ignore"):
        m.setattr(em, "_kernel", kernel if compiled else None)
        try:
            model.add_process_noise(out, *args)
        except (ValueError, TypeError, IndexError) as e:
            return type(e).__name__, str(e)
    return "ok", bits(out)


def assert_same_noise(name: str, P: np.ndarray, args: tuple[Any, ...],
                      monkeypatch: pytest.MonkeyPatch) -> str:
    model = MODELS[name]
    got = noise_outcome(model, True, P, args, monkeypatch)
    want = noise_outcome(model, False, P, args, monkeypatch)
    assert got == want, (name, args)
    return got[0]


def test_process_noise_matches_the_reference(monkeypatch: pytest.MonkeyPatch) -> None:
    """Random covariances with -0.0, NaN, inf and subnormals sprinkled in; air block dormant
    and active."""
    rng = np.random.default_rng(7)
    air = em.layout_for("ins35+gnss+air")
    specials = np.array([-0.0, 0.0, math.nan, math.inf, -math.inf, 5e-324, -1e308])
    for i in range(200):
        name = LAYOUTS[i % len(LAYOUTS)]
        n = MODELS[name].layout.n
        P = rng.normal(size=(n, n)) * 10.0 ** rng.uniform(-12, 3)
        if i % 3 == 0:
            P.flat[rng.integers(0, n * n, 20)] = rng.choice(specials, 20)
        dt = float(10.0 ** rng.uniform(-3.0, -1.0))
        args: tuple[Any, ...] = (dt,)
        if name == "ins35+gnss+air" and i % 2:
            q = rng.choice(np.concatenate([specials, rng.uniform(0, 1, 7)]), 4).tolist()
            args = (dt, air.WIND, q[0], q[1], q[2], q[3])
        assert assert_same_noise(name, P, args, monkeypatch) == "ok"


def test_process_noise_declines_what_it_does_not_take(monkeypatch: pytest.MonkeyPatch) -> None:
    """Fortran order, float32, another size, an int scalar, an air block past the edge: the
    reference runs (and raises where it raises)."""
    air = em.layout_for("ins35+gnss+air")
    n = air.n
    P = np.arange(n * n, dtype=float).reshape(n, n) * 1e-3
    Q = MODELS["ins35+gnss+air"].process_noise(0.01)
    assert kernel.add_process_noise(np.asfortranarray(P), Q, -1, 0.0, 0.0, 1.0, 0.0) is False
    assert kernel.add_process_noise(P.astype(np.float32), Q, -1, 0.0, 0.0, 1.0, 0.0) is False
    assert kernel.add_process_noise(P[:4, :4].copy(), Q, -1, 0.0, 0.0, 1.0, 0.0) is False
    assert kernel.add_process_noise(P.copy(), Q, air.WIND, 1, 0.0, 1.0, 0.0) is False
    assert kernel.add_process_noise(P.copy(), Q, n - 3, 0.0, 0.0, 1.0, 0.0) is False
    ro = P.copy()
    ro.flags.writeable = False
    assert kernel.add_process_noise(ro, Q, -1, 0.0, 0.0, 1.0, 0.0) is False
    same = P.copy()
    assert kernel.add_process_noise(same, same, -1, 0.0, 0.0, 1.0, 0.0) is False
    assert same.tobytes() == P.tobytes()  # nothing written when declined
    for args in [(0.01, air.WIND, 1, 0.0, 1.0, 0.0), (0.01, n - 3, 0.0, 0.0, 0.5, 0.0)]:
        assert assert_same_noise("ins35+gnss+air", P, args, monkeypatch) in {"ok", "IndexError"}
    with pytest.raises(TypeError):
        kernel.add_process_noise(P, Q)
