"""sim._simkernel (the compiled simulator kernel) against its Python references in sim.imu and
sim.guidance, and
the Gauss-Markov block filter against scipy.signal.lfilter, which it replaces: the same bits for
every output (struct bytes, so -0.0 and 0.0 differ), NaN where the reference gives NaN, the same
exception where it raises, and the IMU model's samples unchanged.

NaN payloads and signs are not compared (as in tests/fusion/test_strapdown_kernel.py): IEEE 754
leaves them to the hardware and to the operand order the compiler picks. The kernel must be
built for these tests: pip builds it when a C compiler is installed (docs/development.md,
"Compiled kernels")."""

from __future__ import annotations

import math
import os
import struct
import subprocess
import sys
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp
from scipy.signal import lfilter  # the tests compare with it; the product must not import it

import sim.guidance as guidance
import sim.imu as imu
import sim.kernel as sk
from physconst.kernel import python_forced
from sim import presets
from sim.flight import Flight, FlightConfig
from sim.plans import load_plan
from tests.helpers.kernels import compiled_kernel, require_built

kernel = compiled_kernel("sim._simkernel")
SPECIAL = [0.0, -0.0, 5e-324, -5e-324, 2.2e-308, math.inf, -math.inf, math.nan, 1e308, -1e308]


@pytest.fixture(autouse=True)
def _kernel_built() -> None:
    require_built(kernel, "sim._simkernel", "the compiled simulator kernel")


def canonical(a: np.ndarray) -> bytes:
    """Bytes of a float64 array with every NaN made one value (payloads are not compared)."""
    a = np.array(a, dtype=np.float64)
    a[np.isnan(a)] = np.nan
    return a.tobytes()


def floats_key(values: Any) -> list[Any]:
    return ["nan" if math.isnan(v) else struct.pack("<d", v) for v in values]


def outcome(fn: Callable[..., Any], *args: Any) -> tuple[str, Any]:
    try:
        return "ok", floats_key(fn(*args))
    except (ValueError, OverflowError, TypeError) as e:
        return type(e).__name__, str(e)


def scipy_filter(x: np.ndarray, b0: list[float], a1: list[float], zi: list[float]) -> np.ndarray:
    out = np.empty(x.shape)
    for j in range(x.shape[1]):
        out[:, j], _ = lfilter([b0[j]], [1.0, a1[j]], x[:, j], zi=[zi[j]])
    return out


def all_filters(x: np.ndarray, b0: list[float], a1: list[float], zi: list[float]
                ) -> tuple[bytes, bytes, bytes]:
    """scipy's, the Python reference's and the kernel's output."""
    outs = []
    for fn in (imu.first_order_filter_python, kernel.first_order_filter):
        out = np.full(x.shape, 7.0)
        fn(x, b0, a1, zi, out)
        outs.append(canonical(out))
    return canonical(scipy_filter(x, b0, a1, zi)), outs[0], outs[1]


# ------------------------------------------------------------------------------- selection
def test_kernel_is_built_and_used_unless_the_reference_is_forced() -> None:
    forced = python_forced(os.environ)
    assert sk.KERNEL == ("python" if forced else "c")
    assert (imu.imu_output is kernel.imu_output) != forced
    assert (imu.first_order_filter is kernel.first_order_filter) != forced
    assert (guidance.law is kernel.law) != forced


def test_the_imu_model_does_not_import_scipy_signal() -> None:
    code = "import sys, sim.imu; print('scipy.signal' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], check=True, capture_output=True,
                         text=True).stdout
    assert out.strip() == "False"


# ------------------------------------------------------------------------------- the filter
def test_filter_matches_lfilter_on_the_imu_block_layout() -> None:
    """Seeded noise blocks as the IMU model draws them (columns 6:12 of a (1024, 18) block, a
    strided view), its coefficients, and special values in the input and initial state."""
    rng = np.random.default_rng(20261203)
    for trial in range(20):
        z = rng.standard_normal((1024, 18))
        phi = np.exp(-0.005 / rng.uniform(1.0, 1000.0, 6))
        q = rng.uniform(1e-6, 1.0, 6) * np.sqrt(1.0 - phi**2)
        zi = (phi * rng.standard_normal(6)).tolist()
        if trial % 2:  # zeros, negative zeros, subnormals, huge values, inf, NaN in the input
            z[rng.integers(0, 1024, 40), rng.integers(6, 12, 40)] = rng.choice(SPECIAL, 40)
            zi[trial % 6] = SPECIAL[trial % len(SPECIAL)]
        want, ref, got = all_filters(z[:, 6:12], q.tolist(), (-phi).tolist(), zi)
        assert ref == want
        assert got == want


def test_filter_signs_of_zero_and_infinities_follow_lfilter() -> None:
    """scipy's delay is x·0.0 − y·a1: a zero input after a zero output keeps the sign rules of
    that form, and an infinite input makes the next delay NaN (a plain phi·y would not)."""
    x = np.array([[-0.0], [0.0], [-0.0], [math.inf], [1.0], [-math.inf], [0.0]])
    for b0, a1, zi in ([1.0, -0.5, -0.0], [0.0, -0.5, 0.0], [-1.0, 0.5, -0.0], [2.0, -0.0, 0.0]):
        want, ref, got = all_filters(x, [b0], [a1], [zi])
        assert ref == want and got == want


@settings(max_examples=40, deadline=None)
@given(
    hnp.arrays(np.float64, st.tuples(st.integers(0, 40), st.integers(1, 6)),
               elements=st.floats(width=64)),
    st.data(),
)
def test_filter_matches_lfilter_on_any_doubles(x: np.ndarray, data: st.DataObject) -> None:
    k = x.shape[1]
    coefs = st.lists(st.floats(width=64), min_size=k, max_size=k)
    b0, a1, zi = data.draw(coefs), data.draw(coefs), data.draw(coefs)
    if x.shape[0] == 0:  # lfilter needs a sample; both others write nothing
        for fn in (imu.first_order_filter_python, kernel.first_order_filter):
            out = np.empty(x.shape)
            fn(x, b0, a1, zi, out)
        return
    want, ref, got = all_filters(x, b0, a1, zi)
    assert ref == want
    assert got == want


def test_filter_in_place_and_fallbacks() -> None:
    rng = np.random.default_rng(5)
    x = rng.standard_normal((50, 3))
    b0, a1, zi = [0.1, 0.2, 0.3], [-0.9, -0.8, -0.7], [0.5, -0.5, 0.0]
    want = scipy_filter(x, b0, a1, zi).tobytes()
    same = x.copy()
    kernel.first_order_filter(same, b0, a1, zi, same)  # the same elements in place
    assert same.tobytes() == want
    # inputs the kernel does not take go to the reference, which gives the same numbers
    for args in (
        (x.tolist(), b0, a1, zi),  # a list, not a buffer: the reference takes it
        (x, np.array(b0), a1, zi),  # numpy coefficients
        (x, b0, a1, [0.5, -0.5, 0]),  # an int
        (x.astype(np.float32), b0, a1, zi),  # another dtype
    ):
        out = np.empty((50, 3))
        kernel.first_order_filter(np.asarray(args[0], dtype=np.float64) if isinstance(
            args[0], list) else args[0], *args[1:], out)
        ref_out = np.empty((50, 3))
        imu.first_order_filter_python(np.asarray(args[0], dtype=np.float64) if isinstance(
            args[0], list) else args[0], *args[1:], ref_out)
        assert out.tobytes() == ref_out.tobytes()
    # an overlapping output (shifted by a row) goes to the reference, which reads x first
    buf = rng.standard_normal((51, 3))
    a, b = buf.copy(), buf.copy()
    kernel.first_order_filter(a[1:], b0, a1, zi, a[:-1])
    imu.first_order_filter_python(b[1:], b0, a1, zi, b[:-1])
    assert a.tobytes() == b.tobytes()
    # wrong shapes: the reference's own error
    with pytest.raises(ValueError):
        kernel.first_order_filter(x, b0, a1, zi, np.empty((49, 3)))
    with pytest.raises(ValueError):
        kernel.first_order_filter(x, b0[:2], a1[:2], zi[:2], np.empty((50, 2)))


# ------------------------------------------------------------------------------- IMU output
def params(lsb_acc: float = 0.0, lsb_gyr: float = 0.0, r_acc: float = 156.9,
           r_gyr: float = 8.7) -> tuple[float, ...]:
    rng = np.random.default_rng(11)
    t = (np.eye(3) + rng.normal(scale=1e-3, size=(3, 3))).ravel().tolist()
    g = (np.eye(3) + rng.normal(scale=1e-3, size=(3, 3))).ravel().tolist()
    return (*t, *g, r_acc, r_gyr, lsb_acc, lsb_gyr)


def assert_output_same(u: Any, e: Any, p: Any) -> tuple[str, Any]:
    got, want = outcome(kernel.imu_output, u, e, p), outcome(imu.imu_output_python, u, e, p)
    assert got == want, (u, e, p)
    return got


@settings(max_examples=60, deadline=None)
@given(
    st.lists(st.floats(-200.0, 200.0), min_size=6, max_size=6),
    st.lists(st.floats(-1.0, 1.0), min_size=6, max_size=6),
    st.sampled_from([0.0, 1e-3 * 9.80665, 0.061e-3 * 9.80665, 3.3e-7]),
    st.sampled_from([0.0, math.radians(0.0076), 1e-9]),
)
def test_output_matches_the_reference(u: list[float], e: list[float], lsb_acc: float,
                                      lsb_gyr: float) -> None:
    assert assert_output_same(u, e, params(lsb_acc, lsb_gyr))[0] == "ok"


@settings(max_examples=60, deadline=None)
@given(
    st.lists(st.floats(), min_size=6, max_size=6),
    st.lists(st.floats(), min_size=6, max_size=6),
    st.lists(st.floats(), min_size=22, max_size=22),
)
def test_output_matches_the_reference_on_any_doubles(u: list[float], e: list[float],
                                                     p: list[float]) -> None:
    """NaN and inf anywhere (the ranges and LSBs too): the same values or the same exception
    (round() of an infinite or NaN quotient)."""
    assert_output_same(u, e, p)


def test_output_edge_cases() -> None:
    p = params(1e-3, 1e-4)
    # -0.0 rounds to the int 0: +0.0 out; halves round to even; saturation at both ends
    assert assert_output_same([-1e-9, 0.0, -0.0, 0.0, 0.0, 0.0], [0.0] * 6, p)[0] == "ok"
    assert kernel.imu_output([-1e-9, 0.0, -0.0, 0.0, 0.0, 0.0], [0.0] * 6, p)[0] == 0.0
    assert math.copysign(1.0, kernel.imu_output([-1e-9] + [0.0] * 5, [0.0] * 6, p)[0]) == 1.0
    for half in (0.5e-3, 1.5e-3, 2.5e-3, -2.5e-3):
        assert_output_same([half, 0.0, 0.0, 0.0, 0.0, 0.0], [0.0] * 6, p)
        assert_output_same([0.0, 0.0, 0.0, half / 10, 0.0, 0.0], [0.0] * 6, p)
    assert_output_same([1e6, -1e6, math.inf, -math.inf, 1e3, -1e3], [0.0] * 6, p)
    no_range = params(1e-3, 1e-4, math.inf, math.inf)
    assert assert_output_same([math.inf] + [0.0] * 5, [0.0] * 6, no_range)[0] == "OverflowError"
    assert assert_output_same([0.0] * 3 + [math.nan] + [0.0] * 2, [0.0] * 6, p)[0] == "ValueError"
    # tiny LSB: quotients that overflow, or NaN after an overflow: the reference's first error
    huge = params(1e-300, 0.0, math.inf)
    assert assert_output_same([1.0, 1e308, 0.0] + [0.0] * 3, [0.0] * 6, huge)[0] == "OverflowError"
    assert assert_output_same([0.0] * 6, [1e-3, math.inf, math.nan, 0.0, 0.0, 0.0], huge)[0] == (
        "OverflowError")
    assert assert_output_same([0.0] * 6, [math.nan, math.inf, 0.0, 0.0, 0.0, 0.0], huge)[0] == (
        "ValueError")
    # no quantisation: NaN passes through
    assert assert_output_same([math.nan] * 6, [0.0] * 6, params())[0] == "ok"


def test_output_fallbacks_give_the_reference() -> None:
    p = params(1e-3)
    e = [0.01, -0.02, 0.03, 1e-4, -2e-4, 3e-4]
    for u, ee, pp in (
        ([1, 2, 3, 4, 5, 6], e, p),  # ints
        (tuple(np.arange(6.0)), e, p),  # numpy scalars
        (np.arange(6.0), e, p),  # an array
        ([0.0] * 6, tuple(e), list(p)),  # tuple / list swapped: still taken
    ):
        assert assert_output_same(u, ee, pp)[0] == "ok"
    for bad in (([0.0] * 5, e, p), ([0.0] * 6, e, p[:21]), ([0.0] * 6, e, "x" * 22)):
        assert outcome(kernel.imu_output, *bad) == outcome(imu.imu_output_python, *bad)
    # keywords go to the reference (which takes them, or raises its own error)
    assert outcome(lambda: kernel.imu_output([0.0] * 6, e, p=p)) == outcome(
        lambda: imu.imu_output_python([0.0] * 6, e, p=p))
    assert outcome(lambda: kernel.imu_output([0.0] * 6, e, q=p)) == outcome(
        lambda: imu.imu_output_python([0.0] * 6, e, q=p))


# ------------------------------------------------------------------------------- the model
@pytest.mark.parametrize("preset", ["industrial-mems", "tactical"])
def test_imu_model_stream_is_the_same_with_and_without_the_kernel(
    preset: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Three noise blocks of samples, one by one and in bulk, with the kernel and with the
    references: the same bytes."""
    cfg = presets.suite_config(imu=preset).imu
    rng = np.random.default_rng(2)
    u = rng.normal(size=(3000, 6)) * [3.0, 3.0, 10.0, 0.5, 0.5, 0.5]

    def run() -> tuple[bytes, bytes, bytes]:
        one = imu.ImuModel(cfg, np.random.default_rng(9), 200.0)
        block = imu.ImuModel(cfg, np.random.default_rng(9), 200.0)
        ys = np.array([one.measure_list(row) for row in u.tolist()])
        f, w = block.measure_block(u[:, :3], u[:, 3:])
        return ys.tobytes(), np.hstack((f, w)).tobytes(), one.current_bias().tobytes()

    with_kernel = run()
    monkeypatch.setattr(imu, "first_order_filter", imu.first_order_filter_python)
    monkeypatch.setattr(imu, "imu_output", imu.imu_output_python)
    assert run() == with_kernel


# ------------------------------------------------------------------------------- guidance law
def law_outcome(fn: Callable[..., Any], args: list[Any]) -> tuple[Any, ...]:
    """Controls (type and bits), the integrators after the call, or the exception."""
    args = list(args)
    args[9] = list(args[9])  # each implementation updates its own copy
    try:
        c = fn(*args)
        result: Any = (type(c).__name__, floats_key(c))
    except (ValueError, TypeError) as e:
        result = (type(e).__name__, str(e))
    return result, floats_key(args[9])


def assert_law_same(args: list[Any]) -> Any:
    got, want = law_outcome(kernel.law, args), law_outcome(guidance.law_python, args)
    assert got == want, args
    return got


def law_params() -> tuple[float, ...]:
    trim = guidance.TrimPoint(guidance.Controls(0.01, -0.05, 0.002, 0.6), 0.03, 1500.0, 0.004)
    plan = load_plan("racetrack")
    return guidance.Guidance(plan, 0.0, 1000.0, 50.0, trim)._law_params


FIN = st.floats(-1e3, 1e3)
STATE = st.tuples(
    st.floats(0.0, 1e4), st.sampled_from([0.005, 0.01, 0.02]), FIN, FIN, st.floats(0.0, 5e3),
    st.floats(-80.0, 80.0), st.floats(-80.0, 80.0), st.floats(-20.0, 20.0),
    st.floats(-5.0, 120.0), st.floats(-3.5, 3.5), st.floats(-1.6, 1.6), st.floats(-4.0, 4.0),
    st.floats(-2.0, 2.0), st.floats(-2.0, 2.0), st.floats(-2.0, 2.0), st.floats(-0.5, 0.5),
    st.floats(-0.5, 0.5), st.floats(-10.0, 1e4),
)


@settings(max_examples=80, deadline=None)
@given(STATE, st.one_of(st.none(), st.floats(-7.0, 7.0)), st.floats(-1.0, 1.0),
       st.floats(0.0, 1.2), st.booleans(), st.floats(-0.5, 0.5),
       st.tuples(st.floats(0.0, 5e3), st.floats(20.0, 80.0), st.floats(0.5, 5.0)),
       st.lists(st.floats(-0.5, 0.5), min_size=5, max_size=5))
def test_law_matches_the_reference(s: tuple[float, ...], course_err: float | None,
                                   phi_fixed: float, limit: float, pitch_direct: bool,
                                   theta_fixed: float, targets: tuple[float, float, float],
                                   integrators: list[float]) -> None:
    gin = guidance.GuidanceInput(*s)
    assert_law_same([gin, course_err, phi_fixed, limit, pitch_direct, theta_fixed, *targets,
                     integrators, law_params()])


@settings(max_examples=60, deadline=None)
@given(st.tuples(*[st.floats()] * 18), st.one_of(st.none(), st.floats()), st.floats(),
       st.floats(), st.booleans(), st.floats(), st.tuples(st.floats(), st.floats(), st.floats()),
       st.lists(st.floats(), min_size=5, max_size=5),
       st.lists(st.floats(), min_size=29, max_size=29))
def test_law_matches_the_reference_on_any_doubles(
    s: tuple[float, ...], course_err: float | None, phi_fixed: float, limit: float,
    pitch_direct: bool, theta_fixed: float, targets: tuple[float, float, float],
    integrators: list[float], params: list[float]
) -> None:
    """NaN and inf anywhere: the same values, or the same "math domain error" (sin / tan / cos
    of inf) with the integrators the reference had updated before it raised."""
    assert_law_same([guidance.GuidanceInput(*s), course_err, phi_fixed, limit, pitch_direct,
                     theta_fixed, *targets, integrators, tuple(params)])


def test_law_edge_cases_and_fallbacks() -> None:
    p = law_params()
    base = [0.0, 0.005, 0.0, 0.0, 1000.0, 50.0, 0.0, 0.0, 50.0, 0.1, 0.05, 0.0, 0.0, 0.0, 0.0,
            0.05, 0.0, 1500.0]
    targets = [1000.0, 50.0, 2.5]

    def args(s: list[Any], course: Any = 0.2, pitch_direct: Any = False) -> list[Any]:
        return [guidance.GuidanceInput(*s), course, 0.1, 0.5, pitch_direct, 0.05, *targets,
                [0.0, 0.01, -0.01, 0.0, 0.02], p]

    assert assert_law_same(args(base))[0][0] == "Controls"
    for i, v in ((9, math.inf), (10, math.inf), (9, -math.inf)):  # sin(phi), cos(theta)
        s = list(base)
        s[i] = v
        assert assert_law_same(args(s))[0][0] == "ValueError"
    for alpha in (0.15, 0.2, 0.25, 0.4):  # the angle-of-attack guard, partly and fully on
        s = list(base)
        s[15] = alpha
        assert_law_same(args(s))
        assert_law_same(args(s, course=None, pitch_direct=True))
    for phi in (-math.pi, math.pi, 3.0, -0.0, 1e-300):  # the wrap's float modulo
        s = list(base)
        s[9] = phi
        assert_law_same(args(s))
    # inputs the kernel does not take go to the reference (same result, same errors)
    for a in (
        args([*base[:4], 1000, *base[5:]]),  # an int in the state
        args(base, course=1),  # an int course error
        args(base, pitch_direct=0),  # not a bool
        [tuple(base), *args(base)[1:]],  # a plain tuple works too (fast path)
        [list(base), *args(base)[1:]],  # a list: the reference
        [*args(base)[:-1], list(p)],  # params as a list
    ):
        assert_law_same(a)
    a = args(base)
    got = law_outcome(lambda *x: kernel.law(*x[:-1], params=x[-1]), a)
    want = law_outcome(lambda *x: guidance.law_python(*x[:-1], params=x[-1]), a)
    assert got == want


def test_guidance_flies_the_same_with_and_without_the_kernel(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The law on the states of a recorded manoeuvre flight (attitude, turn and waypoint legs),
    with the kernel and with the reference: the same controls and plan progress, bit for bit."""
    with Flight(FlightConfig(), load_plan("manoeuvre")) as flight:
        states = []
        for _ in range(3000):
            states.append(flight._guidance_input(flight.time_s))
            flight.step()
        law = flight.guidance
        args = (law.plan, 0.0, 1000.0, 50.0, law._trim, law.gains)

    def fly() -> list[Any]:
        g = guidance.Guidance(*args)
        out = [[*floats_key(g.update(s)), g.leg_index] for s in states]
        return [*out, floats_key(g._integrators)]

    with_kernel = fly()
    monkeypatch.setattr(guidance, "law", guidance.law_python)
    assert fly() == with_kernel
