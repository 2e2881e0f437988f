"""An autopilot in the loop: PX4 (simulator interface) or ArduPilot (SITL JSON backend) flies
our JSBSim aircraft through its actuator commands.

* :mod:`hil.autopilot.backend`: what a protocol backend provides (:class:`AutopilotBackend`)
  and the one lockstep loop every backend runs in (:func:`fly_with_autopilot`).
* :mod:`hil.autopilot.arming`: :class:`~hil.autopilot.arming.TrimHold`, the trim flown
  until the autopilot is armed (every backend).
* :mod:`hil.autopilot.actuators`: :class:`~hil.autopilot.actuators.ActuatorMap`, PX4's
  HIL_ACTUATOR_CONTROLS channels -> the aircraft's controls (YAML per airframe).
* :mod:`hil.autopilot.px4`: :class:`~hil.autopilot.px4.Px4Backend`, the simulator side of
  PX4's simulator MAVLink interface (SITL over TCP, HITL over serial).
* :mod:`hil.autopilot.factory`: :func:`make_backend`, the one place a backend is built from
  its kind (``px4``, ``ardupilot``) and settings.
* :mod:`hil.autopilot.telemetry`: the autopilot's own estimate and health, recorded from its
  MAVLink telemetry (:class:`~hil.autopilot.telemetry.AutopilotTelemetry`).
* :mod:`hil.autopilot.ardupilot`: ArduPilot SITL's JSON physics interface
  (:class:`~hil.autopilot.ardupilot.ArduPilotBackend`), with :mod:`hil.autopilot.sitl_json`
  (its bytes), :mod:`hil.autopilot.servos` (servo outputs -> controls) and
  :mod:`hil.autopilot.sim_params` (the scenario's denial as SIM_* parameters over MAVLink).
* :mod:`hil.autopilot.commander`: the scenario's script run over the autopilot's telemetry
  link (:class:`~hil.autopilot.commander.Commander`: parameters read back, the mission, arm,
  mode), with :mod:`hil.autopilot.param_file` (parameter files),
  :mod:`hil.autopilot.mission` (mission items and their upload), :mod:`hil.autopilot.modes`
  (mode names, custom_mode, flying modes) and :mod:`hil.autopilot.aiding` (hilnav's estimate
  as the autopilot's navigation source).
"""

from hil.autopilot.backend import AutopilotBackend, AutopilotFlown, DenialStep, fly_with_autopilot
from hil.autopilot.factory import AUTOPILOT_KINDS, BackendSettings, close_backend, make_backend

__all__ = [
    "AUTOPILOT_KINDS",
    "AutopilotBackend",
    "AutopilotFlown",
    "BackendSettings",
    "DenialStep",
    "close_backend",
    "fly_with_autopilot",
    "make_backend",
]
