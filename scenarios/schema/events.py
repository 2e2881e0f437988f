"""The fault-event part of a scenario file."""

from __future__ import annotations

import math
from typing import Annotated, Any, Literal, Self

from pydantic import BaseModel, BeforeValidator, Field, model_validator

from physconst import G0_MPS2
from scenarios.schema.base import Strict, key_error
from scenarios.schema.units import Span, StartTime
from sim import faults


def _axis(value: Any) -> Any:
    if isinstance(value, str) and value.lower() in ("x", "y", "z"):
        return "xyz".index(value.lower())
    return value


Axis = Annotated[
    Literal[0, 1, 2], BeforeValidator(_axis, json_schema_input_type=Literal[0, 1, 2, "x", "y", "z"])
]
"""Body axis (FRD): 0/x forward, 1/y right, 2/z down."""


class _Event(Strict):
    """Common fields: ``at`` (start, s since the flight began) and ``duration`` (None: to the
    end of the flight)."""

    type: str
    at: StartTime = Field(description="Start: seconds after the flight begins, or '5 min'.")
    duration: Span | None = Field(
        default=None,
        description="Length (s or '90 s', '2 min'); omitted: until the end of the flight.",
    )

    def to_fault(self) -> faults.FaultEvent:  # pragma: no cover - every subclass overrides
        raise NotImplementedError


    def describe(self) -> str:
        """``type (start-end s)`` for messages; ``end`` is 'end' when open-ended."""
        end = "end" if self.duration is None else f"{self.at + self.duration:g} s"
        return f"{self.type} ({self.at:g} s to {end})"


class GnssOutageEvent(_Event):
    """No GNSS fix at all (HIL_GPS stops)."""

    type: Literal["gnss_outage"]

    def to_fault(self) -> faults.FaultEvent:
        return faults.GnssOutage(start_s=self.at, duration_s=self.duration)


class GnssJammingEvent(_Event):
    """Jamming: a blackout, then intermittent fixes with degraded flags and noisy positions."""

    type: Literal["gnss_jamming"]
    blackout_s: float = Field(default=10.0, ge=0.0, description="Initial blackout, s.")
    flap_period_s: float = Field(default=2.0, gt=0.0, description="Intermittent period, s.")
    flap_duty: float = Field(default=0.5, ge=0.0, le=1.0, description="Fraction with fixes.")
    garbage_sigma_m: float = Field(default=50.0, ge=0.0,
                                   description="Position noise of bad fixes, m.")
    garbage_velocity_sigma_mps: float = Field(default=5.0, ge=0.0,
                                              description="Velocity noise of bad fixes, m/s.")

    def to_fault(self) -> faults.FaultEvent:
        return faults.GnssJamming(
            start_s=self.at, duration_s=self.duration, blackout_s=self.blackout_s,
            flap_period_s=self.flap_period_s, flap_duty=self.flap_duty,
            garbage_sigma_m=self.garbage_sigma_m,
            garbage_velocity_sigma_mps=self.garbage_velocity_sigma_mps,
        )


class GnssDegradationEvent(_Event):
    """Position/velocity noise and the reported accuracy multiplied by ``factor``."""

    type: Literal["gnss_degradation"]
    factor: float = Field(default=5.0, ge=1.0, description="Noise multiplier.")
    ramp_s: float = Field(default=0.0, ge=0.0, description="Ramp-in time, s.")

    def to_fault(self) -> faults.FaultEvent:
        return faults.GnssDegradation(
            start_s=self.at, duration_s=self.duration, factor=self.factor, ramp_s=self.ramp_s
        )


class GnssSpoofDriftEvent(_Event):
    """Slow spoof: the reported position is pulled off at ``rate_mps`` towards ``bearing_deg``."""

    type: Literal["gnss_spoof_drift"]
    rate_mps: float = Field(default=1.0, ge=0.0, le=1000.0, description="Drift rate, m/s.")
    bearing_deg: float = Field(
        default=90.0, ge=-360.0, le=360.0, description="Drift direction, deg from true north."
    )
    vertical_rate_mps: float = Field(default=0.0, ge=-100.0, le=100.0,
                                     description="Drift rate up (+) or down (-), m/s.")
    consistent_velocity: bool = Field(
        default=True, description="The reported velocity carries the drift rate too."
    )

    def to_fault(self) -> faults.FaultEvent:
        return faults.GnssSpoofDrift(
            start_s=self.at, duration_s=self.duration, rate_mps=self.rate_mps,
            bearing_deg=self.bearing_deg, vertical_rate_mps=self.vertical_rate_mps,
            consistent_velocity=self.consistent_velocity,
        )


class GnssSpoofHijackEvent(_Event):
    """Sudden hijack: the reported position jumps by ``offset_ned_m`` and stays there."""

    type: Literal["gnss_spoof_hijack"]
    offset_ned_m: tuple[float, float, float] = Field(
        default=(500.0, 0.0, 0.0), description="Jump north, east, down, m."
    )

    def to_fault(self) -> faults.FaultEvent:
        return faults.GnssSpoofHijack(
            start_s=self.at, duration_s=self.duration, offset_ned_m=self.offset_ned_m
        )


class GnssDelayEvent(_Event):
    """Fixes emitted ``extra_latency_s`` later (time of validity kept)."""

    type: Literal["gnss_delay"]
    extra_latency_s: float = Field(default=0.5, gt=0.0, le=60.0, description="Extra delay, s.")

    def to_fault(self) -> faults.FaultEvent:
        return faults.GnssDelay(
            start_s=self.at, duration_s=self.duration, extra_latency_s=self.extra_latency_s
        )


class GnssRateEvent(_Event):
    """Fixes decimated to ``rate_hz`` (at most the receiver's rate)."""

    type: Literal["gnss_rate"]
    rate_hz: float = Field(default=1.0, gt=0.0, description="Reduced fix rate, Hz.")

    def to_fault(self) -> faults.FaultEvent:
        return faults.GnssRate(start_s=self.at, duration_s=self.duration, rate_hz=self.rate_hz)


class BaroDriftEvent(_Event):
    """Sensor pressure offset growing linearly (give one rate; default -0.1 Pa/s)."""

    type: Literal["baro_drift"]
    rate_pa_per_s: float | None = Field(default=None, description="Drift, Pa/s.")
    rate_hpa_per_h: float | None = Field(default=None, description="Drift, hPa/h.")

    @model_validator(mode="after")
    def _one_rate(self) -> Self:
        _one_of(self, ("rate_pa_per_s", "rate_hpa_per_h"))
        return self

    def to_fault(self) -> faults.FaultEvent:
        rate = -0.1
        if self.rate_pa_per_s is not None:
            rate = self.rate_pa_per_s
        elif self.rate_hpa_per_h is not None:
            rate = self.rate_hpa_per_h * 100.0 / 3600.0
        return faults.BaroDrift(start_s=self.at, duration_s=self.duration, rate_pa_per_s=rate)


class BaroGlitchEvent(_Event):
    """Sensor pressure offset while active (give one; default 500 Pa = 5 hPa)."""

    type: Literal["baro_glitch"]
    offset_pa: float | None = Field(default=None, description="Offset, Pa.")
    offset_hpa: float | None = Field(default=None, description="Offset, hPa.")

    @model_validator(mode="after")
    def _one_offset(self) -> Self:
        _one_of(self, ("offset_pa", "offset_hpa"))
        return self

    def to_fault(self) -> faults.FaultEvent:
        offset = 500.0
        if self.offset_pa is not None:
            offset = self.offset_pa
        elif self.offset_hpa is not None:
            offset = 100.0 * self.offset_hpa
        return faults.BaroGlitch(start_s=self.at, duration_s=self.duration, offset_pa=offset)


class BaroFreezeEvent(_Event):
    """Pressure and temperature stuck at their last values."""

    type: Literal["baro_freeze"]

    def to_fault(self) -> faults.FaultEvent:
        return faults.BaroFreeze(start_s=self.at, duration_s=self.duration)


class WeatherFrontEvent(_Event):
    """Ambient pressure change (true altitude unchanged): ramps while active, stays after.
    Give one rate; default -1 hPa per 10 min."""

    type: Literal["weather_front"]
    rate_hpa_per_10min: float | None = Field(default=None, description="hPa per 10 min.")
    rate_hpa_per_h: float | None = Field(default=None, description="hPa per hour.")

    @model_validator(mode="after")
    def _one_rate(self) -> Self:
        _one_of(self, ("rate_hpa_per_10min", "rate_hpa_per_h"))
        return self

    def to_fault(self) -> faults.FaultEvent:
        rate = -100.0 / 600.0
        if self.rate_hpa_per_10min is not None:
            rate = self.rate_hpa_per_10min * 100.0 / 600.0
        elif self.rate_hpa_per_h is not None:
            rate = self.rate_hpa_per_h * 100.0 / 3600.0
        return faults.WeatherFront(start_s=self.at, duration_s=self.duration, rate_pa_per_s=rate)


class ImuBiasStepEvent(_Event):
    """A bias step on one axis: ``value_deg_per_h`` for the gyro, ``value_mg`` for the
    accelerometer."""

    type: Literal["imu_bias_step"]
    sensor: Literal["gyro", "accel"]
    axis: Axis
    value_deg_per_h: float | None = Field(default=None, description="Gyro step, deg/h.")
    value_mg: float | None = Field(default=None, description="Accelerometer step, mg.")

    @model_validator(mode="after")
    def _value_matches_sensor(self) -> Self:
        want, other = (
            ("value_deg_per_h", "value_mg") if self.sensor == "gyro"
            else ("value_mg", "value_deg_per_h")
        )
        if getattr(self, other) is not None:
            raise key_error(f"a {self.sensor} step takes {want}, not {other}", (other,))
        if getattr(self, want) is None:
            raise key_error(f"a {self.sensor} step needs {want}")
        return self


    def to_fault(self) -> faults.FaultEvent:
        if self.sensor == "gyro":
            value = float(self.value_deg_per_h or 0.0) * math.pi / 180.0 / 3600.0
        else:
            value = float(self.value_mg or 0.0) * 1e-3 * G0_MPS2
        return faults.ImuBiasStep(
            start_s=self.at, duration_s=self.duration, sensor=self.sensor, axis=self.axis,
            value=value,
        )


class ImuStuckEvent(_Event):
    """One IMU axis repeats its last value."""

    type: Literal["imu_stuck"]
    sensor: Literal["gyro", "accel"]
    axis: Axis


    def to_fault(self) -> faults.FaultEvent:
        return faults.ImuStuck(
            start_s=self.at, duration_s=self.duration, sensor=self.sensor, axis=self.axis
        )


class ImuSaturationEvent(_Event):
    """One IMU sensor clipped at ``limit_dps`` (gyro) or ``limit_g`` (accel), on ``axis`` or
    (omitted) on all three."""

    type: Literal["imu_saturation"]
    sensor: Literal["gyro", "accel"]
    axis: Axis | None = None
    limit_dps: float | None = Field(default=None, gt=0.0, description="Gyro limit, deg/s.")
    limit_g: float | None = Field(default=None, gt=0.0, description="Accelerometer limit, g.")

    @model_validator(mode="after")
    def _limit_matches_sensor(self) -> Self:
        want, other = (
            ("limit_dps", "limit_g") if self.sensor == "gyro" else ("limit_g", "limit_dps")
        )
        if getattr(self, other) is not None:
            raise key_error(f"a {self.sensor} saturation takes {want}, not {other}", (other,))
        if getattr(self, want) is None:
            raise key_error(f"a {self.sensor} saturation needs {want}")
        return self


    def to_fault(self) -> faults.FaultEvent:
        if self.sensor == "gyro":
            limit = float(self.limit_dps or 0.0) * math.pi / 180.0
        else:
            limit = float(self.limit_g or 0.0) * G0_MPS2
        return faults.ImuSaturation(
            start_s=self.at, duration_s=self.duration, sensor=self.sensor, limit=limit,
            axis=self.axis,
        )


class MagAnomalyEvent(_Event):
    """Extra magnetic field in NED (µT), e.g. a local anomaly or a powered cable."""

    type: Literal["mag_anomaly"]
    offset_ned_ut: tuple[float, float, float] = Field(
        default=(2.0, 0.0, 0.0), description="Extra field north, east, down, µT."
    )

    def to_fault(self) -> faults.FaultEvent:
        n, e, d = self.offset_ned_ut
        return faults.MagAnomaly(
            start_s=self.at, duration_s=self.duration, offset_ned_t=(n * 1e-6, e * 1e-6, d * 1e-6)
        )


def _one_of(model: BaseModel, names: tuple[str, str]) -> None:
    if sum(getattr(model, n) is not None for n in names) > 1:
        raise key_error(f"give one of {names[0]} and {names[1]}, not both", (names[1],))


_EVENT_CLASSES: tuple[type[_Event], ...] = (
    GnssOutageEvent, GnssJammingEvent, GnssDegradationEvent, GnssSpoofDriftEvent,
    GnssSpoofHijackEvent, GnssDelayEvent, GnssRateEvent, BaroDriftEvent, BaroGlitchEvent,
    BaroFreezeEvent, WeatherFrontEvent, ImuBiasStepEvent, ImuStuckEvent, ImuSaturationEvent,
    MagAnomalyEvent,
)
EVENT_SPECS: dict[str, type[_Event]] = {
    c.model_fields["type"].annotation.__args__[0]: c  # type: ignore[union-attr]
    for c in _EVENT_CLASSES
}
"""Event ``type`` name -> its model."""

Event = Annotated[
    GnssOutageEvent | GnssJammingEvent | GnssDegradationEvent | GnssSpoofDriftEvent
    | GnssSpoofHijackEvent | GnssDelayEvent | GnssRateEvent | BaroDriftEvent | BaroGlitchEvent
    | BaroFreezeEvent | WeatherFrontEvent | ImuBiasStepEvent | ImuStuckEvent
    | ImuSaturationEvent | MagAnomalyEvent,
    Field(discriminator="type"),
]

