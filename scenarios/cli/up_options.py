"""The options of ``hilnav up`` and the durations derived from them (shared by
:mod:`scenarios.cli.up` and :mod:`scenarios.cli.up_autopilot`)."""

from __future__ import annotations

from pathlib import Path
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

from fusion.choices import DEFAULT_AIRSPEED_MODE, DEFAULT_ALIGN_MODE, DEFAULT_THERMAL_MODE

__all__ = ["DEFAULT_DURATION_S", "FUSION_IDLE_EXIT_S", "UpOptions", "fusion_idle_exit_s",
           "settle_s"]

FUSION_IDLE_EXIT_S = 3.0
"""The fusion service of ``up`` exits after this long without input (once input started)."""
DEFAULT_DURATION_S = 3600.0
"""How long ``up`` flies without a duration (or until Ctrl-C)."""


class UpOptions(BaseModel):
    """Options of :func:`run_up`."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    duration_s: float | None = Field(default=None, gt=0.0)
    speed: float = Field(default=1.0, gt=0.0, le=1000.0)
    out: Path = Path("out/up")
    vehicle: str = "sim1"
    plan: str = "racetrack"
    seed: int = Field(default=1, ge=0)
    imu: str = "industrial-mems"
    """IMU preset: the simulated sensor and the filter's tuning."""
    gnss: str = "modern"
    """GNSS receiver preset: the simulated receiver and the filter's model of it."""
    bridge: str = "none"
    """The fusion's GNSS-outage bridging method."""
    altitude: str = "ekf"
    """The fusion's altitude method."""
    airspeed: str = DEFAULT_AIRSPEED_MODE
    """The fusion's air-data choice (on, off, synthetic)."""
    align: str = DEFAULT_ALIGN_MODE
    """The fusion's alignment (auto, static, in-flight)."""
    imu_thermal: str = "off"
    """Thermal preset of the simulated IMU part (``off``: an IMU without a temperature)."""
    thermal: str = DEFAULT_THERMAL_MODE
    """The fusion's IMU thermal strategy (off, blind, states, cal)."""
    thermal_cal: Path | None = None
    """The fusion's thermal calibration file (implies ``cal``)."""
    thermal_part: str = "bmi088"
    """The part whose datasheet figures the fusion's thermal strategy assumes."""
    gnss_off: tuple[str, ...] = ()
    gcs: str | None = None
    monitor: bool = True
    lockstep: bool = False
    """Run the sim with ``--lockstep``: it never runs ahead of the fusion (no loss at any
    speed; the run goes as fast as the slower of the two)."""
    foxglove_port: int | None = Field(default=None, ge=0, le=65535)
    """The monitor also serves a Foxglove WebSocket on ``127.0.0.1:<port>`` (needs monitor)."""
    settle_s: float | None = Field(default=None, ge=0.0)
    """Scorecard settling time; None: 60 s, at most a quarter of the duration."""
    zenoh_host: str = "127.0.0.1"
    """Where the in-process router listens (beyond loopback only with ``users_file`` or
    ``insecure``)."""
    users_file: Path | None = None
    """usrpwd dictionary (``user:password`` lines) of outside clients, admitted read-only;
    turns on authentication and access control for the children too."""
    insecure: bool = False
    """Allow ``zenoh_host`` beyond loopback without authentication."""
    zenoh_key_file: Path | None = None
    """Shared payload key for every child (default: ``HILNAV_ZENOH_KEY``, inherited)."""
    autopilot: Literal["none", "px4", "ardupilot"] = "none"
    """An autopilot flies instead of hilnav's guidance (:mod:`scenarios.cli.up_autopilot`)."""
    autopilot_link: str | None = None
    """Where the simulator meets it (None: the backend's default)."""
    autopilot_telemetry: str | None = "udpin:127.0.0.1:14550"
    """Where it reports its estimate (None: not recorded)."""
    actuator_map: Path | None = None
    """PX4: the actuator map YAML (None: the legacy HIL order)."""
    servo_map: Path | None = None
    """ArduPilot: the servo map YAML (None: ArduPlane's default)."""
    ardupilot_mavlink: str | None = None
    """ArduPilot's MAVLink port for the ``SIM_GPS1_*`` parameters of the GNSS denial (None: its
    own GNSS is not denied)."""
    connect_timeout_s: float = Field(default=300.0, gt=0.0)
    stall_timeout_s: float = Field(default=10.0, gt=0.0)
    autopilot_binary: Path | None = None
    """The autopilot's SITL binary that ``up`` starts itself (:mod:`hil.autopilot.launch`)."""

    @model_validator(mode="after")
    def _autopilot_options(self) -> UpOptions:
        if self.autopilot_binary is not None and self.autopilot == "none":
            raise ValueError("--autopilot-binary needs --px4 or --ardupilot")
        if self.actuator_map is not None and self.autopilot != "px4":
            raise ValueError("--actuator-map is PX4's: it needs --px4")
        for name, value in (("--servo-map", self.servo_map),
                            ("--ardupilot-mavlink", self.ardupilot_mavlink)):
            if value is not None and self.autopilot != "ardupilot":
                raise ValueError(f"{name} is ArduPilot's: it needs --ardupilot")
        return self


def fusion_idle_exit_s(options: UpOptions) -> float:
    """How long the fusion service of ``up`` waits without input before it ends the run: with
    an autopilot the stream pauses whenever the autopilot does (lockstep), and the simulator
    side waits ``stall_timeout_s`` for it, so the fusion waits that long too."""
    if options.autopilot == "none":
        return FUSION_IDLE_EXIT_S
    return options.stall_timeout_s + FUSION_IDLE_EXIT_S


def settle_s(options: UpOptions) -> float:
    """The scorecard's settling time: ``settle_s``, else 60 s, at most a quarter of the
    duration."""
    if options.settle_s is not None:
        return options.settle_s
    return min(60.0, 0.25 * (options.duration_s or DEFAULT_DURATION_S))
