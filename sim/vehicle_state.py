"""What a flight controller reports about its own outputs: normalised actuator controls and
propeller speed, sampled from the flight at a fixed rate in simulated time.

A real autopilot in HIL sends HIL_ACTUATOR_CONTROLS (its mixer's normalised outputs) and
RAW_RPM (an rpm sensor); the learned vehicle models (airspeed from controls and rpm) need
both. :class:`VehicleStateReporter` turns what the flight adapter flies with
(:meth:`sim.flight.Flight.vehicle_state`, a :class:`VehicleState` already in PX4's order and
sign conventions) into :class:`~sim.samples.ActuatorSample` and :class:`~sim.samples.RpmSample`
at ``VehicleStateConfig.rate_hz`` (default 50 Hz; >= 25 Hz, what those models need).

Timing: the first step reports, then every ``1 / rate_hz`` of simulated time on a fixed grid
(as the streamer's truth frames), so a 200 Hz flight reports every 4th step at 50 Hz. The
flight's properties are read only on the steps that report (``read`` is called lazily).

Noise: none. The controls are the commands the autopilot itself computed (exact by
definition); the rpm is JSBSim's propeller speed. An rpm sensor's error model (hall-effect
quantisation, pulse-count jitter) is not modelled yet.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from pydantic import BaseModel, ConfigDict, Field

from sim.samples import ActuatorSample, RpmSample

__all__ = [
    "CONTROL_INDEX",
    "N_CONTROLS",
    "VehicleState",
    "VehicleStateConfig",
    "VehicleStateReporter",
    "control_range",
]

N_CONTROLS = 16
"""Length of a control vector (HIL_ACTUATOR_CONTROLS ``controls[16]``)."""

CONTROL_INDEX = {
    "roll": 0,
    "pitch": 1,
    "yaw": 2,
    "throttle": 3,
    "flaps": 4,
    "spoilers": 5,
    "airbrakes": 6,
    "landing_gear": 7,
}
"""Index of each named control in PX4's order (its ``actuator_controls`` group 0)."""


def control_range(index: int) -> tuple[float, float]:
    """Valid range of control ``index``: [0, 1] for the throttle, [-1, 1] for every other
    (PX4's normalised range; the simulator's flaps use its [0, 1] part)."""
    return (0.0, 1.0) if index == CONTROL_INDEX["throttle"] else (-1.0, 1.0)


@dataclass(frozen=True, slots=True)
class VehicleState:
    """The flight's actuator commands and propeller speeds at one instant.

    Attributes
    ----------
    controls : tuple of 16 float
        PX4 HIL_ACTUATOR_CONTROLS order and signs: 0 roll (+ = right wing down), 1 pitch
        (+ = nose up), 2 yaw (+ = nose right), all in [-1, 1]; 3 throttle in [0, 1]; 4 flaps
        in [0, 1] (0 = retracted); 5-15 unused (0).
    propeller_rpm : tuple of float
        Propeller speed of each engine that has a propeller, rev/min (empty for jets).
    """

    controls: tuple[float, ...]
    propeller_rpm: tuple[float, ...]


class VehicleStateConfig(BaseModel):
    """Rate and content of the vehicle-state reports.

    ``rate_hz``: report rate in simulated time, Hz (>= 25). ``actuators`` / ``rpm``: whether
    ActuatorSample / RpmSample are produced at all (off: a stream without controls or rpm,
    as from a flight controller that does not send them).
    """

    model_config = ConfigDict(frozen=True, extra="forbid")

    rate_hz: float = Field(default=50.0, ge=25.0, le=1000.0)
    actuators: bool = True
    rpm: bool = True


class VehicleStateReporter:
    """Samples a flight's :class:`VehicleState` at ``config.rate_hz`` of simulated time.

    Parameters
    ----------
    config : VehicleStateConfig
    """

    def __init__(self, config: VehicleStateConfig | None = None) -> None:
        self.config = config or VehicleStateConfig()
        self._period_us = round(1e6 / self.config.rate_hz)
        self._next_us: int | None = None

    def step(
        self, time_us: int, read: Callable[[], VehicleState]
    ) -> list[ActuatorSample | RpmSample]:
        """Samples due at ``time_us`` (empty between reports).

        Parameters
        ----------
        time_us : int
            Simulated time of the flight's current state, us.
        read : callable
            Returns the flight's current :class:`VehicleState`; called only when a report is
            due.

        Returns
        -------
        list of ActuatorSample and RpmSample
            One ActuatorSample (if enabled), then one RpmSample per propeller (``index`` =
            its position in ``propeller_rpm``), all stamped ``time_us``.
        """
        cfg = self.config
        if not (cfg.actuators or cfg.rpm):
            return []
        if self._next_us is not None and time_us < self._next_us:
            return []
        base = time_us if self._next_us is None else self._next_us
        self._next_us = base + self._period_us
        if self._next_us <= time_us:  # a step longer than the period: re-anchor the grid
            self._next_us = time_us + self._period_us
        state = read()
        out: list[ActuatorSample | RpmSample] = []
        if cfg.actuators:
            out.append(ActuatorSample(time_us, state.controls))
        if cfg.rpm:
            out.extend(RpmSample(time_us, rpm, i) for i, rpm in enumerate(state.propeller_rpm))
        return out
