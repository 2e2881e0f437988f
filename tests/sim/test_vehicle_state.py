"""Tests of the vehicle-state reports (sim.vehicle_state, Flight.vehicle_state).

Report timing on a simulated-time grid (>= 25 Hz), PX4 sign conventions checked against
JSBSim's response (a positive reported control turns the body the PX4 way), the controls of a
right turn and a climb in a real JSBSim flight, propeller rpm per engine, and the reports
through the simulator chain.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from pydantic import ValidationError

from hil.pipeline import SimChain, SimSetup
from sim.flight import Flight, FlightConfig, suggested_start
from sim.plans import FlightPlan, Leg, load_plan
from sim.samples import ActuatorSample, RpmSample
from sim.vehicle_state import (
    N_CONTROLS,
    VehicleState,
    VehicleStateConfig,
    VehicleStateReporter,
    control_range,
)

_STATE = VehicleState(controls=(0.1, -0.2, 0.0, 0.6) + (0.0,) * 12, propeller_rpm=(2000.0,))


def _report_times(rate_hz: float, step_hz: float, duration_s: float) -> list[int]:
    rep = VehicleStateReporter(VehicleStateConfig(rate_hz=rate_hz))
    times: list[int] = []
    for k in range(round(duration_s * step_hz) + 1):
        t = round(k * 1e6 / step_hz)
        times.extend(s.time_us for s in rep.step(t, lambda: _STATE)
                     if isinstance(s, ActuatorSample))
    return times


def test_reports_on_a_simulated_time_grid() -> None:
    times = _report_times(50.0, 200.0, 10.0)
    assert times[0] == 0 and len(times) == 501
    assert set(np.diff(times)) == {20_000}  # every 4th step of a 200 Hz flight
    # steps that do not divide the period (60 Hz): a report on the first step at or after
    # each grid point, so intervals of one or two steps, none longer than 1/25 s, and the
    # mean rate is the configured one
    times = _report_times(50.0, 60.0, 10.0)
    gaps = np.diff(times)
    assert set(gaps) <= {16_666, 16_667, 33_333, 33_334}
    assert gaps.max() <= 40_000
    assert abs(len(times) - 501) <= 1
    times = _report_times(25.0, 50.0, 4.0)
    assert set(np.diff(times)) == {40_000}


def test_reporter_reads_the_flight_only_when_due_and_honours_its_switches() -> None:
    calls = []

    def read() -> VehicleState:
        calls.append(1)
        return _STATE

    rep = VehicleStateReporter()
    for k in range(8):
        rep.step(k * 5_000, read)
    assert len(calls) == 2  # 200 Hz steps, 50 Hz reports
    out = VehicleStateReporter(VehicleStateConfig(actuators=False)).step(0, read)
    assert [type(s) for s in out] == [RpmSample]
    out = VehicleStateReporter(VehicleStateConfig(rpm=False)).step(0, read)
    assert [type(s) for s in out] == [ActuatorSample]
    assert VehicleStateReporter(VehicleStateConfig(actuators=False, rpm=False)).step(0, read) == []
    with pytest.raises(ValidationError):
        VehicleStateConfig(rate_hz=20.0)  # the learned vehicle models need >= 25 Hz


@pytest.mark.parametrize("aircraft", ["c172x", "c310"])
@pytest.mark.parametrize(
    ("prop", "axis", "rate_index"),
    [
        ("fcs/aileron-cmd-norm", 0, "velocities/p-rad_sec"),
        ("fcs/elevator-cmd-norm", 1, "velocities/q-rad_sec"),
        ("fcs/rudder-cmd-norm", 2, "velocities/r-rad_sec"),
    ],
)
def test_positive_reported_controls_turn_the_aircraft_the_px4_way(
    aircraft: str, prop: str, axis: int, rate_index: str
) -> None:
    """Bump one JSBSim command from trim, hold everything else (no guidance) for 0.5 s: the
    reported control moves by the bump in PX4's sign, and the body rate about that axis gets
    the sign PX4 gives a positive control (roll right, nose up, nose right)."""
    bump = 0.2
    with Flight(FlightConfig(aircraft=aircraft, rate_hz=50.0,
                             start=suggested_start(aircraft)), load_plan("cruise")) as flight:
        fdm = flight._fdm  # the test drives JSBSim directly, without the guidance law
        before = flight.vehicle_state().controls[axis]
        rate0 = fdm[rate_index]
        sign = 1.0 if axis == 0 else -1.0  # JSBSim's elevator and rudder are opposite to PX4
        fdm[prop] = fdm[prop] + sign * bump
        after = flight.vehicle_state().controls[axis]
        assert after - before == pytest.approx(bump, abs=1e-9)
        for _ in range(25):
            fdm.run()
        rate = fdm[rate_index] - rate0
    # measured 0.04-0.22 rad/s for these aircraft; the other axes stay below 0.03 rad/s
    assert rate > 0.02


def _fly(plan: FlightPlan, duration_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Times (s), bank (rad) and climb rate (m/s) per step, and the reported controls."""
    rows, controls = [], []
    with Flight(FlightConfig(rate_hz=50.0), plan) as flight:
        for _ in range(round(duration_s * 50.0)):
            truth = flight.step()
            q = truth.q_nb
            phi = math.atan2(2 * (q[0] * q[1] + q[2] * q[3]), 1 - 2 * (q[1] ** 2 + q[2] ** 2))
            rows.append((truth.time_us * 1e-6, phi, -truth.v_ned_mps[2]))
            controls.append(flight.vehicle_state().controls)
    return np.array(rows), np.array(controls)


def test_controls_of_a_right_turn_and_a_climb() -> None:
    """c172x: 15 s level, a 90-degree right turn at 25 deg of bank, a 100 m climb.

    Measured (jsbsim 1.3.3), relative to the level trim (roll -0.08, pitch -0.20, yaw 0.00,
    throttle 0.73): roll +0.39 while rolling in, -0.09 while rolling out; yaw +0.04 (rudder
    into the turn) in the turn; throttle +0.12 in the 2.5 m/s climb. The pitch control is
    *lower* in the climb (-0.03: more power pitches this aircraft's nose up and a climb needs
    slightly less lift), so the climb is recognised by its throttle, not its elevator; the
    pitch sign is checked by the response test above.
    """
    plan = FlightPlan(name="turn-climb", repeat=False, legs=(
        Leg(kind="heading", heading_deg=0.0, duration_s=15.0),
        Leg(kind="turn", turn_deg=90.0, bank_deg=25.0),
        Leg(kind="heading", heading_deg=90.0, duration_s=40.0, alt_m=100.0,
            climb_rate_mps=2.5),
    ))
    rows, u = _fly(plan, 70.0)
    t, phi, climb = rows.T
    assert u.shape[1] == N_CONTROLS and not u[:, 5:].any()
    for i in range(N_CONTROLS):
        lo, hi = control_range(i)
        assert lo <= u[:, i].min() and u[:, i].max() <= hi
    level = t < 14.0
    trim = u[level].mean(axis=0)
    dphi = np.gradient(phi, t)
    rolling_in = (t < 40.0) & (dphi > math.radians(3.0))
    rolling_out = (t > 20.0) & (t < 40.0) & (dphi < -math.radians(3.0))
    turning = (t > 15.0) & (t < 40.0) & (phi > math.radians(20.0))
    climbing = climb > 2.0
    assert rolling_in.sum() > 25 and rolling_out.sum() > 25 and climbing.sum() > 500
    # the roll command leads the bank: right roll-in > trim > roll-out, by most of 0.1
    assert u[rolling_in, 0].mean() - trim[0] > 0.05
    assert u[rolling_out, 0].mean() - trim[0] < -0.03
    assert u[turning, 2].mean() - trim[2] > 0.02  # right rudder in a right turn
    assert u[climbing, 3].mean() - trim[3] > 0.08  # power for the climb


def test_propeller_rpm_per_engine() -> None:
    twin = Flight(FlightConfig(aircraft="c310", rate_hz=50.0, start=suggested_start("c310")),
                  load_plan("cruise"))
    with twin:
        rpm = twin.vehicle_state().propeller_rpm
        assert len(rpm) == 2 and rpm[0] == pytest.approx(rpm[1], rel=1e-9)
        assert 1000.0 < rpm[0] < 2800.0  # c310 propellers: ~1600 rpm at this cruise
    jet = Flight(FlightConfig(aircraft="A4", rate_hz=50.0, start=suggested_start("A4")),
                 load_plan("cruise"))
    with jet:
        assert jet.vehicle_state().propeller_rpm == ()  # a jet has no propeller


def test_rpm_follows_the_throttle() -> None:
    """More throttle, faster propeller (fixed-pitch c172x): the rpm carries information."""
    setup = SimSetup.build(plan="climb-descent", duration_s=40.0, seed=3)
    rpm, thr = [], []
    with SimChain(setup) as chain:
        for step in chain.steps():
            for s in step.samples:
                if isinstance(s, RpmSample):
                    rpm.append(s.rpm)
                elif isinstance(s, ActuatorSample):
                    thr.append(s.controls[3])
    assert len(rpm) == len(thr) >= 1999  # 50 Hz for 40 s
    assert np.corrcoef(rpm, thr)[0, 1] > 0.5  # measured 0.92 (2219-2717 rpm)


def test_simulator_chain_reports_at_the_configured_rate() -> None:
    setup = SimSetup.build(plan="racetrack", duration_s=10.0, seed=2, vehicle_state_rate_hz=40.0)
    act: list[int] = []
    rpm: list[int] = []
    with SimChain(setup) as chain:
        for step in chain.steps():
            act.extend(s.time_us for s in step.samples if isinstance(s, ActuatorSample))
            rpm.extend(s.time_us for s in step.samples if isinstance(s, RpmSample))
    assert chain.ended is None
    assert act == rpm  # one propeller, stamped with its actuator report
    assert set(np.diff(act)) == {25_000}  # 40 Hz in simulated time
    assert len(act) == 400
