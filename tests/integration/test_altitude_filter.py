"""Altitude methods inside fusion.filter.NavFilter: ekf, loop, loop-mpc, loop-kf.

Synthetic flights (tests/helpers/nav_synth.py: sensor errors from the filter's own model, a
barometer 30 m off plus a Gauss-Markov bias) with a GNSS outage; faults injected into the
baro stream. One short JSBSim flight checks that ``replay(altitude=...)`` selects the method.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from fusion import earth
from fusion.config import ALTITUDE_METHODS, AltitudeConfig, FilterConfig
from fusion.estimate import AltitudeStatus, NavEstimate
from fusion.filter import NavFilter
from physconst.isa import isa_pressure_pa as height_to_pressure
from sim.samples import BaroSample, ImuSample
from tests.helpers.nav_synth import Flight, Prepared, SensorErrors, make_scenario, prepare

CFG = FilterConfig()
ERRORS = SensorErrors.from_config(CFG)
OUTAGE = (50.0, 100.0)
IMU_RATE_HZ = 50.0
BARO_RATE_HZ = 25.0
GATE_M = CFG.altitude.channel.monitor.gate_m
ACCEL_STEP_MPS2 = 0.05
"""Vertical accelerometer bias step at the outage start, unknown to the filter (5 mg): a free
inertial vertical drifts 0.5 * 0.05 * 50^2 = 62 m in the 50 s outage."""


@pytest.fixture(scope="module")
def flight() -> Prepared:
    """110 s: climb 3 m/s (10-35 s), turns, a climb and a descent inside the outage."""
    return prepare(
        Flight(
            duration_s=110.0,
            turns=[(20.0, 32.0, 0.15), (80.0, 90.0, -0.15)],
            climbs=[(10.0, 35.0, 3.0), (52.0, 72.0, 2.5), (78.0, 105.0, -2.0)],
        ),
        IMU_RATE_HZ,
    )


@pytest.fixture(scope="module")
def samples(flight: Prepared) -> list[object]:
    """The sensor stream, with the accelerometer bias step from the outage start."""
    sc = make_scenario(
        flight, np.random.default_rng(7), ERRORS, imu_rate_hz=IMU_RATE_HZ,
        baro_rate_hz=BARO_RATE_HZ, gnss_outages=[OUTAGE],
    )  # fmt: skip
    out: list[object] = []
    for s in sc.samples:
        if isinstance(s, ImuSample) and s.time_us * 1e-6 >= OUTAGE[0]:
            f = np.asarray(s.specific_force_b_mps2) + np.array([0.0, 0.0, ACCEL_STEP_MPS2])
            s = dataclasses.replace(s, specific_force_b_mps2=f)
        out.append(s)
    return out


def config(method: str) -> FilterConfig:
    return CFG.model_copy(update={"altitude": AltitudeConfig.model_validate({"method": method})})


def run(nav: NavFilter, stream: list[Any]) -> list[NavEstimate]:
    out: list[NavEstimate] = []
    for s in stream:
        out.extend(nav.step(s))
    return out


@dataclasses.dataclass
class Result:
    t: np.ndarray
    err_v: np.ndarray
    err_h: np.ndarray
    dh_est: np.ndarray
    dh_true: np.ndarray
    est: list[NavEstimate]
    nav: NavFilter


def evaluate(flight: Prepared, method: str, stream: list[object]) -> Result:
    nav = NavFilter(config(method))
    est = run(nav, stream)
    t = np.array([e.time_us for e in est]) * 1e-6
    kin = flight.traj(t)
    h_est = np.array([e.alt_msl_m for e in est])
    err_h = np.array(
        [
            math.hypot(*earth.ned_offset_m(e.lat_rad, e.lon_rad, e.alt_msl_m, *k)[:2])
            for e, k in zip(est, kin.lla, strict=True)
        ]
    )
    return Result(t, h_est - kin.lla[:, 2], err_h, np.diff(h_est), np.diff(kin.lla[:, 2]), est, nav)


@pytest.fixture(scope="module")
def results(flight: Prepared, samples: list[object]) -> dict[str, Result]:
    res = {m: evaluate(flight, m, samples) for m in ALTITUDE_METHODS}
    # The free inertial vertical: the EKF without any baro sample in the outage.
    no_baro = [
        s
        for s in samples
        if not (isinstance(s, BaroSample) and OUTAGE[0] <= s.time_us * 1e-6 < OUTAGE[1])
    ]
    res["free"] = evaluate(flight, "ekf", no_baro)
    return res


def in_outage(r: Result) -> np.ndarray:
    return (r.t >= OUTAGE[0]) & (r.t < OUTAGE[1])


# --------------------------------------------------------------------------- methods


def test_loop_methods_keep_the_altitude_bounded_where_free_inertial_diverges(
    results: dict[str, Result],
) -> None:
    # GIVEN a 60 s outage with an unknown 5 mg vertical accelerometer bias step
    free = results["free"]
    k_end = int(np.searchsorted(free.t, OUTAGE[1])) - 1
    # THEN the free inertial vertical is off by tens of metres at the end of the outage
    assert abs(free.err_v[k_end]) > 40.0
    for m in ALTITUDE_METHODS:
        r = results[m]
        # AND every method that uses the barometer stays within metres (the baro's Gauss-Markov
        # bias, 5 m / 1000 s, drifts ~1.6 m (1 sigma) in 50 s); the loop absorbs the bias step
        # in its a_c within seconds, the EKF more slowly (its baro-bias state takes part of it)
        bound = 10.0 if m == "ekf" else 4.0
        assert np.max(np.abs(r.err_v[in_outage(r)])) < bound, m
        # and with GNSS on (after the first 20 s) within the GNSS height noise
        on = (r.t > 20.0) & ~in_outage(r)
        assert np.sqrt(np.mean(r.err_v[on] ** 2)) < 2.5, m


def test_horizontal_solution_not_degraded_by_the_altitude_method(
    results: dict[str, Result],
) -> None:
    ekf = results["ekf"]
    for m in ("loop", "loop-mpc", "loop-kf"):
        r = results[m]
        assert np.array_equal(r.t, ekf.t)
        # GIVEN a healthy barometer THEN the EKF (and so the horizontal) is the ekf method's:
        # the channel only replaces the output vertical (see fusion.filter)
        np.testing.assert_allclose(r.err_h, ekf.err_h, atol=1e-6)
        assert (
            np.sqrt(np.mean(r.err_h[in_outage(r)] ** 2))
            <= np.sqrt(np.mean(ekf.err_h[in_outage(ekf)] ** 2)) + 1e-6
        )


def test_output_vertical_comes_from_the_channel(results: dict[str, Result]) -> None:
    for m in ("loop", "loop-mpc", "loop-kf"):
        r = results[m]
        ch = r.nav.altitude_channel
        assert ch is not None and ch.method == m
        last = r.nav.estimate()
        assert last is not None
        assert last.alt_msl_m == pytest.approx(ch.height_m)
        assert last.v_ned_mps[2] == pytest.approx(-ch.vz_mps)
        # the EKF's own height differs (it is not the output)
        ins = r.nav.ins_state
        assert ins is not None and ins.alt_msl_m != last.alt_msl_m
    assert results["ekf"].nav.altitude_channel is None


def test_altitude_status_reports_calibration_and_compensator(results: dict[str, Result]) -> None:
    for m in ("loop", "loop-mpc", "loop-kf"):
        r = results[m]
        st = [e.altitude for e in r.est]
        assert all(isinstance(a, AltitudeStatus) and a.method == m for a in st)
        before = [a for a, t in zip(st, r.t, strict=True) if 40.0 < t < OUTAGE[0]]
        during = [a for a, t in zip(st, r.t, strict=True) if OUTAGE[0] + 2.0 < t < OUTAGE[1]]
        assert before and during
        # GIVEN a barometer 30 m high (+ a 5 m Gauss-Markov bias) THEN P4's calibration
        # (s, b) learned from GNSS height brings the baro height to the truth (s and b
        # separately are poorly observable over a 75 m climb; their sum is what matters)
        assert all(a is not None and a.initialised and a.gnss_valid and a.in_use for a in before)
        sel = (r.t > 40.0) & (r.t < OUTAGE[0])
        true_h = np.array([e.alt_msl_m for e in r.est])[sel] - r.err_v[sel]
        baro_h = np.array([a.baro_height_m for a in before if a is not None])
        assert abs(np.mean(baro_h - true_h)) < 2.5
        assert before[-1] is not None and before[-1].calibration_bias_m < -10.0
        # AND during the outage the calibration is frozen and GNSS is not valid
        assert all(a is not None and a.calibration_frozen and not a.gnss_valid for a in during)
        assert r.est[-1].health.altitude_calibration_updates > 0
        last = st[-1]
        assert last is not None
        if m == "loop":
            assert last.correction_m == 0.0 and last.compensator_steps == 0
        else:
            assert last.compensator_steps > 0 and math.isfinite(last.correction_m)
    ekf = results["ekf"].est[-1].altitude
    assert ekf is not None and ekf.method == "ekf" and not ekf.initialised


def test_health_stays_integer_counters_for_the_status_payload(
    results: dict[str, Result],
) -> None:
    from hil.bus import status_payload

    for m in ALTITUDE_METHODS:
        payload = status_payload(results[m].est[-1])
        assert payload["health"]["baro_glitches"] == 0
        assert payload["health"]["baro_frozen"] == 0


# --------------------------------------------------------------------------- bad baro input


INVALID = ((30.0, 32.0), (80.0, 82.0))
FROZEN = (64.0, 84.0)
GLITCHES = ((45.0, 45.04), (70.0, 72.0), (88.0, 88.5))


def _faulty(samples: list[object], fault: str) -> tuple[list[object], int]:
    """A copy of the stream with baro faults; returns it and the number of faulty samples."""
    out: list[object] = []
    n = 0
    stuck: float | None = None
    bad_p = (0.0, -50.0, math.nan, math.inf, 2.0e5, 50.0)  # <= 0, NaN, beyond the model
    for s in samples:
        if isinstance(s, BaroSample):
            t = s.time_us * 1e-6
            p: float | None = None
            if fault == "invalid" and any(a <= t < b for a, b in INVALID):
                p = bad_p[n % len(bad_p)]
            elif fault == "frozen" and FROZEN[0] <= t < FROZEN[1]:  # stuck in a 2.5 m/s climb
                stuck = s.pressure_pa if stuck is None else stuck
                p = stuck
            elif fault == "glitch":
                if abs(t - GLITCHES[0][0]) < 1e-3:  # one spike, -170 m
                    p = height_to_pressure(_isa_height(s.pressure_pa) - 170.0)
                elif GLITCHES[1][0] <= t < GLITCHES[1][1]:  # a 2 s burst, +130 m
                    p = height_to_pressure(_isa_height(s.pressure_pa) + 130.0)
                elif GLITCHES[2][0] <= t < GLITCHES[2][1]:  # 0.5 s, +6 m (inside the gate)
                    p = height_to_pressure(_isa_height(s.pressure_pa) + 6.0)
            if p is not None:
                s = dataclasses.replace(s, pressure_pa=p)
                n += 1
        out.append(s)
    return out, n


def _isa_height(p: float) -> float:
    from physconst.isa import pressure_altitude_m as pressure_to_height

    return pressure_to_height(p)


def _max_jump(r: Result, windows: tuple[tuple[float, float], ...]) -> float:
    """Largest change of the altitude error between consecutive outputs (50 Hz) from 1 s
    before to 5 s after each fault window (not the GNSS return's correction), m."""
    sel = np.zeros(len(r.dh_est), bool)
    for a, b in windows:
        sel |= (r.t[1:] > a - 1.0) & (r.t[1:] < b + 5.0)
    return float(np.max(np.abs(r.dh_est - r.dh_true)[sel]))


@pytest.mark.parametrize("method", ALTITUDE_METHODS)
def test_invalid_pressure_counted_and_not_used(
    flight: Prepared, samples: list[object], results: dict[str, Result], method: str
) -> None:
    stream, n = _faulty(samples, "invalid")
    r = evaluate(flight, method, stream)
    h = r.est[-1].health
    # GIVEN pressures <= 0, NaN, Inf and beyond the atmosphere model (-5 .. 47 km)
    # THEN every one is counted as invalid and none reaches the altitude
    assert n >= 95 and h.baro_invalid == n
    assert _max_jump(r, INVALID) < 0.5
    clean = results[method]
    # (the samples they replaced are missing: 2 s bridged on the held sample and inertially)
    near = np.zeros(len(r.t), bool)
    for a, b in INVALID:
        near |= (r.t > a - 1.0) & (r.t < b + 5.0)
    # (the EKF, which had not fully learned the accelerometer bias step, drifts more in 2 s)
    assert np.max(np.abs(r.err_v - clean.err_v)[near]) < (2.0 if method == "ekf" else 1.0)


@pytest.mark.parametrize("method", ALTITUDE_METHODS)
def test_frozen_baro_detected(flight: Prepared, samples: list[object], method: str) -> None:
    stream, n = _faulty(samples, "frozen")
    r = evaluate(flight, method, stream)
    h = r.est[-1].health
    freeze_s = CFG.altitude.channel.monitor.freeze_time_s
    # GIVEN the barometer stuck for 20 s (25 Hz) while the aircraft climbs at 2.5 m/s
    # THEN after freeze_time_s every stuck sample is counted and not used, and the EKF got
    # none after ekf_repeat_hold_s
    held_s = freeze_s - CFG.altitude.ekf_repeat_hold_s
    assert h.baro_frozen >= n - round(freeze_s * BARO_RATE_HZ) - 1
    assert h.baro_repeats_held >= round(held_s * BARO_RATE_HZ) - 1
    flagged = [
        e.altitude.baro_frozen for e, t in zip(r.est, r.t, strict=True)
        if FROZEN[0] + freeze_s + 0.5 < t < FROZEN[1] and e.altitude is not None
    ]  # fmt: skip
    assert flagged and all(flagged)
    # AND the altitude never jumps by more than the gate (for the loop methods the rollback
    # of the 2 s of stuck readings is the largest step: 2.5 m/s x 2 s)
    assert _max_jump(r, (FROZEN,)) < GATE_M
    if method != "ekf":
        # the stuck readings had pulled the loop off the climb: it was rolled back
        ch = r.nav.altitude_channel
        assert ch is not None and ch.health.freeze_rollbacks == 1
        # and follows the climb inertially (the EKF's own vertical drifts further: it had not
        # learned the accelerometer bias step as fully as the loop's a_c)
        assert np.max(np.abs(r.err_v[r.t > 20.0])) < GATE_M


@pytest.mark.parametrize("method", ALTITUDE_METHODS)
def test_glitches_never_jump_the_altitude_beyond_the_gate(
    flight: Prepared, samples: list[object], method: str
) -> None:
    stream, _n = _faulty(samples, "glitch")
    r = evaluate(flight, method, stream)
    h = r.est[-1].health
    # GIVEN a -170 m spike, a 2 s burst of +130 m and a 0.5 s step of +6 m
    # THEN the altitude never jumps by more than the gate, and the large ones are rejected
    assert _max_jump(r, GLITCHES) < GATE_M
    after = r.t > 20.0
    assert np.max(np.abs(r.err_v[after])) < GATE_M
    if method == "ekf":
        assert h.baro_rejected > 0  # the EKF's chi-square gate
    else:
        assert h.baro_glitches >= 1 + 2 * 25  # the spike and the burst (25 Hz)
        # the large glitches do not show at all: the error stays at its usual size there
        spike = (r.t > 44.0) & (r.t < 47.0) | (r.t > 69.0) & (r.t < 74.0)
        assert np.max(np.abs(r.err_v[spike])) < 4.0


# --------------------------------------------------------------------------- selection


def test_unknown_method_lists_the_valid_ones() -> None:
    with pytest.raises(ValueError, match="loop-mpc"):
        FilterConfig.model_validate({"altitude": {"method": "baro-mpc"}})
    bad = CFG.model_copy(
        update={"altitude": AltitudeConfig().model_copy(update={"method": "baro-mpc"})}
    )
    with pytest.raises(ValueError, match="valid methods: ekf, loop, loop-mpc, loop-kf"):
        NavFilter(bad)


def test_replay_selects_the_altitude_method(tmp_path: Path) -> None:
    from hil.pipeline import SimSetup, record_flight
    from scenarios.replay import replay

    with pytest.raises(ValueError, match="valid methods: ekf, loop, loop-mpc, loop-kf"):
        replay(tmp_path / "none.tlog", tmp_path / "x", altitude="baro")
    log = tmp_path / "short.tlog"
    record_flight(SimSetup.build(plan="racetrack", duration_s=30.0, seed=3), log)
    summaries: dict[str, dict[str, Any]] = {}
    for m in ("ekf", "loop-mpc"):
        res = replay(log, tmp_path / m, altitude=m, settle_s=5.0)
        summaries[m] = res.summary
    assert summaries["loop-mpc"]["altitude"] == "loop-mpc"
    # the channel ran (it calibrated the baro from GNSS) only with the loop method
    assert summaries["loop-mpc"]["health"]["filter"]["altitude_calibration_updates"] > 0
    assert summaries["ekf"]["health"]["filter"]["altitude_calibration_updates"] == 0
