"""Scenario files: YAML validated by frozen pydantic models, with file:line error messages.

A scenario says everything a run needs: aircraft, start state, flight plan, duration, sensor
presets with overrides, seed, fusion settings, pass criteria and a timeline of fault events.
Human units live here and only here; the builders return the SI objects of ``sim`` and
``scenarios.summary``.

Units: a key whose name ends in a unit (``duration_s``, ``bearing_deg``, ``offset_hpa``,
``value_mg``...) takes a plain number in that unit. A key without a unit in its name (``at``
and ``duration`` of an event, ``max`` of a criterion) takes a number in the natural unit (s for
times, the metric's own unit for limits) or a string with a unit: ``"5 min"``, ``"25 m"``,
``"1.5 km"``, ``"0.5 deg"``, ``"2 m/s"``. Conversions happen once, on load.

Entry points:

* :func:`load_scenario` reads and validates a file; every problem is a :class:`ScenarioError`
  whose ``str()`` is one line: ``FILE:LINE: KEY: what is wrong``.
* :func:`json_schema` is the JSON Schema (Draft 2020-12) of the file format, for editors.
* :func:`list_library` lists the scenarios shipped in ``scenarios/library``.
* :class:`Scenario` builds :class:`~sim.flight.FlightConfig`, :class:`~sim.plans.FlightPlan`,
  :class:`~sim.sensors.SensorSuiteConfig`, the ``sim.faults`` events and the
  :class:`~scenarios.summary.Criterion` tuple.
"""

from __future__ import annotations

import copy
import difflib
import functools
import math
import re
from collections.abc import Callable, Iterator, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, ClassVar, Literal, Self, cast

import yaml
from pydantic import (
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Discriminator,
    Field,
    PrivateAttr,
    Tag,
    ValidationError,
    ValidationInfo,
    WithJsonSchema,
    create_model,
    field_validator,
    model_validator,
)
from pydantic.fields import FieldInfo
from pydantic_core import PydanticCustomError

from physconst import G0_MPS2
from scenarios.metrics import ERROR_AT_S
from scenarios.summary import Criterion
from sim import faults, presets
from sim.baro import BaroConfig
from sim.flight import FlightConfig, StartState, available_aircraft, suggested_start
from sim.gnss import GnssConfig
from sim.imu import AccelConfig, GyroConfig, ImuConfig
from sim.mag import MagConfig
from sim.plans import FlightPlan, available_plans, load_plan
from sim.sensors import SensorSuiteConfig

__all__ = [
    "ALTITUDE_METHODS",
    "BRIDGE_METHODS",
    "KNOWN_METRICS",
    "LIBRARY_DIR",
    "Scenario",
    "ScenarioError",
    "json_schema",
    "list_library",
    "load_scenario",
    "metric_unit",
    "parse_quantity",
]

BRIDGE_METHODS: tuple[str, ...] = ("none", "gmdh", "gmdh-pseudo", "mlp", "rbf", "bp-parallel")
"""Outage-bridging methods a scenario may name (``fusion.bridging.registry``)."""
ALTITUDE_METHODS: tuple[str, ...] = ("ekf", "loop", "loop-mpc", "loop-kf")
"""Vertical-channel methods a scenario may name (``fusion.altitude``)."""

LIBRARY_DIR = Path(__file__).resolve().parent / "library"
"""The scenario library shipped with hilnav."""


# Turbulence names -> severity of sim.flight's MIL-F-8785C mapping (see sim/flight.py).
_TURBULENCE: dict[str, float] = {"none": 0.0, "light": 0.43, "moderate": 0.57, "severe": 0.86}


class ScenarioError(ValueError):
    """A scenario file (or override) is invalid; ``str()`` is the one-line user message.

    Attributes
    ----------
    path : the scenario file, if known.
    line : 1-based line in that file, if known.
    key : dotted key that is wrong (``events[2].at``), if any.
    """

    def __init__(
        self, message: str, *, path: Path | None = None, line: int | None = None, key: str = ""
    ) -> None:
        self.path = path
        self.line = line
        self.key = key
        self.detail = message
        where = ""
        if path is not None:
            where = f"{path}:{line}: " if line is not None else f"{path}: "
        super().__init__(f"{where}{key + ': ' if key else ''}{message}")


# ----------------------------------------------------------------------------------- units
# unit -> (dimension, factor to the dimension's base). Bases are the units of summary.json:
# m, s, m/s and *degrees* (the summary reports angles in degrees).
_UNITS: dict[str, tuple[str, float]] = {
    "m": ("length", 1.0),
    "km": ("length", 1000.0),
    "cm": ("length", 0.01),
    "ft": ("length", 0.3048),
    "nmi": ("length", 1852.0),
    "s": ("time", 1.0),
    "ms": ("time", 1e-3),
    "min": ("time", 60.0),
    "h": ("time", 3600.0),
    "deg": ("angle", 1.0),
    "°": ("angle", 1.0),
    "rad": ("angle", 180.0 / math.pi),
    "mrad": ("angle", 0.18 / math.pi),
    "arcmin": ("angle", 1.0 / 60.0),
    "m/s": ("speed", 1.0),
    "km/h": ("speed", 1.0 / 3.6),
    "kn": ("speed", 1852.0 / 3600.0),
    "ft/min": ("speed", 0.3048 / 60.0),
}
_UNIT_OF_TOKEN: dict[str, str] = {"m": "m", "s": "s", "deg": "deg", "mps": "m/s"}
_QUANTITY = re.compile(
    r"^\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*([A-Za-z°/]+(?:/[A-Za-z]+)?)?\s*$"
)


def parse_quantity(value: Any, unit: str | None) -> float:
    """A number with an optional unit, converted to ``unit``.

    Parameters
    ----------
    value : a number (already in ``unit``) or a string such as ``"5 min"``, ``"25 m"``,
        ``"0.5 deg"``, ``"2 m/s"`` (a string without a unit is in ``unit``).
    unit : the target unit (a key of the unit table: m, s, deg, m/s...), or None for a
        dimensionless quantity (then only plain numbers are accepted).

    Returns
    -------
    float : the value in ``unit``.

    Raises
    ------
    ValueError
        Not a number, an unknown unit, or a unit of the wrong dimension; the message names
        the accepted units.
    """
    if isinstance(value, bool):
        raise ValueError(f"expected a number, got {value!r}")
    if isinstance(value, int | float):
        number, given = float(value), None
    elif isinstance(value, str):
        m = _QUANTITY.match(value)
        if m is None:
            raise ValueError(f"cannot read {value!r} as a number with a unit, e.g. '25 m'")
        number, given = float(m.group(1)), m.group(2)
    else:
        raise ValueError(f"expected a number or a string with a unit, got {value!r}")
    if not math.isfinite(number):
        raise ValueError(f"{value!r} is not finite")
    if given is None:
        return number
    if given not in _UNITS:
        raise ValueError(f"unknown unit {given!r} in {value!r}; known units: {', '.join(_UNITS)}")
    if unit is None:
        raise ValueError(f"{value!r}: this value has no unit, give a plain number")
    dim, factor = _UNITS[given]
    want_dim, want_factor = _UNITS[unit]
    if dim != want_dim:
        same = ", ".join(u for u, (d, _) in _UNITS.items() if d == want_dim)
        article = "an" if dim[0] in "aeiou" else "a"
        raise ValueError(f"{value!r} is {article} {dim}, expected a {want_dim} ({same})")
    return number * factor / want_factor


_TIME_PATTERN = r"^\s*[+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?\s*(s|ms|min|h)?\s*$"


def _start_time(value: Any) -> float:
    t = parse_quantity(value, "s")
    if t < 0.0:
        raise ValueError(f"must be >= 0 s (got {value!r})")
    return t


def _span(value: Any) -> float:
    t = parse_quantity(value, "s")
    if t <= 0.0:
        raise ValueError(f"must be > 0 s (got {value!r})")
    return t


StartTime = Annotated[
    float,
    BeforeValidator(_start_time),
    WithJsonSchema({"anyOf": [{"type": "number", "minimum": 0},
                              {"type": "string", "pattern": _TIME_PATTERN}]}),
]
"""A time >= 0: seconds as a number, or a string with a unit ("90 s", "5 min", "1.5 h")."""
Span = Annotated[
    float,
    BeforeValidator(_span),
    WithJsonSchema({"anyOf": [{"type": "number", "exclusiveMinimum": 0},
                              {"type": "string", "pattern": _TIME_PATTERN}]}),
]
"""A length of time > 0, as :data:`StartTime`."""


# --------------------------------------------------------------------------------- metrics
def _metric_names() -> tuple[str, ...]:
    at = [str(s) for s in ERROR_AT_S]
    outage = [
        "start_s", "end_s", "duration_s", "horizontal_rmse_m", "horizontal_max_m",
        "vertical_rmse_m", "vertical_max_m", "cep50_m", "cep95_m", "nees_mean", "reconverge_s",
    ]
    names = [f"outages.{n}" for n in outage]
    names += [f"outages.horizontal_error_m_at.{s}" for s in at]
    names += [f"outages.vertical_error_m_at.{s}" for s in at]
    names += [f"outages.rmse.{n}" for n in
              ("lat_deg", "lon_deg", "h_m", "vn_mps", "ve_mps", "vd_mps", "horizontal_m")]
    names += [f"outages.containment_3sigma.{n}" for n in ("horizontal", "vertical")]
    names += [f"events.{n}" for n in (
        "start_s", "end_s", "detect_s", "max_horizontal_m", "max_vertical_m", "reaccept_count",
        "bad_fixes_fused", "reconverge_s")]
    names += [f"gnss_on.{n}" for n in (
        "horizontal_rmse_m", "vertical_rmse_m", "roll_rmse_deg", "pitch_rmse_deg",
        "yaw_rmse_deg")]
    names += [f"nees.{n}" for n in (
        "nees_mean", "rms_z_pos", "rms_z_vel", "rms_z_att", "within_3sigma_pos",
        "within_3sigma_vel", "within_3sigma_att")]
    names += [f"containment_3sigma.{n}" for n in ("horizontal", "vertical")]
    names += [f"rejections_outside_events.{n}" for n in (
        "gnss_rejected", "baro_rejected", "mag_rejected")]
    names += ["sim_duration_s", "realtime_factor"]
    return tuple(names)


KNOWN_METRICS: tuple[str, ...] = _metric_names()
"""Dotted summary.json paths a criterion may name (``health.*`` is also accepted). Through a
list (``outages``, ``events``) the worst value counts (largest for ``max``, smallest for
``min``)."""


def metric_unit(path: str) -> str | None:
    """Unit of a summary.json value from its field name (``_m`` m, ``_s`` s, ``_deg`` deg,
    ``_mps`` m/s; the innermost named part wins), or None for a dimensionless value."""
    for part in reversed(path.split(".")):
        for token in reversed(part.split("_")):
            if token in _UNIT_OF_TOKEN:
                return _UNIT_OF_TOKEN[token]
    return None


# ---------------------------------------------------------------------------- model bases
class _Strict(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid")


def _custom(
    message: str, loc: tuple[str | int, ...] = (), other: tuple[str | int, ...] = ()
) -> PydanticCustomError:
    """A validation error whose ``loc`` (relative to the raising model) rides in its context,
    so :func:`load_scenario` can point at the right key of a cross-field check."""
    return PydanticCustomError("scenario", "{message}", {"message": message, "loc": loc,
                                                         "other": other})


def _attribute_docs(cls: type) -> dict[str, str]:
    """``name : text`` lines of a numpydoc ``Attributes`` section (the sim configs document
    their fields there), for the JSON Schema descriptions."""
    doc = cls.__doc__ or ""
    out: dict[str, str] = {}
    current: list[str] = []
    for line in doc.splitlines():
        m = re.match(r"^\s{4}([a-z_0-9]+(?:, [a-z_0-9]+)*) : (.*)$", line)
        if m:
            current = [n.strip() for n in m.group(1).split(",")]
            for n in current:
                out[n] = m.group(2).strip()
        elif current and line.startswith(" " * 8) and line.strip():
            for n in current:
                out[n] += " " + line.strip()
        else:
            current = []
    return out


def _overrides(
    config: type[BaseModel],
    name: str,
    *,
    base: type[BaseModel] = _Strict,
) -> type[BaseModel]:
    """A model with every field of ``config`` optional (same types and bounds), for
    overriding a preset field by field."""
    docs = _attribute_docs(config)
    fields: dict[str, Any] = {}
    for field_name, info in config.model_fields.items():
        new: FieldInfo = copy.copy(info)
        new.default = None
        new.default_factory = None
        if new.description is None and field_name in docs:
            new.description = docs[field_name]
        annotation: Any = info.annotation
        fields[field_name] = (annotation | None, new)
    model: type[BaseModel] = create_model(name, __base__=base, __module__=__name__, **fields)
    model.__doc__ = f"Overrides of {config.__name__} (every field optional; units in the names)."
    return model


def _extra(keyword: str, values: Sequence[str]) -> Any:
    """``json_schema_extra`` listing the accepted names (enum) or typical ones (examples)."""
    return {keyword: list(values)}


def _first_error(error: ValidationError) -> tuple[tuple[str | int, ...], str]:
    e = error.errors()[0]
    return tuple(e["loc"]), _clean_msg(e["msg"])


def _clean_msg(msg: str) -> str:
    return msg.removeprefix("Value error, ").removeprefix("Assertion failed, ")


# --------------------------------------------------------------------------------- start
if TYPE_CHECKING:
    StartSection = StartState
    GyroOverrides = GyroConfig
    AccelOverrides = AccelConfig
else:
    StartSection = _overrides(StartState, "StartSection")
    StartSection.__doc__ = (
        "Start state; omitted fields take the aircraft's suggested trim altitude and airspeed "
        "(sim.flight.suggested_start) and sim.flight.StartState's defaults."
    )
    GyroOverrides = _overrides(GyroConfig, "GyroOverrides")
    AccelOverrides = _overrides(AccelConfig, "AccelOverrides")


# ------------------------------------------------------------------------------- sensors
class _PresetSection(_Strict):
    """A sensor: a named preset, then field-by-field overrides in the preset's units."""

    _kind: ClassVar[str] = ""
    _names: ClassVar[tuple[str, ...]] = ()
    _lookup: ClassVar[Any] = None
    _not_config: ClassVar[tuple[str, ...]] = ("preset",)

    preset: str = ""  # every section sets its own default

    @field_validator("preset")
    @classmethod
    def _known_preset(cls, value: str) -> str:
        if value not in cls._names:
            raise ValueError(_unknown(f"{cls._kind} preset", value, cls._names))
        return value

    def config(self) -> Any:
        """The preset with this section's overrides applied (validated)."""
        update = {
            k: v for k, v in self.model_dump(exclude_unset=True).items()
            if k not in self._not_config
        }
        base = type(self)._lookup(self.preset)
        return base.model_copy(update=update) if update else base

    @model_validator(mode="after")
    def _overrides_apply(self) -> Self:
        try:
            self.config()
        except ValidationError as error:
            loc, msg = _first_error(error)
            raise _custom(msg, loc) from None
        return self


def _section_field(kind: str, names: list[str], default: str) -> Any:
    return Field(
        default=default,
        description=f"{kind} preset (sim.presets): {', '.join(names)}",
        json_schema_extra=_extra("enum", list(names)),
    )


class ImuSection(_PresetSection):
    """IMU: preset, output rate and datasheet-unit overrides of the gyro and accelerometer."""

    _kind = "IMU"
    _names = tuple(presets.available_imu_presets())
    _lookup = staticmethod(presets.imu_preset)
    _not_config = ("preset", "rate_hz")

    preset: str = _section_field("IMU", presets.available_imu_presets(), "industrial-mems")
    rate_hz: float | None = Field(
        default=None, gt=0.0, description="IMU output rate, Hz (must divide sim_rate_hz); "
        "omitted: the simulation rate."
    )
    gyro: GyroOverrides | None = None
    accel: AccelOverrides | None = None


def _flat_section(
    config: type[BaseModel],
    name: str,
    kind: str,
    available: Callable[[], list[str]],
    lookup: Callable[[str], Any],
    default: str,
    *,
    with_rate: bool,
    doc: str,
) -> type[_PresetSection]:
    """A sensor section whose overrides sit next to ``preset`` (the sensor's config fields)."""
    names = available()
    fields: dict[str, Any] = {"preset": (str, _section_field(kind, names, default))}
    if with_rate:
        fields["rate_hz"] = (
            float, Field(default=50.0, gt=0.0, description=f"{kind} output rate, Hz."),
        )
    base: Any = create_model(
        f"_{name}Base", __base__=_PresetSection, __module__=__name__, **fields
    )
    base._kind = kind
    base._names = tuple(names)
    base._lookup = staticmethod(lookup)
    base._not_config = ("preset", "rate_hz") if with_rate else ("preset",)
    model: Any = _overrides(config, name, base=base)
    model.__doc__ = doc
    return cast(type[_PresetSection], model)


if TYPE_CHECKING:
    class GnssSection(_PresetSection):
        """GNSS receiver section (typing stand-in; built by _flat_section)."""

    class BaroSection(_PresetSection):
        """Barometer section (typing stand-in)."""

        rate_hz: float = 50.0

    class MagSection(_PresetSection):
        """Magnetometer section (typing stand-in)."""

        rate_hz: float = 50.0
else:
    GnssSection = _flat_section(
        GnssConfig, "GnssSection", "GNSS", presets.available_gnss_presets, presets.gnss_preset,
        "modern", with_rate=False,
        doc="GNSS receiver: preset, then overrides (rate_hz, latency_s, sigmas...).",
    )
    BaroSection = _flat_section(
        BaroConfig, "BaroSection", "barometer", presets.available_baro_presets,
        presets.baro_preset, "ms5611", with_rate=True,
        doc="Barometer: preset, output rate, then overrides (noise, bias, the non-standard "
        "day's sea_level_temperature_offset_k / sea_level_pressure_offset_hpa...).",
    )
    MagSection = _flat_section(
        MagConfig, "MagSection", "magnetometer", presets.available_mag_presets,
        presets.mag_preset, "consumer", with_rate=True,
        doc="Magnetometer: preset, output rate, then overrides (µT).",
    )


class Sensors(_Strict):
    """The sensor suite."""

    imu: ImuSection = ImuSection()
    gnss: GnssSection = GnssSection()
    baro: BaroSection = BaroSection()
    mag: MagSection = MagSection()


# -------------------------------------------------------------------------------- fusion
class FusionSection(_Strict):
    """Fusion settings: outage-bridging and vertical-channel methods."""

    bridge: str = Field(
        default="none", description="GNSS-outage bridging method.",
        json_schema_extra=_extra("enum", list(BRIDGE_METHODS)),
    )
    altitude: str = Field(
        default="ekf", description="Vertical-channel method.",
        json_schema_extra=_extra("enum", list(ALTITUDE_METHODS)),
    )

    @field_validator("bridge")
    @classmethod
    def _known_bridge(cls, value: str) -> str:
        if value not in BRIDGE_METHODS:
            raise ValueError(_unknown("bridging method", value, BRIDGE_METHODS))
        return value

    @field_validator("altitude")
    @classmethod
    def _known_altitude(cls, value: str) -> str:
        if value not in ALTITUDE_METHODS:
            raise ValueError(_unknown("altitude method", value, ALTITUDE_METHODS))
        return value


def _unknown(kind: str, value: str, valid: Sequence[str]) -> str:
    close = difflib.get_close_matches(str(value), list(valid), n=1)
    hint = f" (did you mean {close[0]!r}?)" if close else ""
    return f"unknown {kind} {value!r}{hint}; valid: {', '.join(valid)}"


# ------------------------------------------------------------------------------ criteria
class CriterionSpec(_Strict):
    """A pass criterion: the summary.json value at ``metric`` must be <= ``max`` (or >= ``min``).

    Through a list (all outages, all events) the worst value counts. Items without the value
    are skipped unless ``fail_if_missing`` (e.g. an event never detected has no ``detect_s``).
    """

    name: str | None = Field(default=None, description="Label; default 'METRIC <= MAX'.")
    metric: str = Field(
        description="Dotted path into summary.json (worst case over all outages / events).",
        json_schema_extra={"anyOf": [{"enum": list(KNOWN_METRICS)},
                                     {"pattern": r"^health(\.[A-Za-z0-9_]+)+$"}]},
    )
    max: float | str | None = Field(
        default=None,
        description="Upper limit: a number in the metric's unit or a string with a unit, "
        "e.g. '25 m', '1.5 km', '0.5 deg', '2 m/s', '30 s'.",
    )
    min: float | str | None = Field(
        default=None, description="Lower limit (instead of max), e.g. 0.9 for a containment."
    )
    fail_if_missing: bool = Field(
        default=False, description="An item (outage, event) without the value fails."
    )

    @field_validator("metric")
    @classmethod
    def _known_metric(cls, value: str) -> str:
        if value in KNOWN_METRICS or re.fullmatch(r"health(\.[A-Za-z0-9_]+)+", value):
            return value
        raise ValueError(_unknown("metric", value, KNOWN_METRICS) + ", health.*")

    @model_validator(mode="after")
    def _one_limit(self) -> Self:
        if (self.max is None) == (self.min is None):
            raise _custom("give exactly one of max and min")
        key = "max" if self.max is not None else "min"
        try:
            self.limit()
        except ValueError as error:
            raise _custom(str(error), (key,)) from None
        return self

    @property
    def op(self) -> Literal["<=", ">="]:
        """``"<="`` for ``max``, ``">="`` for ``min``."""
        return "<=" if self.max is not None else ">="

    def limit(self) -> float:
        """The limit in the unit of the summary field (m, s, deg, m/s or dimensionless)."""
        raw = self.max if self.max is not None else self.min
        return parse_quantity(raw, metric_unit(self.metric))

    def criterion(self) -> Criterion:
        """The :class:`~scenarios.summary.Criterion` this spec describes."""
        raw = self.max if self.max is not None else self.min
        name = self.name or f"{self.metric} {self.op} {raw}"
        return Criterion(name=name, path=self.metric, limit=self.limit(), op=self.op,
                         none_fails=self.fail_if_missing)


# -------------------------------------------------------------------------------- events
def _axis(value: Any) -> Any:
    if isinstance(value, str) and value.lower() in ("x", "y", "z"):
        return "xyz".index(value.lower())
    return value


Axis = Annotated[
    Literal[0, 1, 2], BeforeValidator(_axis, json_schema_input_type=Literal[0, 1, 2, "x", "y", "z"])
]
"""Body axis (FRD): 0/x forward, 1/y right, 2/z down."""


class _Event(_Strict):
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
            raise _custom(f"a {self.sensor} step takes {want}, not {other}", (other,))
        if getattr(self, want) is None:
            raise _custom(f"a {self.sensor} step needs {want}")
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
            raise _custom(f"a {self.sensor} saturation takes {want}, not {other}", (other,))
        if getattr(self, want) is None:
            raise _custom(f"a {self.sensor} saturation needs {want}")
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
        raise _custom(f"give one of {names[0]} and {names[1]}, not both", (names[1],))


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

# ------------------------------------------------------------------------------ scenario
def _turbulence(value: Any) -> Any:
    if isinstance(value, str):
        if value not in _TURBULENCE:
            raise ValueError(_unknown("turbulence level", value, list(_TURBULENCE)))
        return _TURBULENCE[value]
    return value


Turbulence = Annotated[
    float,
    BeforeValidator(
        _turbulence,
        json_schema_input_type=float | Literal["none", "light", "moderate", "severe"],
    ),
]


class InlinePlan(FlightPlan):
    """A flight plan written inside the scenario (``name`` defaults to the scenario's)."""

    name: str = Field(default="inline", min_length=1)


def _plan_kind(value: Any) -> str:
    return "inline" if isinstance(value, Mapping | FlightPlan) else "name"


PlanRef = Annotated[
    Annotated[str, Tag("name")] | Annotated[InlinePlan, Tag("inline")],
    Discriminator(_plan_kind),
]


class Scenario(_Strict):
    """One scenario file (see the module docstring; ``hilnav schema`` prints the JSON Schema).

    Build the simulation objects with :meth:`flight_config`, :meth:`flight_plan`,
    :meth:`sensor_config`, :meth:`fault_events` and :meth:`criteria`.
    """

    model_config = ConfigDict(frozen=True, extra="forbid", populate_by_name=True,
                              title="hilnav scenario")

    name: str = Field(default="", description="Scenario name; default: the file name.")
    description: str = ""
    aircraft: str = Field(
        default="c172x", description="JSBSim aircraft (hilnav list).",
        json_schema_extra=_extra("enum", available_aircraft()),
    )
    start: StartSection = Field(default_factory=lambda: StartSection())
    plan: PlanRef = Field(
        default="racetrack",
        description="A packaged plan name, a plan YAML path relative to this file, or an "
        "inline plan (description, frame, legs, repeat).",
        json_schema_extra=_extra("examples", available_plans()),
    )
    duration_s: float = Field(gt=0.0, le=86400.0, description="Simulated flight time, s.")
    seed: int = Field(default=1, ge=0, le=2**31 - 1, description="Seed of every random stream.")
    sim_rate_hz: float = Field(default=200.0, ge=50.0, le=400.0,
                               description="Flight dynamics (JSBSim) rate, Hz.")
    wind_ned_mps: tuple[float, float, float] = Field(
        default=(0.0, 0.0, 0.0), description="Steady wind the air moves *towards*, NED m/s."
    )
    turbulence: Turbulence = Field(
        default=0.0, ge=0.0, le=1.0,
        description="Severity 0..1 or none / light / moderate / severe (MIL-F-8785C).",
    )
    sensors: Sensors = Field(default_factory=lambda: Sensors())
    fusion: FusionSection = Field(default_factory=lambda: FusionSection())
    pass_criteria: tuple[CriterionSpec, ...] = Field(
        default=(), alias="criteria", description="All must hold for the run to pass."
    )
    events: tuple[Event, ...] = Field(default=(), description="Fault timeline.")

    _plan: FlightPlan | None = PrivateAttr(default=None)
    _base_dir: Path | None = PrivateAttr(default=None)

    @model_validator(mode="before")
    @classmethod
    def _name_inline_plan(cls, data: Any) -> Any:
        # An inline plan needs no name of its own: it takes the scenario's.
        if isinstance(data, Mapping) and isinstance(data.get("plan"), Mapping):
            plan = data["plan"]
            if "name" not in plan:
                data = {**data, "plan": {"name": str(data.get("name") or "inline"), **plan}}
        return data

    @field_validator("aircraft")
    @classmethod
    def _known_aircraft(cls, value: str) -> str:
        valid = available_aircraft()
        if value not in valid:
            raise ValueError(_unknown("aircraft", value, valid))
        return value

    @model_validator(mode="after")
    def _consistent(self, info: ValidationInfo) -> Self:
        context = info.context if isinstance(info.context, Mapping) else {}
        base_dir = context.get("base_dir")
        self._base_dir = Path(base_dir) if base_dir is not None else None
        self._plan = self._resolve_plan()
        try:
            self.start_state()
        except (ValueError, ValidationError) as error:
            raise _custom(_message(error), ("start",)) from None
        self._check_rates()
        for problem in _timeline_problems(self):
            raise problem
        self._check_criteria()
        return self

    # -- validation helpers ------------------------------------------------------------
    def _resolve_plan(self) -> FlightPlan:
        if isinstance(self.plan, FlightPlan):
            return self.plan
        if self.plan in available_plans():
            return load_plan(self.plan)
        path = Path(self.plan)
        if not path.is_absolute() and self._base_dir is not None:
            path = self._base_dir / path
        try:
            return load_plan(str(path))
        except ValidationError as error:
            loc, msg = _first_error(error)
            where = ".".join(str(p) for p in loc)
            raise _custom(f"flight plan {path}: {where}: {msg}", ("plan",)) from None
        except ValueError as error:
            raise _custom(str(error), ("plan",)) from None

    def _check_rates(self) -> None:
        sim = self.sim_rate_hz
        imu = self.sensors.imu.rate_hz
        if imu is not None:
            ratio = sim / imu
            if round(ratio) < 1 or abs(ratio - round(ratio)) > 1e-9 * ratio:
                raise _custom(
                    f"IMU rate {imu:g} Hz must divide sim_rate_hz ({sim:g} Hz)",
                    ("sensors", "imu", "rate_hz"),
                )
        for key, rate in (
            ("gnss", self.sensors.gnss.config().rate_hz),
            ("baro", self.sensors.baro.rate_hz),
            ("mag", self.sensors.mag.rate_hz),
        ):
            if rate > sim * (1.0 + 1e-12):
                raise _custom(
                    f"{key} rate {rate:g} Hz exceeds sim_rate_hz ({sim:g} Hz)",
                    ("sensors", key, "rate_hz"),
                )

    def _check_criteria(self) -> None:
        spans = [
            (e.duration if e.duration is not None else self.duration_s - e.at)
            for e in self.events if e.type in ("gnss_outage", "gnss_jamming")
        ]
        for i, c in enumerate(self.pass_criteria):
            if c.metric.startswith("events.") and not self.events:
                raise _custom(
                    f"metric {c.metric!r} scores the scenario's events, and it has none",
                    ("criteria", i, "metric"),
                )
            if not c.metric.startswith("outages."):
                continue
            if not spans:
                raise _custom(
                    f"metric {c.metric!r} is measured during GNSS outages, and this scenario "
                    "has no gnss_outage or gnss_jamming event",
                    ("criteria", i, "metric"),
                )
            m = re.fullmatch(r"outages\.(?:horizontal|vertical)_error_m_at\.(\d+)", c.metric)
            if m and max(spans) < float(m.group(1)):
                raise _custom(
                    f"no outage lasts {m.group(1)} s (longest {max(spans):g} s), so "
                    f"{c.metric!r} is never measured",
                    ("criteria", i, "metric"),
                )

    # -- builders ------------------------------------------------------------------------
    @property
    def source_dir(self) -> Path | None:
        """Directory of the scenario file (relative plan paths resolve against it)."""
        return self._base_dir

    @property
    def imu_preset(self) -> str:
        """The IMU preset name (what the filter is tuned for, see hil.tuning)."""
        return self.sensors.imu.preset

    def start_state(self) -> StartState:
        """The start state: the given fields over the aircraft's suggested trim point."""
        given = self.start.model_dump(exclude_unset=True)
        return suggested_start(self.aircraft, **given)

    def flight_config(self, seed: int | None = None) -> FlightConfig:
        """JSBSim flight configuration (``seed`` overrides the scenario's seed)."""
        return FlightConfig(
            aircraft=self.aircraft,
            rate_hz=self.sim_rate_hz,
            start=self.start_state(),
            wind_ned_mps=self.wind_ned_mps,
            turbulence=self.turbulence,
            seed=self.seed if seed is None else seed,
        )

    def flight_plan(self) -> FlightPlan:
        """The flight plan (packaged, from a file next to the scenario, or inline)."""
        return self._plan if self._plan is not None else self._resolve_plan()

    def sensor_config(self) -> SensorSuiteConfig:
        """Sensor suite: presets with this scenario's overrides, in datasheet units."""
        s = self.sensors
        imu = self.imu_config()
        return SensorSuiteConfig(
            imu=imu,
            gnss=s.gnss.config(),
            baro=s.baro.config(),
            mag=s.mag.config(),
            imu_rate_hz=s.imu.rate_hz,
            baro_rate_hz=s.baro.rate_hz,
            mag_rate_hz=s.mag.rate_hz,
        )

    def imu_config(self) -> ImuConfig:
        """The simulated IMU: the preset with the scenario's gyro / accel overrides."""
        s = self.sensors.imu
        update: dict[str, Any] = {}
        if s.gyro is not None:
            update["gyro"] = s.gyro.model_dump(exclude_unset=True)
        if s.accel is not None:
            update["accel"] = s.accel.model_dump(exclude_unset=True)
        base = presets.imu_preset(s.preset)
        return base.model_copy(update=update) if update else base

    def fault_events(self) -> tuple[faults.FaultEvent, ...]:
        """The timeline as ``sim.faults`` events, SI units, in file order."""
        return tuple(e.to_fault() for e in self.events)

    def criteria(self) -> tuple[Criterion, ...]:
        """Pass criteria for :func:`scenarios.summary.build_summary`."""
        return tuple(c.criterion() for c in self.pass_criteria)

    def outage_windows(self) -> tuple[tuple[float, float], ...]:
        """``(start_s, end_s)`` of every gnss_outage and gnss_jamming event, clipped to the
        flight, in file order (the spans the summary's ``outages`` are meant to score)."""
        return tuple(
            (e.at, min(self.duration_s, e.at + e.duration) if e.duration else self.duration_s)
            for e in self.events if e.type in ("gnss_outage", "gnss_jamming")
        )

    def with_overrides(
        self,
        *,
        seed: int | None = None,
        bridge: str | None = None,
        altitude: str | None = None,
        duration_s: float | None = None,
    ) -> Scenario:
        """A re-validated copy with command-line overrides applied.

        Raises
        ------
        ScenarioError
            The result is invalid (e.g. a shorter duration leaves an event outside the flight).
        """
        data = self.model_dump(by_alias=True, exclude_unset=True)
        data.setdefault("duration_s", self.duration_s)
        if seed is not None:
            data["seed"] = seed
        if duration_s is not None:
            data["duration_s"] = duration_s
        if bridge is not None or altitude is not None:
            fusion = dict(data.get("fusion", {}))
            if bridge is not None:
                fusion["bridge"] = bridge
            if altitude is not None:
                fusion["altitude"] = altitude
            data["fusion"] = fusion
        try:
            return Scenario.model_validate(data, context={"base_dir": self._base_dir})
        except ValidationError as error:
            raise _scenario_error(error, None, None, data) from None


def _message(error: Exception) -> str:
    if isinstance(error, ValidationError):
        loc, msg = _first_error(error)
        return f"{'.'.join(str(p) for p in loc)}: {msg}" if loc else msg
    return str(error)


def _timeline_problems(s: Scenario) -> Iterator[PydanticCustomError]:
    """Events outside the flight, contradictory overlaps and impossible rates, in file order."""
    end = s.duration_s
    for i, e in enumerate(s.events):
        if e.at >= end:
            yield _custom(
                f"{e.type} starts at {e.at:g} s, at or after the end of the flight "
                f"(duration_s {end:g})", ("events", i, "at"),
            )
        stop = end if e.duration is None else e.at + e.duration
        if stop > end * (1.0 + 1e-12):
            yield _custom(
                f"{e.type} ends at {stop:g} s, after the end of the flight (duration_s "
                f"{end:g}); shorten it or leave duration out to last until the end",
                ("events", i, "duration"),
            )
        if isinstance(e, GnssRateEvent):
            receiver = s.sensors.gnss.config().rate_hz
            if e.rate_hz > receiver:
                yield _custom(
                    f"gnss_rate {e.rate_hz:g} Hz is above the receiver's {receiver:g} Hz",
                    ("events", i, "rate_hz"),
                )
    built: list[faults.FaultEvent] = []
    for i, e in enumerate(s.events):
        try:
            built.append(e.to_fault())
        except ValueError as error:  # sim.faults' own field checks (ours should catch first)
            yield _custom(str(error), ("events", i))
            return
    # Which overlaps contradict each other is sim.faults' rule (check_events); asking it pair
    # by pair tells which two events clash, so the message can point at both lines.
    for j in range(len(built)):
        for i in range(j):
            try:
                faults.check_events([built[i], built[j]], end)
            except ValueError as error:
                reason = str(error).removeprefix("fault timeline: ")
                reason = reason.replace("event 0 (", f"events[{i}] (", 1)
                reason = reason.replace("event 1 (", f"events[{j}] (", 1)
                yield _custom(reason, ("events", j), ("events", i))
    try:
        faults.check_events(built, end)
    except ValueError as error:
        yield _custom(str(error), ("events",))


# --------------------------------------------------------------------------- load / lines
class _KeyLines:
    """Line numbers of a YAML document's keys, from its composed node tree."""

    def __init__(self, root: yaml.Node | None) -> None:
        self.root = root

    def locate(self, loc: Sequence[str | int]) -> tuple[int | None, list[str | int]]:
        """1-based line of the deepest node ``loc`` reaches, and the loc parts that matched
        (union tags that are not keys are dropped; a last part that is not in the file, e.g.
        a missing key, is kept)."""
        node = self.root
        line = node.start_mark.line + 1 if node is not None else None
        kept: list[str | int] = []
        for k, part in enumerate(loc):
            last = k == len(loc) - 1
            if isinstance(node, yaml.MappingNode) and isinstance(part, str):
                for key_node, value_node in node.value:
                    if getattr(key_node, "value", None) == part:
                        line = key_node.start_mark.line + 1
                        node = value_node
                        kept.append(part)
                        break
                else:
                    if last:
                        kept.append(part)
                continue
            if isinstance(node, yaml.SequenceNode) and isinstance(part, int):
                if 0 <= part < len(node.value):
                    node = node.value[part]
                    line = node.start_mark.line + 1
                    kept.append(part)
                    continue
            if last or isinstance(part, int):
                kept.append(part)
        return line, kept


def _dotted(loc: Sequence[str | int]) -> str:
    out = ""
    for part in loc:
        out += f"[{part}]" if isinstance(part, int) else (f".{part}" if out else str(part))
    return out


def _duplicate_keys(node: yaml.Node | None) -> tuple[int, str] | None:
    if isinstance(node, yaml.MappingNode):
        seen: set[Any] = set()
        for key_node, value_node in node.value:
            key = getattr(key_node, "value", None)
            if key in seen:
                return key_node.start_mark.line + 1, str(key)
            seen.add(key)
            found = _duplicate_keys(value_node)
            if found:
                return found
    elif isinstance(node, yaml.SequenceNode):
        for item in node.value:
            found = _duplicate_keys(item)
            if found:
                return found
    return None


def _allowed_keys(loc: Sequence[str | int], data: Any) -> list[str]:
    """Keys the schema allows in the mapping at ``loc`` (for 'did you mean')."""
    schema = _schema()
    defs = schema.get("$defs", {})

    def resolve(node: dict[str, Any], value: Any) -> dict[str, Any]:
        for _ in range(10):
            if "$ref" in node:
                node = defs[node["$ref"].rsplit("/", 1)[-1]]
            elif "oneOf" in node or "anyOf" in node:
                branches = node.get("oneOf") or node.get("anyOf") or []
                tag = value.get("type") if isinstance(value, dict) else None
                mapping = node.get("discriminator", {}).get("mapping", {})
                if tag in mapping:
                    node = defs[mapping[tag].rsplit("/", 1)[-1]]
                    continue
                objects = [
                    b for b in branches
                    if "$ref" in b or b.get("type") == "object"
                ]
                if not objects:
                    return node
                node = objects[0]
            else:
                return node
        return node

    node: dict[str, Any] = schema
    value = data
    for part in loc:
        node = resolve(node, value)
        if isinstance(part, int):
            node = node.get("items", {})
            value = value[part] if isinstance(value, list) and part < len(value) else None
        elif part in node.get("properties", {}):
            node = node["properties"][part]
            value = value.get(part) if isinstance(value, dict) else None
    node = resolve(node, value)
    return list(node.get("properties", {}))


# Error types whose message already says enough without echoing the input value.
_NO_INPUT_ECHO = frozenset({"scenario", "value_error", "assertion_error", "extra_forbidden",
                            "missing", "union_tag_invalid", "union_tag_not_found"})


def _scenario_error(
    error: ValidationError, path: Path | None, lines: _KeyLines | None, data: Any
) -> ScenarioError:
    """The first validation problem as a one-line ScenarioError (file, line, key, message)."""
    e = error.errors()[0]
    loc: tuple[str | int, ...] = tuple(e["loc"])
    ctx = e.get("ctx") or {}
    msg = _clean_msg(e["msg"])
    other_line = None
    if e["type"] == "scenario":
        loc = loc + tuple(ctx.get("loc", ()))
        msg = ctx.get("message", msg)
        if lines is not None and ctx.get("other"):
            other_line, _ = lines.locate(tuple(ctx["other"]))
    line, kept = lines.locate(loc) if lines is not None else (None, list(loc))
    if e["type"] == "extra_forbidden" and kept:
        allowed = _allowed_keys(kept[:-1], data if isinstance(data, dict) else {})
        key = str(kept[-1])
        msg = _unknown("key", key, allowed) if allowed else f"unknown key {key!r}"
    elif e["type"] == "missing":
        msg = "required key is missing"
    elif e["type"] == "union_tag_invalid":
        msg = _unknown("event type", str(ctx.get("tag")), list(EVENT_SPECS))
        kept = [*kept, "type"]
        if lines is not None:
            line, _ = lines.locate(kept)
    elif e["type"] == "union_tag_not_found":
        msg = f"each event needs a 'type': one of {', '.join(EVENT_SPECS)}"
    if other_line is not None:
        msg += f" (see line {other_line})"
    elif e["type"] not in _NO_INPUT_ECHO and isinstance(
        e.get("input"), str | int | float
    ):
        msg += f" (got {e['input']!r})"
    return ScenarioError(msg, path=path, line=line, key=_dotted(kept))


def load_scenario(path: str | Path) -> Scenario:
    """Read and validate a scenario YAML file.

    Parameters
    ----------
    path : the file; a relative ``plan`` path inside it resolves against its directory.

    Returns
    -------
    Scenario : validated; ``name`` defaults to the file name without ``.yaml``.

    Raises
    ------
    ScenarioError
        Missing file, YAML syntax, duplicate or unknown key, bad value, unknown preset,
        an event outside the flight, contradictory overlapping events...: one line,
        ``FILE:LINE: KEY: message``.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ScenarioError("no such scenario file", path=path) from None
    except (OSError, UnicodeDecodeError) as error:
        raise ScenarioError(f"cannot read the file ({error})", path=path) from None
    try:
        root = yaml.compose(text, Loader=yaml.SafeLoader)
        data = yaml.safe_load(text)
    except yaml.MarkedYAMLError as error:
        mark = error.problem_mark or error.context_mark
        line = mark.line + 1 if mark is not None else None
        problem = error.problem or error.context or "syntax error"
        raise ScenarioError(f"not valid YAML: {problem}", path=path, line=line) from None
    except yaml.YAMLError as error:
        raise ScenarioError(f"not valid YAML: {error}", path=path) from None
    if not isinstance(data, dict):
        raise ScenarioError("a scenario must be a YAML mapping (key: value lines)", path=path,
                            line=1)
    duplicate = _duplicate_keys(root)
    if duplicate is not None:
        raise ScenarioError("key appears twice in the same mapping", path=path,
                            line=duplicate[0], key=duplicate[1])
    if not data.get("name"):
        data = {**data, "name": path.stem}
    try:
        scenario = Scenario.model_validate(data, context={"base_dir": path.parent})
    except ValidationError as error:
        raise _scenario_error(error, path, _KeyLines(root), data) from None
    return scenario


@functools.lru_cache(maxsize=1)
def _schema() -> dict[str, Any]:
    schema = Scenario.model_json_schema(by_alias=True)
    schema["$schema"] = "https://json-schema.org/draft/2020-12/schema"
    return schema


def json_schema() -> dict[str, Any]:
    """JSON Schema (Draft 2020-12) of scenario files, for editor completion and CI checks.

    Returns
    -------
    dict : a fresh copy (``hilnav schema`` prints it as JSON).
    """
    return copy.deepcopy(_schema())


def list_library() -> list[Path]:
    """The scenario files shipped in ``scenarios/library``, sorted by name."""
    return sorted(LIBRARY_DIR.glob("*.yaml"))
