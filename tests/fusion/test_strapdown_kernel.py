"""fusion._strapdown (the compiled INS kernel) against its Python reference in fusion.strapdown:
the same bits for every output (struct bytes, so -0.0 and 0.0 differ), NaN where the reference
gives NaN, the same exception where it raises, and the filter's estimates unchanged end to end.

NaN payloads and signs are not compared: IEEE 754 leaves them to the hardware and the operand
order the C compiler picks (CPython's own float operations included), so they are not a property
of the algorithm. The kernel must be built for these tests: pip builds it when a C compiler is
installed (docs/development.md, "Compiled kernels")."""

from __future__ import annotations

import math
import os
import struct
import sys
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

import fusion.strapdown as sd
from fusion.config import FilterConfig
from fusion.strapdown import InsState
from physconst.kernel import python_forced
from tests.helpers.filter_digest import filter_digest, tuned_config
from tests.helpers.kernels import compiled_kernel, require_built
from tests.helpers.nav_synth import Flight, SensorErrors, make_scenario, prepare

kernel = compiled_kernel("fusion._strapdown")
PAIRS: list[tuple[str, Callable[..., Any]]] = [
    ("update", sd.update_python),
    ("increments", sd.increments_python),
    ("increments_scaled", sd.increments_scaled_python),
    ("increments_compensated", sd.increments_compensated_python),
]


@pytest.fixture(autouse=True)
def _kernel_built() -> None:
    require_built(kernel, "fusion._strapdown", "the compiled INS kernel")


def leaves(x: Any) -> Iterator[Any]:
    if isinstance(x, tuple):
        yield type(x)
        for v in x:
            yield from leaves(v)
    else:
        yield x


def fingerprint(x: Any) -> list[Any]:
    """Type of every tuple and value, float bits (NaN as one value)."""
    out: list[Any] = []
    for v in leaves(x):
        if isinstance(v, type):
            out.append(v)
        else:
            out.append(type(v))
            out.append("nan" if math.isnan(v) else struct.pack("<d", v))
    return out


def outcome(fn: Callable[..., Any], *args: Any) -> tuple[str, Any]:
    try:
        return "ok", fingerprint(fn(*args))
    except (ValueError, ZeroDivisionError, TypeError) as e:
        return type(e).__name__, str(e)


def assert_same(name: str, *args: Any) -> tuple[str, Any]:
    ref = dict(PAIRS)[name]
    got, want = outcome(getattr(kernel, name), *args), outcome(ref, *args)
    assert got == want, (name, args)
    return got


# ------------------------------------------------------------------------------- strategies
def finite(lo: float, hi: float) -> st.SearchStrategy[float]:
    return st.floats(lo, hi, allow_nan=False, allow_infinity=False)


ANY = st.floats()  # every double: NaN, inf, -0.0, subnormals
vec = st.tuples(finite(-0.5, 0.5), finite(-0.5, 0.5), finite(-0.5, 0.5))  # both series branches
vec_any = st.tuples(ANY, ANY, ANY)


@st.composite
def unit_quat(draw: st.DrawFn) -> tuple[float, float, float, float]:
    q = draw(st.tuples(*[finite(-1.0, 1.0)] * 4).filter(lambda q: sum(c * c for c in q) > 1e-6))
    n = math.sqrt(sum(c * c for c in q))
    return (q[0] / n, q[1] / n, q[2] / n, q[3] / n)


@st.composite
def states(draw: st.DrawFn) -> InsState:
    return InsState(
        draw(finite(-math.pi / 2, math.pi / 2)),
        draw(finite(-math.pi, math.pi)),
        draw(finite(-1e4, 1e5)),
        draw(st.tuples(*[finite(-400.0, 400.0)] * 3)),
        draw(unit_quat()),
    )


@st.composite
def raw_states(draw: st.DrawFn) -> InsState:
    return InsState(draw(ANY), draw(ANY), draw(ANY), draw(vec_any), draw(st.tuples(*[ANY] * 4)))


DT = st.one_of(finite(1e-6, 0.05), st.sampled_from([1e-300, 5e-324, 0.0, -0.0, 1e3, 1e6]))


# ------------------------------------------------------------------------------- the kernel
def test_kernel_is_built_and_used_unless_the_reference_is_forced() -> None:
    forced = python_forced(os.environ)
    assert sd.KERNEL == ("python" if forced else "c")
    assert (sd.update is kernel.update) != forced
    assert (sd.increments_compensated is kernel.increments_compensated) != forced


def test_built_without_sincos_merging() -> None:
    """gcc merges sin(x) and cos(x) into one sincos() call unless told not to (setup.py): the
    library binary must call sin and cos, never sincos."""
    assert kernel is not None and kernel.__file__ is not None
    binary = Path(kernel.__file__).read_bytes()
    assert b"sincos" not in binary
    if sys.platform.startswith("linux"):
        assert b"\0sin\0" in binary and b"\0cos\0" in binary


@settings(max_examples=60, deadline=None)
@given(states(), vec, vec, vec, vec, DT)
@example(  # rotation just below / above the series threshold a2 = 1e-4
    InsState(0.7, 0.1, 100.0, (50.0, 1.0, -2.0), (1.0, 0.0, 0.0, 0.0)),
    (0.0099999, 0.0, 0.0),
    (0.1, 0.0, -0.05),
    (0.01, 0.0, 0.0),
    (0.1, 0.0, -0.05),
    0.01,
)
@example(
    InsState(0.7, 0.1, 100.0, (50.0, 1.0, -2.0), (1.0, 0.0, 0.0, 0.0)),
    (0.0100001, 0.0, 0.0),
    (0.1, 0.0, -0.05),
    (0.01, 0.0, 0.0),
    (0.1, 0.0, -0.05),
    0.01,
)
def test_update_matches_the_reference(
    state: InsState, th: Any, dv: Any, pth: Any, pdv: Any, dt: float
) -> None:
    assert_same("update", state, th, dv, pth, pdv, dt)


def test_update_matches_the_reference_on_a_seeded_sweep() -> None:
    """3000 random flights' worth of single steps (hypothesis explores the corners above at a
    few milliseconds per example; this covers the bulk): rotation angles from 1e-6 to 0.5 rad
    on both sides of the series threshold, any attitude, latitudes up to the poles."""
    rng = np.random.default_rng(20261203)
    n = 3000
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    scale = 10.0 ** rng.uniform(-6.0, np.log10(0.5), size=(n, 1))
    th, pth = rng.normal(size=(n, 3)) * scale, rng.normal(size=(n, 3)) * scale
    dv, pdv = rng.normal(size=(n, 3)) * 0.5, rng.normal(size=(n, 3)) * 0.5
    lat = rng.uniform(-HALF_PI, HALF_PI, n)
    lon = rng.uniform(-math.pi, math.pi, n)
    h = rng.uniform(-500.0, 2e4, n)
    v = rng.normal(size=(n, 3)) * 100.0
    dt = 10.0 ** rng.uniform(-4.0, 0.0, n)
    branches = {"series": 0, "sin/cos": 0}
    for i in range(n):
        state = InsState(float(lat[i]), float(lon[i]), float(h[i]), tuple(v[i].tolist()),
                         tuple(q[i].tolist()))  # fmt: skip
        args = [tuple(a[i].tolist()) for a in (th, dv, pth, pdv)]
        assert assert_same("update", state, *args, float(dt[i]))[0] == "ok"
        a = args[0]
        branches["series" if a[0] ** 2 + a[1] ** 2 + a[2] ** 2 < 1e-4 else "sin/cos"] += 1
    assert min(branches.values()) > n / 4


@settings(max_examples=50, deadline=None)
@given(raw_states(), vec_any, vec_any, vec_any, vec_any, ANY)
def test_update_matches_the_reference_on_any_doubles(
    state: InsState, th: Any, dv: Any, pth: Any, pdv: Any, dt: float
) -> None:
    """NaN and inf anywhere: the same NaN positions, or the same exception (sin(inf) is a
    domain error, a zero divisor a ZeroDivisionError)."""
    assert_same("update", state, th, dv, pth, pdv, dt)


Q0 = (1.0, 0.0, 0.0, 0.0)
ZERO = (0.0, 0.0, 0.0)
NEG0 = (-0.0, -0.0, -0.0)
TH = (0.001, -0.002, 0.0005)
DV = (0.05, 0.01, -0.098)
HALF_PI = math.pi / 2


@pytest.mark.parametrize(
    ("state", "th", "dv", "pth", "pdv", "dt", "expect"),
    [
        # the n-frame rotation zeta past the series branch: huge dt (1000 s: ~0.07 rad)
        (InsState(0.5, 0.0, 0.0, (0.0, 0.0, 0.0), Q0), ZERO, ZERO, ZERO, ZERO, 1e3, "ok"),
        (InsState(0.5, 0.0, 0.0, (100.0, 0.0, 0.0), Q0), TH, DV, TH, DV, 1e6, "ok"),
        # tiny dt, subnormal dt, zero and negative zero dt and increments
        (InsState(0.5, 0.0, 10.0, (30.0, 0.0, 0.0), Q0), TH, DV, ZERO, ZERO, 5e-324, "ok"),
        (InsState(0.5, 0.0, 10.0, (30.0, 0.0, 0.0), Q0), NEG0, NEG0, NEG0, NEG0, -0.0, "ok"),
        (
            InsState(-0.0, -0.0, -0.0, NEG0, (1.0, -0.0, -0.0, -0.0)),
            NEG0,
            NEG0,
            ZERO,
            ZERO,
            0.01,
            "ok",
        ),
        # the result quaternion's scalar part negative (rw < 0): the sign flip of the norm
        (
            InsState(0.5, 0.2, 100.0, (50.0, 0.0, 0.0), (0.0005, 1.0, 0.0, 0.0)),
            (-0.01, 0.0, 0.0),
            DV,
            ZERO,
            ZERO,
            0.01,
            "ok",
        ),
        (
            InsState(0.5, 0.2, 100.0, (50.0, 0.0, 0.0), (-0.6, 0.8, 0.0, 0.0)),
            TH,
            DV,
            TH,
            DV,
            0.01,
            "ok",
        ),
        # poles: cos(lat) ~ 6e-17 at pi / 2 in doubles, and just off it
        (InsState(HALF_PI, 0.0, 100.0, (10.0, 10.0, 0.0), Q0), TH, DV, TH, DV, 0.01, "ok"),
        (InsState(-HALF_PI, 3.0, 100.0, (10.0, 10.0, 0.0), Q0), TH, DV, TH, DV, 0.01, "ok"),
        (InsState(HALF_PI - 1e-9, 0.0, 100.0, (10.0, 10.0, 0.0), Q0), TH, DV, TH, DV, 0.01, "ok"),
        (InsState(1.5, 0.0, 100.0, (10.0, 10.0, 0.0), Q0), TH, DV, TH, DV, 0.01, "ok"),
        # negative heights, deep and slightly
        (InsState(0.3, 0.0, -420.0, (10.0, 0.0, 5.0), Q0), TH, DV, TH, DV, 0.005, "ok"),
        (InsState(0.3, 0.0, -6.0e6, (10.0, 0.0, 5.0), Q0), TH, DV, TH, DV, 0.005, "ok"),
        # NaN in a velocity / the attitude: propagated to the same fields
        (InsState(0.3, 0.0, 100.0, (math.nan, 0.0, 0.0), Q0), TH, DV, TH, DV, 0.005, "ok"),
        (InsState(0.3, 0.0, 100.0, ZERO, (math.nan, 0.0, 0.0, 0.0)), TH, DV, TH, DV, 0.005, "ok"),
        (InsState(0.3, 0.0, 100.0, ZERO, Q0), (math.nan, 0.0, 0.0), DV, TH, DV, 0.005, "ok"),
        # errors where the reference raises them
        (InsState(math.inf, 0.0, 0.0, ZERO, Q0), TH, DV, TH, DV, 0.01, "ValueError"),
        (InsState(0.0, 0.0, 0.0, ZERO, Q0), (math.inf, 0.0, 0.0), DV, TH, DV, 0.01, "ValueError"),
        (InsState(0.0, 0.0, -6378137.0, ZERO, Q0), TH, DV, TH, DV, 0.01, "ZeroDivisionError"),
        (
            InsState(0.5, 0.0, 0.0, ZERO, (0.0, 0.0, 0.0, 0.0)),
            ZERO,
            ZERO,
            ZERO,
            ZERO,
            0.01,
            "ZeroDivisionError",
        ),
    ],
)
def test_update_matches_the_reference_on_hand_picked_inputs(
    state: InsState, th: Any, dv: Any, pth: Any, pdv: Any, dt: float, expect: str
) -> None:
    assert assert_same("update", state, th, dv, pth, pdv, dt)[0] == expect


def test_inputs_the_kernel_does_not_take_go_to_the_reference() -> None:
    """Ints (exact integer arithmetic in Python), numpy values and keyword arguments are
    computed by the reference itself, whose errors come out unchanged."""
    s = InsState(0.5, 0.1, 100.0, (50.0, 0.0, 0.0), Q0)
    ints = InsState(0, 0, 100, (50, 0, 0), (1, 0, 0, 0))
    arr = np.array([1e-3, 2e-3, 0.0])
    for args in [
        (ints, (0, 0, 0), (1, 2, 3), (0, 0, 0), (0, 0, 0), 1),
        (s, arr, arr, arr, arr, np.float64(0.01)),
        (s, [1e-3, 0.0, 0.0], [0.1, 0.0, 0.0], ZERO, ZERO, 0.01),  # lists: the fast path
        ((0.5, 0.1, 100.0, [50.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0]), TH, DV, TH, DV, 0.01),
    ]:
        assert_same("update", *args)
    assert kernel.update(s, TH, DV, dtheta_prev_b=TH, dv_prev_b=DV, dt_s=0.01) == sd.update_python(
        s, TH, DV, TH, DV, 0.01
    )
    for bad in [(s, (1.0, 2.0), DV, TH, DV, 0.01), (s[:4], TH, DV, TH, DV, 0.01), (s, TH)]:
        with pytest.raises((ValueError, TypeError)) as got:
            kernel.update(*bad)
        with pytest.raises(got.type, match=str(got.value).replace("(", r"\(").replace(")", r"\)")):
            sd.update_python(*bad)


six = st.tuples(*[ANY] * 6)
six_finite = st.tuples(*[finite(-200.0, 200.0)] * 6)


@settings(max_examples=60, deadline=None)
@given(st.one_of(six, six_finite), ANY, vec_any, vec_any)
@example((1.0, 2.0, -0.0, 0.1, -0.2, 0.3), 0.005, NEG0, ZERO)
def test_increments_match_the_reference(fw: Any, dt: float, ba: Any, bg: Any) -> None:
    assert_same("increments", fw, dt, ba, bg)


@settings(max_examples=60, deadline=None)
@given(st.one_of(six, six_finite), ANY, vec_any, vec_any, vec_any, vec_any)
@example((1.0, 2.0, 3.0, 0.1, 0.2, 0.3), 0.005, ZERO, ZERO, ZERO, (0.0, -1.0, 0.0))  # 1 + s = 0
@example((1.0, 2.0, 3.0, 0.1, 0.2, 0.3), 0.005, ZERO, ZERO, (-1.0, 0.0, 0.0), ZERO)
def test_scaled_increments_match_the_reference(
    fw: Any, dt: float, ba: Any, bg: Any, sa: Any, sg: Any
) -> None:
    assert_same("increments_scaled", fw, dt, ba, bg, sa, sg)


@settings(max_examples=60, deadline=None)
@given(st.one_of(six, six_finite), ANY, vec_any, vec_any, st.tuples(*[ANY] * 9),
       st.tuples(*[finite(-2.0, 2.0)] * 9))  # fmt: skip
def test_compensated_increments_match_the_reference(
    fw: Any, dt: float, ba: Any, bg: Any, ai: Any, gi: Any
) -> None:
    assert_same("increments_compensated", fw, dt, ba, bg, ai, gi)
    assert_same("increments_compensated", fw, dt, ba, bg, gi, ai)


# ------------------------------------------------------------------------------- end to end
def swap_in(monkeypatch: pytest.MonkeyPatch, use_kernel: bool) -> dict[str, int]:
    """Bind every reference to the four functions held by a loaded fusion module (the filter
    binds them at import) to a counting wrapper of the kernel or of the Python reference."""
    calls = {name: 0 for name, _ in PAIRS}
    by_id: dict[int, tuple[str, Callable[..., Any]]] = {}
    for name, ref in PAIRS:
        impl = getattr(kernel, name) if use_kernel else ref

        def counted(*args: Any, _impl: Callable[..., Any] = impl, _name: str = name) -> Any:
            calls[_name] += 1
            return _impl(*args)

        by_id[id(getattr(kernel, name))] = by_id[id(ref)] = (name, counted)
    for mod_name, mod in list(sys.modules.items()):
        if mod is None or not (mod_name == "fusion" or mod_name.startswith("fusion.")):
            continue
        for attr, value in list(vars(mod).items()):
            if id(value) in by_id and attr not in {n + "_python" for n, _ in PAIRS}:
                monkeypatch.setattr(mod, attr, by_id[id(value)][1])
    return calls


@pytest.mark.parametrize("layout", ["ins16", "ins22", "ins35+gnss+air"])
def test_filter_estimates_are_identical_with_and_without_the_kernel(
    monkeypatch: pytest.MonkeyPatch, layout: str
) -> None:
    """The estimate digest of bench/fusion_speed.py (every estimate's and innovation's bytes,
    the final covariance) of a 3 s turning flight at 100 Hz, the commands' tuning with plain
    increments (ins16), scale factors (ins22) or the full sensor model (ins35)."""
    prep = prepare(Flight(duration_s=3.0, turns=[(1.0, 2.5, 0.25)]), imu_rate_hz=100.0)
    cfg = FilterConfig(state_layout=layout)  # type: ignore[arg-type]
    sc = make_scenario(prep, np.random.default_rng(7), SensorErrors.from_config(cfg))
    tuned = tuned_config("industrial-mems", cov_rate_hz=100.0, layout=layout)
    digests, counts = {}, {}
    for use_kernel in (True, False):
        with monkeypatch.context() as m:
            counts[use_kernel] = swap_in(m, use_kernel)
            digests[use_kernel] = filter_digest(tuned, sc.samples)
    assert digests[True] == digests[False]
    assert counts[True] == counts[False]
    assert counts[True]["update"] > 150  # the filter did run the swapped-in functions
    inc = {"ins16": "increments", "ins22": "increments_scaled"}.get(
        layout, "increments_compensated"
    )
    assert counts[True][inc] == counts[True]["update"]
