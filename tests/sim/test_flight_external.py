"""Tests of the externally commanded flight (``FlightConfig.control = "external"``), the
physics side of an autopilot in the loop: the controls given to ``Flight.command`` are what
JSBSim flies with (``vehicle_state`` reads them back), in PX4's signs, and they hold until the
next command.
"""

from __future__ import annotations

import math

import pytest

from sim.flight import Flight, FlightConfig, suggested_start
from sim.plans import load_plan
from sim.vehicle_state import N_CONTROLS


def _flight(control: str = "external") -> Flight:
    config = FlightConfig(aircraft="c172x", rate_hz=100.0, start=suggested_start("c172x"),
                          control=control)
    return Flight(config, load_plan("racetrack"))


def test_commanded_controls_are_flown_and_read_back_in_px4_signs() -> None:
    with _flight() as flight:
        trim = flight.vehicle_state().controls
        assert flight.command(trim) == 0
        flight.step()
        assert flight.vehicle_state().controls == pytest.approx(trim, abs=1e-12)
        # held: without a new command the trimmed aircraft stays near level for 5 s
        truth = flight.run_for(5.0)
        roll, pitch = _roll_pitch_deg(truth.q_nb)
        assert abs(roll) < 5.0 and abs(pitch) < 10.0
        # + roll = right wing down: a positive roll command rolls right (p > 0)
        commanded = list(trim)
        commanded[0] = trim[0] + 0.2
        flight.command(commanded)
        truth = flight.run_for(0.5)
        assert truth.omega_b_rps[0] > 0.05
        assert flight.vehicle_state().controls[0] == pytest.approx(commanded[0], abs=1e-12)
        # + pitch = nose up
        commanded = list(trim)
        commanded[1] = trim[1] + 0.2
        flight.command(commanded)
        flight.run_for(0.3)
        assert flight.truth().omega_b_rps[1] > 0.02
        assert flight.vehicle_state().controls[1] == pytest.approx(commanded[1], abs=1e-12)


def test_out_of_range_is_clipped_and_non_finite_ignored_and_counted() -> None:
    with _flight() as flight:
        before = flight.vehicle_state().controls
        assert flight.command([math.nan, 0.0, 0.0, 1.7]) == 2
        after = flight.vehicle_state().controls
        assert after[0] == pytest.approx(before[0], abs=1e-12)  # NaN left the aileron alone
        assert after[3] == 1.0  # throttle clipped to its [0, 1]
        with pytest.raises(ValueError, match="at most 16"):
            flight.command([0.0] * (N_CONTROLS + 1))


def test_a_guided_flight_refuses_commands() -> None:
    with _flight("guidance") as flight, pytest.raises(RuntimeError, match="external"):
        flight.command([0.0])


def _roll_pitch_deg(q: object) -> tuple[float, float]:
    w, x, y, z = (float(v) for v in q)  # type: ignore[attr-defined]
    roll = math.atan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
    pitch = math.asin(max(-1.0, min(1.0, 2 * (w * y - z * x))))
    return math.degrees(roll), math.degrees(pitch)
