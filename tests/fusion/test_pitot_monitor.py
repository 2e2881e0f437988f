"""The pitot monitor's stuck check judges the airspeed change by a cue that does not need the
wind estimate: the inertial acceleration along the air-relative flight path."""

from __future__ import annotations

import math

import numpy as np

from fusion.aiding.pitot_monitor import PitotMonitor
from fusion.config import AirspeedTuning
from physconst.airdata import impact_pressure_pa, true_airspeed_mps

STATIC_PA = 90_000.0
TEMP_K = 280.0
G = 9.80665


def _fly(
    tas_of_t: object, bank_rad: float, heading_error_rad: float,
    wind_error_ne_mps: tuple[float, float], stuck_from_s: float | None, duration_s: float,
) -> list[tuple[float, str]]:  # fmt: skip
    """A level flight at constant bank (a coordinated turn, or wings level with
    ``bank_rad = 0``) in a 5 m/s wind, fed to the monitor as the filter would: INS velocity
    (the true ground velocity while GNSS is good), the sum of the feedback's velocity
    corrections (the inertial velocity, propagated with the filter's wrong heading, differs
    from the GNSS-corrected one by them), the filter's wind (wrong by ``wind_error_ne_mps``),
    its attitude (heading wrong by ``heading_error_rad``) and its angle of attack (3 deg).
    Pitot readings at 20 Hz with 1 Pa noise, held from ``stuck_from_s`` on. Returns every
    batch's (time, verdict)."""
    cfg = AirspeedTuning()
    mon = PitotMonitor(cfg)
    rng = np.random.default_rng(3)
    wind = (5.0, -2.0)
    w_est = (wind[0] + wind_error_ne_mps[0], wind[1] + wind_error_ne_mps[1])
    alpha = math.radians(3.0)
    dt = 0.05
    psi = 0.3
    v_inertial = None
    held: float | None = None
    out: list[tuple[float, str]] = []
    n_batch = round(1.0 / (cfg.fuse_rate_hz * dt))
    acc: list[float] = []
    for k in range(round(duration_s / dt) + 1):
        t = k * dt
        va = tas_of_t(t)  # type: ignore[operator]
        dva = (tas_of_t(t + 1e-3) - va) / 1e-3  # type: ignore[operator]
        omega = G * math.tan(bank_rad) / va
        v = (va * math.cos(psi) + wind[0], va * math.sin(psi) + wind[1], 0.0)
        a_true = (dva * math.cos(psi) - va * omega * math.sin(psi),
                  dva * math.sin(psi) + va * omega * math.cos(psi))  # fmt: skip
        if v_inertial is None:
            v_inertial = list(v)
        # the INS integrates the true acceleration rotated by its heading error
        ce, se = math.cos(heading_error_rad), math.sin(heading_error_rad)
        corr = (v[0] - v_inertial[0], v[1] - v_inertial[1], 0.0)
        qc = impact_pressure_pa(va, STATIC_PA, TEMP_K)
        if stuck_from_s is not None and t >= stuck_from_s:
            if held is None:
                held = qc
            qc = held
        qc += float(rng.normal(0.0, cfg.diff_pressure_noise_pa))
        t_us = round(t * 1e6)
        mon.add_reading(t_us, qc)
        acc.append(qc)
        if len(acc) == n_batch:
            q = _q_nb(bank_rad, alpha, psi + heading_error_rad)
            tas = true_airspeed_mps(sum(acc) / len(acc), STATIC_PA, TEMP_K)
            verdict = mon.assess(t_us, tas, v, corr, w_est, 0.0, STATIC_PA, TEMP_K,
                                 q_nb=q, alpha_rad=alpha)  # fmt: skip
            out.append((t, verdict))
            acc = []
        v_inertial[0] += (ce * a_true[0] - se * a_true[1]) * dt
        v_inertial[1] += (se * a_true[0] + ce * a_true[1]) * dt
        psi += omega * dt
    return out


def _q_nb(roll: float, pitch: float, yaw: float) -> tuple[float, float, float, float]:
    cr, sr = math.cos(roll / 2), math.sin(roll / 2)
    cp, sp = math.cos(pitch / 2), math.sin(pitch / 2)
    cy, sy = math.cos(yaw / 2), math.sin(yaw / 2)
    return (cr * cp * cy + sr * sp * sy, sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy, cr * cp * sy - sr * sp * cy)  # fmt: skip


def test_a_healthy_pitot_in_a_turn_is_not_called_stuck_when_heading_and_wind_are_wrong() -> None:
    # GIVEN a steady 30 deg banked turn at a constant 50 m/s airspeed, seen by a filter whose
    # heading is 10 deg off and whose wind is 9 m/s off (after an IMU fault): the airspeed
    # it predicts from |v - w| swings by several m/s through the turn
    verdicts = _fly(lambda t: 50.0, math.radians(30.0), math.radians(10.0), (6.0, -7.0),
                    None, 60.0)  # fmt: skip
    # THEN the healthy pitot, which reads the steady airspeed, is never called stuck
    assert [t for t, v in verdicts if v == "stuck"] == []


def test_a_stuck_pitot_that_misses_an_acceleration_is_called_stuck_despite_a_wrong_wind() -> None:
    # GIVEN wings-level flight accelerating from 40 to 60 m/s over 20 s, the same wrong
    # heading and wind, and a pitot that holds its reading from 6 s on (with its noise)
    verdicts = _fly(lambda t: 40.0 + min(max(t - 2.0, 0.0), 20.0), 0.0, math.radians(10.0),
                    (6.0, -7.0), 6.0, 30.0)  # fmt: skip
    stuck = [t for t, v in verdicts if v == "stuck"]
    # THEN it is called stuck within one window and a few batches
    assert stuck and stuck[0] - 6.0 <= 6.0


def test_a_stuck_pitot_in_a_steady_turn_is_not_called_stuck() -> None:
    # GIVEN a pitot that holds its reading in a steady turn at constant airspeed (it still
    # reads the airspeed: undetectable, and harmless while it lasts)
    verdicts = _fly(lambda t: 50.0, math.radians(30.0), 0.0, (0.0, 0.0), 6.0, 40.0)
    # THEN nothing is declared
    assert [t for t, v in verdicts if v == "stuck"] == []
