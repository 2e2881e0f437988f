"""Fault-event types: one frozen pydantic model per kind of fault, fields in SI with units in
their names and declared as metadata.

Times
    Event times are seconds of simulated flight time. An event is active on ``[start_s,
    start_s + duration_s)``; ``duration_s = None`` means until the end of the flight.

Events
    ==================  =========================================================  ===========
    type name           effect                                                     PX4 failure
    ==================  =========================================================  ===========
    gnss_outage         no fix at all                                              gps off
    gnss_jamming        blackout for ``blackout_s``, then fixes on for             gps
                        ``flap_duty`` of each ``flap_period_s`` only, each         intermittent
                        with N(0, ``garbage_sigma_m``²) position noise (N, E, D),
                        N(0, ``garbage_velocity_sigma_mps``²) velocity noise,
                        eph = epv = max(reported, ``garbage_sigma_m``), 3-5
                        satellites and, with probability 1/2, fix_type 2 (2D)
    gnss_degradation    position and velocity *errors* (fix − truth at the fix's   gps garbage
                        time of validity) and eph / epv / speed accuracy multiplied
                        by ``1 + (factor − 1)·min(1, (t − start)/ramp_s)``
    gnss_spoof_drift    position pulled off at ``rate_mps`` along ``bearing_deg``  gps wrong
                        (clockwise from north) and ``vertical_rate_mps`` *upwards*,
                        from 0 at ``start_s``; velocity carries the drift rate when
                        ``consistent_velocity``; reported accuracy unchanged
    gnss_spoof_hijack   constant NED offset ``offset_ned_m`` (D positive = down)   gps wrong
    gnss_delay          fixes emitted ``extra_latency_s`` later (time of validity  gps delayed
                        kept); later fixes queue behind them, never overtake
    gnss_rate           fixes decimated to ``rate_hz`` (drift-free schedule on     gps slow
                        the times of validity; never more fixes than the receiver
                        makes)
    baro_drift          pressure offset ``rate_pa_per_s·(t − start)`` while        baro wrong
                        active (gone when the fault clears)
    baro_glitch         pressure offset ``offset_pa`` while active                 baro wrong
    baro_freeze         pressure and temperature of the last sample before the     baro stuck
                        start repeated, with new timestamps
    weather_front       ambient pressure at the aircraft changes at                baro wrong
                        ``rate_pa_per_s`` while active and keeps its final offset
                        afterwards (the true altitude is unchanged)
    imu_bias_step       ``value`` (m/s² or rad/s) added to one axis                accel/gyro
                                                                                   wrong
    imu_stuck           one axis repeats its last value before the start           accel/gyro
                                                                                   stuck
    imu_saturation      ``|value|`` clipped at ``limit`` (one axis or all)         accel/gyro
                                                                                   wrong
    mag_anomaly         extra field ``offset_ned_t`` (T, NED) rotated into body    mag wrong
                        with the true attitude and added
    pitot_blockage      ``mode="stuck"``: the differential pressure of the last    airspeed
                        sample before the start repeated (total port iced, drain   stuck
                        hole blocked: trapped pressure); ``mode="zero"``: it       (zero:
                        reads exactly 0 Pa (total port blocked, the drain hole     airspeed
                        vents it to static)                                        wrong)
    pitot_drift         differential-pressure offset ``rate_pa_per_s·(t −          airspeed
                        start)`` while active (gone when the fault clears)        wrong
    airspeed_failure    no airspeed sample at all                                  airspeed
                                                                                   off
    ==================  =========================================================  ===========

Units
    Every quantity field declares its unit in ``json_schema_extra["unit"]`` (read it with
    :func:`field_unit`): ``"s"``, ``"m"``, ``"m/s"``, ``"Hz"``, ``"Pa"``, ``"Pa/s"``, ``"T"``,
    ``"deg"``, ``"1"`` (dimensionless); the IMU events' ``value`` and ``limit`` are in
    ``"m/s^2"`` for the accelerometer and ``"rad/s"`` for the gyro (a mapping sensor -> unit).

Construction
    Keywords (``GnssOutage(start_s=10.0, duration_s=5.0)``), positionally in field order
    (``GnssOutage(10.0, 5.0)``), or from a mapping with ``model_validate``. Numbers must be
    finite; bools are not numbers. A bad field raises ``pydantic.ValidationError`` (a
    ``ValueError``) naming the class and the field.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Annotated, Any, ClassVar, Literal

from pydantic import BaseModel, BeforeValidator, ConfigDict, Field
from pydantic_core import PydanticKnownError

__all__ = [
    "BARO_EVENTS",
    "BARO_SENSOR_EVENTS",
    "EVENT_TYPES",
    "GNSS_EVENTS",
    "GNSS_POSITION_EVENTS",
    "IMU_EVENTS",
    "PITOT_EVENTS",
    "AirspeedFailure",
    "Axis",
    "BaroDrift",
    "BaroFreeze",
    "BaroGlitch",
    "FaultEvent",
    "FaultEventBase",
    "GnssDegradation",
    "GnssDelay",
    "GnssJamming",
    "GnssOutage",
    "GnssRate",
    "GnssSpoofDrift",
    "GnssSpoofHijack",
    "ImuBiasStep",
    "ImuSaturation",
    "ImuSensor",
    "ImuStuck",
    "MagAnomaly",
    "Number",
    "PitotBlockage",
    "PitotDrift",
    "WeatherFront",
    "event_type_name",
    "field_unit",
]


def _not_bool(value: Any) -> Any:
    # pydantic reads True as 1.0; a flag where a number belongs is a mistake.
    if isinstance(value, bool):
        raise PydanticKnownError("float_type")
    return value


def _axis(value: Any) -> Any:
    if isinstance(value, bool):
        raise PydanticKnownError("literal_error", {"expected": "0, 1 or 2"})
    if isinstance(value, str) and value.lower() in ("x", "y", "z"):
        return "xyz".index(value.lower())
    return value


Number = Annotated[float, Field(allow_inf_nan=False), BeforeValidator(_not_bool)]
"""A finite number (int or float; not a bool)."""

# A number > 0 for an optional field: the bound goes on the number inside the union, ahead of
# the bool check, so pydantic applies it to the float itself and the JSON Schema states it.
_Positive = Annotated[float, Field(gt=0.0, allow_inf_nan=False), BeforeValidator(_not_bool)]

Vec3 = tuple[Number, Number, Number]
"""Three finite numbers (N, E, D)."""

Axis = Annotated[
    Literal[0, 1, 2],
    BeforeValidator(_axis, json_schema_input_type=Literal[0, 1, 2, "x", "y", "z"]),
]
"""Body axis (FRD): 0 or "x" forward, 1 or "y" right, 2 or "z" down."""

ImuSensor = Literal["gyro", "accel"]
"""The IMU's gyroscope or accelerometer."""

_IMU_UNIT = {"gyro": "rad/s", "accel": "m/s^2"}


def _field(default: Any, unit: str | Mapping[str, str], description: str, **bounds: Any) -> Any:
    """A quantity field: its unit as metadata, bounds in that unit."""
    extra: dict[str, Any] = {"unit": dict(unit) if isinstance(unit, Mapping) else unit}
    return Field(default, description=description, json_schema_extra=extra, **bounds)


class FaultEventBase(BaseModel):
    """The window every event has: ``start_s`` and ``duration_s`` (None: to the end)."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    type_name: ClassVar[str]
    """The event's type name (snake_case, the key of :data:`EVENT_TYPES`)."""

    start_s: Number = _field(..., "s", "Start, after the flight began.", ge=0.0)
    duration_s: _Positive | None = _field(
        None, "s", "Length; None: until the end of the flight."
    )

    @classmethod
    def __pydantic_init_subclass__(cls, **kwargs: Any) -> None:
        super().__pydantic_init_subclass__(**kwargs)
        cls.type_name = cls.model_fields["type"].default

    def __init__(self, /, *args: Any, **data: Any) -> None:
        # Positional arguments fill the fields in declaration order (``type`` excepted).
        if args:
            names = [n for n in type(self).model_fields if n != "type"]
            if len(args) > len(names):
                raise TypeError(
                    f"{type(self).__name__} takes at most {len(names)} positional arguments "
                    f"({len(args)} given)"
                )
            for name, value in zip(names[: len(args)], args, strict=True):
                if name in data:
                    raise TypeError(f"{type(self).__name__} got two values for {name!r}")
                data[name] = value
        super().__init__(**data)

    def model_post_init(self, context: Any, /) -> None:
        # The discriminator counts as given: a dump with exclude_unset still names the type.
        self.__pydantic_fields_set__.add("type")

    @property
    def end_s(self) -> float | None:
        """End of the window, s of flight time (None = end of the flight)."""
        return None if self.duration_s is None else self.start_s + self.duration_s


# --------------------------------------------------------------------------- GNSS


class GnssOutage(FaultEventBase):
    """No GNSS fix at all while active."""

    type: Literal["gnss_outage"] = "gnss_outage"


class GnssJamming(FaultEventBase):
    """Jamming: ``blackout_s`` without fixes, then intermittent garbage fixes.

    After the blackout, fixes are let through during the first ``flap_duty`` of each
    ``flap_period_s`` (measured from the end of the blackout), each with position noise
    ``garbage_sigma_m`` (m, 1σ per axis), velocity noise ``garbage_velocity_sigma_mps`` (m/s),
    eph = epv = max(reported, ``garbage_sigma_m``), 3-5 satellites and fix_type 2 with
    probability 1/2.
    """

    type: Literal["gnss_jamming"] = "gnss_jamming"
    blackout_s: Number = _field(10.0, "s", "Blackout before the first fix.", ge=0.0)
    flap_period_s: Number = _field(2.0, "s", "Period of the intermittent fixes.", gt=0.0)
    flap_duty: Number = _field(0.5, "1", "Fraction of each period with fixes.", ge=0.0, le=1.0)
    garbage_sigma_m: Number = _field(
        50.0, "m", "Position noise of the fixes (1σ per axis).", ge=0.0
    )
    garbage_velocity_sigma_mps: Number = _field(
        5.0, "m/s", "Velocity noise of the fixes (1σ per axis).", ge=0.0
    )


class GnssDegradation(FaultEventBase):
    """Position / velocity errors and reported accuracies multiplied by ``factor`` (≥ 1),
    reached linearly over ``ramp_s`` seconds (0 = at once)."""

    type: Literal["gnss_degradation"] = "gnss_degradation"
    factor: Number = _field(5.0, "1", "Error multiplier.", ge=1.0)
    ramp_s: Number = _field(0.0, "s", "Ramp-in time.", ge=0.0)


class GnssSpoofDrift(FaultEventBase):
    """Slow pull-off: the reported position's offset grows from 0 at ``rate_mps`` along
    ``bearing_deg`` (clockwise from true north) and ``vertical_rate_mps`` upwards. With
    ``consistent_velocity`` the reported velocity carries the drift rate too."""

    type: Literal["gnss_spoof_drift"] = "gnss_spoof_drift"
    rate_mps: Number = _field(1.0, "m/s", "Horizontal drift rate.", ge=0.0, le=1000.0)
    bearing_deg: Number = _field(
        90.0, "deg", "Drift direction, clockwise from true north.", ge=-360.0, le=360.0
    )
    vertical_rate_mps: Number = _field(
        0.0, "m/s", "Drift rate up (+) or down (-).", ge=-100.0, le=100.0
    )
    consistent_velocity: bool = Field(
        default=True, description="The reported velocity carries the drift rate too."
    )


class GnssSpoofHijack(FaultEventBase):
    """Sudden jump: the reported position is offset by ``offset_ned_m`` from the start, held
    while active; velocity and reported accuracy unchanged."""

    type: Literal["gnss_spoof_hijack"] = "gnss_spoof_hijack"
    offset_ned_m: Vec3 = _field((500.0, 0.0, 0.0), "m", "Jump north, east, down.")


class GnssDelay(FaultEventBase):
    """Fixes valid while active are emitted ``extra_latency_s`` later (time of validity
    kept)."""

    type: Literal["gnss_delay"] = "gnss_delay"
    extra_latency_s: Number = _field(0.5, "s", "Extra delay.", gt=0.0, le=60.0)


class GnssRate(FaultEventBase):
    """Fixes decimated to ``rate_hz`` while active (never more than the receiver makes)."""

    type: Literal["gnss_rate"] = "gnss_rate"
    rate_hz: Number = _field(1.0, "Hz", "Reduced fix rate.", gt=0.0)


# --------------------------------------------------------------------------- barometer


class BaroDrift(FaultEventBase):
    """Sensor pressure offset growing at ``rate_pa_per_s`` while active (gone after)."""

    type: Literal["baro_drift"] = "baro_drift"
    rate_pa_per_s: Number = _field(-0.1, "Pa/s", "Drift of the sensor's pressure.")


class BaroGlitch(FaultEventBase):
    """Sensor pressure offset ``offset_pa`` while active."""

    type: Literal["baro_glitch"] = "baro_glitch"
    offset_pa: Number = _field(500.0, "Pa", "Offset of the sensor's pressure.")


class BaroFreeze(FaultEventBase):
    """Pressure and temperature stuck at the last sample before the start."""

    type: Literal["baro_freeze"] = "baro_freeze"


class WeatherFront(FaultEventBase):
    """Ambient pressure at the aircraft changing at ``rate_pa_per_s`` while active; the
    offset reached at the end stays. The true altitude does not change."""

    type: Literal["weather_front"] = "weather_front"
    rate_pa_per_s: Number = _field(
        -100.0 / 600.0, "Pa/s", "Change of the ambient pressure."
    )


# --------------------------------------------------------------------------- IMU, magnetometer


class ImuBiasStep(FaultEventBase):
    """``value`` added to body axis ``axis`` of ``sensor`` (m/s² for the accelerometer,
    rad/s for the gyro)."""

    type: Literal["imu_bias_step"] = "imu_bias_step"
    sensor: ImuSensor
    axis: Axis
    value: Number = _field(..., _IMU_UNIT, "Bias step.")


class ImuStuck(FaultEventBase):
    """Body axis ``axis`` of ``sensor`` repeats its last value before the start."""

    type: Literal["imu_stuck"] = "imu_stuck"
    sensor: ImuSensor
    axis: Axis


class ImuSaturation(FaultEventBase):
    """``|value|`` of ``sensor`` clipped at ``limit`` (m/s² or rad/s) on ``axis`` (None: all
    three axes)."""

    type: Literal["imu_saturation"] = "imu_saturation"
    sensor: ImuSensor
    limit: Number = _field(..., _IMU_UNIT, "Clipping limit.", gt=0.0)
    axis: Axis | None = None


class MagAnomaly(FaultEventBase):
    """Extra magnetic field ``offset_ned_t`` (NED), rotated into body with the true attitude
    and added to the magnetometer output (a local anomaly, a powered cable)."""

    type: Literal["mag_anomaly"] = "mag_anomaly"
    offset_ned_t: Vec3 = _field((2e-6, 0.0, 0.0), "T", "Extra field north, east, down.")


# --------------------------------------------------------------------------- pitot (airspeed)


class PitotBlockage(FaultEventBase):
    """Blocked pitot: ``mode="stuck"`` repeats the last differential pressure before the start
    (iced total port with a blocked drain hole traps the pressure); ``mode="zero"`` reads
    0 Pa (blocked total port, the drain hole vents it to the static pressure). The sensor's
    temperature keeps reading."""

    type: Literal["pitot_blockage"] = "pitot_blockage"
    mode: Literal["stuck", "zero"] = Field(
        default="stuck", description="stuck: last value held; zero: reads 0 Pa."
    )


class PitotDrift(FaultEventBase):
    """Differential-pressure offset growing at ``rate_pa_per_s`` while active (gone after):
    a drifting sensor zero, water in the line."""

    type: Literal["pitot_drift"] = "pitot_drift"
    rate_pa_per_s: Number = _field(1.0, "Pa/s", "Drift of the differential pressure.")


class AirspeedFailure(FaultEventBase):
    """The airspeed sensor gives no output at all (PX4 ``failure airspeed off``)."""

    type: Literal["airspeed_failure"] = "airspeed_failure"


FaultEvent = (
    GnssOutage
    | GnssJamming
    | GnssDegradation
    | GnssSpoofDrift
    | GnssSpoofHijack
    | GnssDelay
    | GnssRate
    | BaroDrift
    | BaroGlitch
    | BaroFreeze
    | WeatherFront
    | ImuBiasStep
    | ImuStuck
    | ImuSaturation
    | MagAnomaly
    | PitotBlockage
    | PitotDrift
    | AirspeedFailure
)
"""Any fault event."""

EVENT_TYPES: dict[str, type[FaultEvent]] = {
    cls.type_name: cls
    for cls in (
        GnssOutage,
        GnssJamming,
        GnssDegradation,
        GnssSpoofDrift,
        GnssSpoofHijack,
        GnssDelay,
        GnssRate,
        BaroDrift,
        BaroGlitch,
        BaroFreeze,
        WeatherFront,
        ImuBiasStep,
        ImuStuck,
        ImuSaturation,
        MagAnomaly,
        PitotBlockage,
        PitotDrift,
        AirspeedFailure,
    )
}
"""Type name (snake_case, the ``type`` of a scenario's event) -> event class."""

# Families: the sensor an event acts on, and the events that decide the same output.
GNSS_POSITION_EVENTS = (GnssOutage, GnssJamming, GnssDegradation, GnssSpoofDrift, GnssSpoofHijack)
"""GNSS events that each decide the reported position."""
GNSS_EVENTS = (*GNSS_POSITION_EVENTS, GnssDelay, GnssRate)
"""Every event acting on GNSS fixes."""
BARO_SENSOR_EVENTS = (BaroDrift, BaroGlitch, BaroFreeze)
"""Barometer events that each decide the sensor's own error."""
BARO_EVENTS = (*BARO_SENSOR_EVENTS, WeatherFront)
"""Every event acting on barometer samples."""
IMU_EVENTS = (ImuBiasStep, ImuStuck, ImuSaturation)
"""Every event acting on IMU samples."""
PITOT_EVENTS = (PitotBlockage, PitotDrift, AirspeedFailure)
"""Every event acting on airspeed (pitot) samples; each decides the output."""


def event_type_name(event: object) -> str:
    """The type name of a fault event.

    Raises
    ------
    ValueError
        ``event`` is not an instance of one of :data:`EVENT_TYPES`.
    """
    name = getattr(type(event), "type_name", None)
    if not isinstance(name, str) or EVENT_TYPES.get(name) is not type(event):
        raise ValueError(
            f"not a fault event: {event!r} (expected one of {', '.join(EVENT_TYPES)})"
        )
    return name


def field_unit(cls: type[FaultEvent], name: str, sensor: str | None = None) -> str | None:
    """The declared unit of field ``name`` of event class ``cls``.

    Parameters
    ----------
    cls : an event class (a value of :data:`EVENT_TYPES`).
    name : one of its fields.
    sensor : "gyro" or "accel", for the IMU fields whose unit depends on the sensor.

    Returns
    -------
    str or None
        The unit (``"s"``, ``"Pa"``, ``"rad/s"``...; ``"1"`` for a dimensionless quantity),
        None for a field that is not a quantity (``sensor``, ``axis``, a flag) and for a
        sensor-dependent unit asked without ``sensor``.
    """
    extra = cls.model_fields[name].json_schema_extra
    unit = extra.get("unit") if isinstance(extra, dict) else None
    if isinstance(unit, dict):
        unit = unit.get(sensor) if sensor is not None else None
    return unit if isinstance(unit, str) else None
