"""Tests of the JSBSim adapter (sim.flight), its guidance law and the flight plans (sim.plans).

Physics invariants (1 g in level flight, inertial rates, kinematic consistency of specific
force and velocity), SI conversions, bad input, FlightEnded, determinism, and every packaged
plan flown for 30 minutes by c172x and c310.
"""

from __future__ import annotations

import contextlib
import math
import os
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
import pytest
from pydantic import ValidationError

import sim.aircraft as aircraft_module
import sim.flight as flight_module
from sim.flight import (
    FT_M,
    PSF_PA,
    Flight,
    FlightConfig,
    FlightEnded,
    StartState,
    available_aircraft,
    suggested_start,
)
from sim.plans import FlightPlan, Leg, available_plans, load_plan

# --- an Earth model identical to JSBSim 1.3.3's (FGInertial: WGS-84 ellipsoid, J2 gravity) --
_GM = 14.0764417572e15 * FT_M**3
_A = 20925646.32546 * FT_M
_B = 20855486.5951 * FT_M
_J2 = 1.08262982e-3
_W_IE = 7.292115e-5  # JSBSim's planet rotation rate, rad/s (FGInertial)
_E2 = 1.0 - (_B / _A) ** 2


def _c_en(lat: float, lon: float) -> np.ndarray:
    """Columns: the N, E, D axes in ECEF."""
    sl, cl, so, co = math.sin(lat), math.cos(lat), math.sin(lon), math.cos(lon)
    return np.array([[-sl * co, -so, -cl * co], [-sl * so, co, -cl * so], [cl, 0.0, -sl]])


def _ecef(lat: float, lon: float, h: float) -> np.ndarray:
    s, c = math.sin(lat), math.cos(lat)
    n = _A / math.sqrt(1.0 - _E2 * s * s)
    return np.array(
        [(n + h) * c * math.cos(lon), (n + h) * c * math.sin(lon), (n * (1 - _E2) + h) * s]
    )


def _gravity_n(lat: float, lon: float, h: float) -> np.ndarray:
    """JSBSim's J2 gravitation plus the centrifugal term, in NED, m/s^2."""
    r = _ecef(lat, lon, h)
    rn = float(np.linalg.norm(r))
    s2 = (r[2] / rn) ** 2
    pre = 1.5 * _J2 * (_A / rn) ** 2
    g = _GM / rn**2
    g_e = (
        -g
        * np.array([(1 + pre * (1 - 5 * s2)), (1 + pre * (1 - 5 * s2)), (1 + pre * (3 - 5 * s2))])
        * r
        / rn
    )
    w = np.array([0.0, 0.0, _W_IE])
    return _c_en(lat, lon).T @ (g_e - np.cross(w, np.cross(w, r)))


def _rates_n(lat: float, h: float, v_n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Earth rate and transport rate in NED, rad/s."""
    s = math.sin(lat)
    d = 1.0 - _E2 * s * s
    r_n = _A / math.sqrt(d)
    r_m = r_n * (1.0 - _E2) / d
    w_ie = _W_IE * np.array([math.cos(lat), 0.0, -s])
    w_en = np.array([v_n[1] / (r_n + h), -v_n[0] / (r_m + h), -v_n[1] * math.tan(lat) / (r_n + h)])
    return w_ie, w_en


def _c_nb(q: np.ndarray) -> np.ndarray:
    w, x, y, z = q
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def _euler(q: np.ndarray) -> tuple[float, float, float]:
    w, x, y, z = q
    phi = math.atan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
    theta = math.asin(max(-1.0, min(1.0, 2 * (w * y - z * x))))
    psi = math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    return phi, theta, psi


# --- plans ------------------------------------------------------------------------------


def test_packaged_plans_load_and_are_data() -> None:
    names = available_plans()
    assert {"cruise", "racetrack", "climb-descent", "survey", "manoeuvre"} <= set(names)
    for name in names:
        plan = load_plan(name)
        assert plan.name == name
        assert plan.repeat
        assert len(plan.legs) >= 1


def test_unknown_plan_names_the_valid_ones() -> None:
    with pytest.raises(ValueError, match="cruise") as info:
        load_plan("loop-the-loop")
    message = str(info.value)
    assert "\n" not in message
    for name in available_plans():
        assert name in message


def test_plan_from_a_yaml_path(tmp_path: Path) -> None:
    path = tmp_path / "box.yaml"
    path.write_text("legs:\n  - {kind: waypoint, x_m: 1000, y_m: 0, alt_m: 50}\n")
    plan = load_plan(str(path))
    assert plan.name == "box"
    assert plan.legs[0].alt_m == 50.0


def test_legs_reject_fields_of_other_kinds() -> None:
    with pytest.raises(ValidationError, match="x_m"):
        Leg(kind="heading", heading_deg=10.0, duration_s=5.0, x_m=3.0)
    with pytest.raises(ValidationError, match="duration_s"):
        Leg(kind="attitude", bank_deg=20.0)
    with pytest.raises(ValidationError, match="bank_speed"):
        Leg.model_validate({"kind": "turn", "turn_deg": 90, "bank_speed": 3})


# --- configuration and bad input ------------------------------------------------------------


def test_unknown_aircraft_names_the_valid_ones() -> None:
    with pytest.raises(ValueError, match="c172x") as info:
        Flight(FlightConfig(aircraft="zeppelin9000"), load_plan("cruise"))
    assert "c310" in str(info.value)
    assert "\n" not in str(info.value)


def test_config_ranges_are_validated() -> None:
    with pytest.raises(ValidationError, match="rate_hz"):
        FlightConfig(rate_hz=1000.0)
    with pytest.raises(ValidationError, match="turbulence"):
        FlightConfig(turbulence=2.0)
    with pytest.raises(ValidationError, match="lat_deg"):
        StartState(lat_deg=95.0)


def test_wheel_aircraft_are_offered() -> None:
    names = available_aircraft()
    assert {"c172x", "c310", "pa28", "c182", "f16", "737"} <= set(names)
    assert "ball" not in names and "weather-balloon" not in names
    assert suggested_start("f16").airspeed_mps > 50.0
    with pytest.raises(ValueError, match="c172x"):
        suggested_start("ball")


def _fly_briefly(aircraft: str, steps: int = 100) -> None:
    config = FlightConfig(aircraft=aircraft, rate_hz=50.0, start=suggested_start(aircraft))
    with Flight(config, load_plan("racetrack")) as flight:
        for _ in range(steps):
            flight.step()


# c310 fails its first trim (JSBSim issue #1440, JSBSim reports the axis it cannot trim);
# Short_S23 loads with XML warnings about properties its engine systems define twice.
_CHATTY_AIRCRAFT = ("c310", "Short_S23")


def test_jsbsim_prints_nothing_while_loading_trimming_and_flying(
    capfd: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    def redirect(*_args: object) -> None:
        raise AssertionError("sim.flight must not redirect file descriptors")

    with monkeypatch.context() as m:
        m.setattr(os, "dup", redirect)
        m.setattr(os, "dup2", redirect)
        for aircraft in _CHATTY_AIRCRAFT:
            _fly_briefly(aircraft)
    assert capfd.readouterr() == ("", "")


def test_the_quiet_flight_test_would_see_jsbsim_output(
    capfd: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    # guard against a vacuous check above: without the discarding logger JSBSim does print
    monkeypatch.setattr(flight_module, "jsbsim_log_discarded", contextlib.nullcontext)
    monkeypatch.setattr(aircraft_module, "jsbsim_log_discarded", contextlib.nullcontext)
    for aircraft in _CHATTY_AIRCRAFT:
        _fly_briefly(aircraft)
    out, err = capfd.readouterr()
    assert "trimmable" in out + err
    assert "already defined" in out + err


# --- physics ----------------------------------------------------------------------------


@pytest.fixture(scope="module")
def level_c172x() -> list:
    """20 s of straight-and-level c172x cruise at 100 Hz (after the trimmed start)."""
    with Flight(FlightConfig(rate_hz=100.0), load_plan("cruise")) as flight:
        return [flight.truth()] + [flight.step() for _ in range(2000)]


def test_level_flight_feels_one_g_and_no_rotation(level_c172x: list) -> None:
    for truth in level_c172x[::10]:
        lat, h = truth.lat_rad, truth.alt_msl_m
        f_n = _c_nb(truth.q_nb) @ truth.specific_force_b_mps2
        g_n = _gravity_n(lat, truth.lon_rad, h)
        # level, unaccelerated: specific force is the reaction to gravity
        assert np.allclose(f_n, -g_n, atol=0.05), (f_n, g_n)
        assert abs(np.linalg.norm(truth.specific_force_b_mps2) - 9.805) < 0.01
        # rates: c172x's aileron actuators have 0.005 rad of hysteresis, so the wings-level
        # loop keeps a +-0.3 deg limit cycle with roll rates of ~1e-3 rad/s
        assert np.abs(truth.omega_b_rps).max() < 5e-3
    # JSBSim's trim leaves the body at rest w.r.t. the Earth (p = q = r = 0), so the gyro
    # of the trimmed start sees exactly the Earth rate: the rates are inertial ones
    first = level_c172x[0]
    w_ie, _ = _rates_n(first.lat_rad, first.alt_msl_m, first.v_ned_mps)
    assert np.allclose(first.omega_b_rps, _c_nb(first.q_nb).T @ w_ie, atol=1e-7)
    assert np.linalg.norm(first.omega_b_rps) == pytest.approx(7.292115e-5, rel=1e-4)


def test_start_state_and_si_conversions(level_c172x: list) -> None:
    truth = level_c172x[0]
    assert truth.time_us == 0
    assert math.degrees(truth.lat_rad) == pytest.approx(47.0, abs=1e-9)
    assert math.degrees(truth.lon_rad) == pytest.approx(8.0, abs=1e-9)
    assert truth.alt_msl_m == pytest.approx(1000.0, abs=0.01)
    assert truth.airspeed_mps == pytest.approx(50.0, abs=0.01)
    assert float(np.hypot(*truth.v_ned_mps[:2])) == pytest.approx(50.0, abs=0.05)
    # ISA (US 1976) at 1000 m geometric = 999.84 m geopotential: 281.651 K, 89 876 Pa
    h_geopot = 6356766.0 * 1000.0 / (6356766.0 + 1000.0)
    t_isa = 288.15 - 0.0065 * h_geopot
    p_isa = 101325.0 * (t_isa / 288.15) ** (9.80665 * 0.0289644 / (8.3144598 * 0.0065))
    assert truth.temperature_k == pytest.approx(t_isa, abs=0.01)
    assert truth.static_pressure_pa == pytest.approx(p_isa, abs=5.0)
    # calibrated airspeed ~ TAS * sqrt(rho / rho0) at low Mach
    sigma = (p_isa / 101325.0) * (288.15 / t_isa)
    assert truth.indicated_airspeed_mps == pytest.approx(50.0 * math.sqrt(sigma), abs=0.1)
    # the conversion constants themselves
    assert FT_M == 0.3048
    assert PSF_PA == pytest.approx(47.880258980, rel=1e-9)
    # heading 0: flying north, wings level
    phi, theta, psi = _euler(truth.q_nb)
    assert abs(phi) < 0.01 and abs(psi) < 0.01 and 0.0 < theta < 0.1


def test_time_base() -> None:
    with Flight(FlightConfig(rate_hz=300.0), load_plan("cruise")) as flight:
        assert flight.dt_s == pytest.approx(1.0 / 300.0)
        for _ in range(300):
            truth = flight.step()
        assert truth.time_us == 1_000_000 == flight.time_us


def test_specific_force_and_rates_are_consistent_with_the_kinematics() -> None:
    """dv_n/dt = C_nb f_b + g_n - (2 w_ie + w_en) x v_n, and dC_nb/dt = C_nb [w_nb x] with
    w_nb = w_ib - C_bn (w_ie + w_en), over three minutes of the manoeuvre plan (bank to
    45 deg and more, pitch changes), by finite differences of the truth itself."""
    rate = 100.0
    with Flight(FlightConfig(rate_hz=rate), load_plan("manoeuvre")) as flight:
        states = [flight.truth()] + [flight.step() for _ in range(int(180 * rate))]
    dt = 1.0 / rate
    v = np.array([s.v_ned_mps for s in states])
    f_b = np.array([s.specific_force_b_mps2 for s in states])
    w_ib = np.array([s.omega_b_rps for s in states])
    c_nb = np.array([_c_nb(s.q_nb) for s in states])
    w_in = []
    g_n = []
    for s in states:
        w_ie, w_en = _rates_n(s.lat_rad, s.alt_msl_m, s.v_ned_mps)
        w_in.append((2 * w_ie + w_en, w_ie + w_en))
        g_n.append(_gravity_n(s.lat_rad, s.lon_rad, s.alt_msl_m))
    coriolis_rate = np.array([w[0] for w in w_in])
    nav_rate = np.array([w[1] for w in w_in])
    # velocity: central differences (JSBSim integrates velocity with Adams-Bashforth 2)
    vdot = (v[2:] - v[:-2]) / (2 * dt)
    model = np.einsum("kij,kj->ki", c_nb, f_b) + np.array(g_n) - np.cross(coriolis_rate, v)
    accel = vdot - model[1:-1]
    # attitude: forward differences (JSBSim integrates attitude with the rate at the step start)
    skew = np.einsum("kji,kjl->kil", c_nb[:-1], (c_nb[1:] - c_nb[:-1]) / dt)
    w_nb = np.stack([skew[:, 2, 1], skew[:, 0, 2], skew[:, 1, 0]], axis=1)
    expected_w_nb = w_ib - np.einsum("kji,kj->ki", c_nb, nav_rate)
    rates = w_nb - expected_w_nb[:-1]
    bank = np.degrees(np.abs([_euler(s.q_nb)[0] for s in states]))
    accel_rms = float(np.sqrt(np.mean(accel**2)))
    print(
        f"\nkinematic residual: accel max {np.abs(accel).max():.2e} m/s^2, rms {accel_rms:.2e}, "
        f"|mean| {np.abs(accel.mean(axis=0)).max():.1e}; rate max {np.abs(rates).max():.2e} "
        f"rad/s, rms {np.sqrt(np.mean(rates**2)):.1e}; max bank {bank.max():.0f} deg"
    )
    assert bank.max() > 40.0  # manoeuvres were flown
    assert np.abs(accel).max() < 0.03  # a few cm/s^2 per sample at most
    assert accel_rms < 1e-3
    assert np.abs(accel.mean(axis=0)).max() < 1e-5  # no bias a strapdown would integrate
    assert np.abs(rates).max() < 1e-3


# --- determinism ------------------------------------------------------------------------


def _turbulent_run(seed: int) -> list:
    config = FlightConfig(rate_hz=100.0, turbulence=0.6, seed=seed, wind_ned_mps=(3.0, -4.0, 0.0))
    with Flight(config, load_plan("racetrack")) as flight:
        return [flight.step() for _ in range(1500)]


def _same(a: list, b: list) -> bool:
    fields = (
        "time_us", "lat_rad", "lon_rad", "alt_msl_m", "v_ned_mps", "q_nb", "omega_b_rps",
        "specific_force_b_mps2", "static_pressure_pa", "temperature_k", "airspeed_mps",
        "indicated_airspeed_mps",
    )  # fmt: skip
    return all(
        np.array_equal(getattr(x, name), getattr(y, name))
        for x, y in zip(a, b, strict=True)
        for name in fields
    )


def test_same_config_gives_bit_identical_truth() -> None:
    first, second, other = _turbulent_run(7), _turbulent_run(7), _turbulent_run(8)
    assert _same(first, second)
    assert not _same(first, other)  # the seed reaches the turbulence model
    # turbulence and wind are acting: airspeed differs from ground speed and wanders
    airspeed = np.array([t.airspeed_mps for t in first])
    ground = np.array([np.hypot(*t.v_ned_mps[:2]) for t in first])
    assert np.std(airspeed) > 0.1
    assert np.abs(airspeed - ground).max() > 2.0


def test_steady_wind_moves_the_air_mass() -> None:
    """A configured wind reaches JSBSim and survives run_ic and the trim (which re-initialise
    the wind from the initial condition)."""

    def air_minus_ground(wind: tuple[float, float, float]) -> float:
        cfg = FlightConfig(aircraft="c172x", rate_hz=100.0, wind_ned_mps=wind,
                           start=StartState(lat_deg=47.0, lon_deg=8.0, alt_msl_m=1000.0,
                                            heading_deg=0.0, airspeed_mps=50.0))
        with Flight(cfg, load_plan("cruise")) as f:
            truths = [f.step() for _ in range(2000)]
        return float(np.mean([t.airspeed_mps - np.linalg.norm(t.v_ned_mps) for t in truths]))

    # flying north: a 6 m/s wind from the north is a 6 m/s headwind
    assert air_minus_ground((0.0, 0.0, 0.0)) == pytest.approx(0.0, abs=0.3)
    assert air_minus_ground((-6.0, 0.0, 0.0)) == pytest.approx(6.0, abs=0.5)


# --- the flight ends cleanly when it must ---------------------------------------------------


def test_stall_ends_the_flight() -> None:
    plan = FlightPlan(
        name="stall",
        legs=(Leg(kind="attitude", pitch_deg=25.0, duration_s=600.0, airspeed_mps=20.0),),
    )
    with Flight(FlightConfig(rate_hz=50.0, stall_alpha_deg=14.0), plan) as flight:
        with pytest.raises(FlightEnded) as info:
            flight.run_for(300.0)
        assert "stall" in info.value.reason
        assert 1.0 < info.value.time_s < 300.0
        with pytest.raises(FlightEnded):  # and it stays ended
            flight.step()
        assert flight.truth().time_us <= round(info.value.time_s * 1e6)


def test_hitting_the_ground_ends_the_flight() -> None:
    plan = FlightPlan(
        name="dive",
        legs=(Leg(kind="heading", heading_deg=0.0, duration_s=900.0, alt_m=-2000.0,
                  climb_rate_mps=8.0),),
    )  # fmt: skip
    config = FlightConfig(rate_hz=50.0, start=StartState(alt_msl_m=300.0))
    with Flight(config, plan) as flight:
        with pytest.raises(FlightEnded) as info:
            flight.run_for(600.0)
    assert "ground" in info.value.reason
    assert 20.0 < info.value.time_s < 200.0


# --- other aircraft of the wheel: load, trim, fly straight and level ------------------------


@pytest.mark.parametrize("aircraft", ["pa28", "c182", "DHC6", "f16", "737", "A320"])
def test_other_aircraft_trim_and_fly_level(aircraft: str) -> None:
    start = suggested_start(aircraft, heading_deg=90.0)
    config = FlightConfig(aircraft=aircraft, rate_hz=50.0, start=start)
    with Flight(config, load_plan("cruise")) as flight:
        truths = [flight.run_for(1.0) for _ in range(60)]
    for truth in truths:
        phi, _, psi = _euler(truth.q_nb)
        assert abs(truth.alt_msl_m - start.alt_msl_m) < 20.0
        assert abs(truth.airspeed_mps - start.airspeed_mps) < 3.0
        assert abs(math.degrees(phi)) < 5.0
        assert abs(math.degrees(psi) - 90.0) < 5.0


# --- every plan, 30 minutes, c172x and c310 -------------------------------------------------


def _fly_half_hour(job: tuple[str, str]) -> tuple[str, str, str, float, float, float]:
    aircraft, plan = job
    with Flight(FlightConfig(aircraft=aircraft, rate_hz=50.0), load_plan(plan)) as flight:
        lowest, slowest = math.inf, math.inf
        try:
            for _ in range(180):
                truth = flight.run_for(10.0)
                lowest = min(lowest, truth.alt_msl_m)
                slowest = min(slowest, truth.airspeed_mps)
        except FlightEnded as ended:
            return aircraft, plan, ended.reason, ended.time_s, lowest, slowest
        return aircraft, plan, "", flight.time_s, lowest, slowest


@pytest.mark.slow
def test_every_plan_flies_thirty_minutes_with_c172x_and_c310() -> None:
    jobs = [(a, p) for a in ("c172x", "c310") for p in available_plans()]
    with ProcessPoolExecutor(max_workers=2) as pool:
        results = list(pool.map(_fly_half_hour, jobs))
    for aircraft, plan, ended, time_s, lowest, slowest in results:
        assert ended == "", f"{aircraft} {plan}: {ended} at {time_s:.0f} s"
        assert time_s == pytest.approx(1800.0)
        assert lowest > 800.0, (aircraft, plan, lowest)
        assert slowest > 35.0, (aircraft, plan, slowest)
