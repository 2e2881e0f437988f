"""Sections of a scenario file: the start state, the sensors (a preset plus field overrides in
datasheet units; ``pitot: {preset: none}`` for an aircraft without an airspeed sensor) and the
fusion methods."""

from __future__ import annotations

import copy
import re
from collections.abc import Callable
from typing import TYPE_CHECKING, Annotated, Any, ClassVar, Literal, Self, cast

from pydantic import (
    BaseModel,
    BeforeValidator,
    Field,
    ValidationError,
    ValidationInfo,
    create_model,
    field_validator,
    model_validator,
)
from pydantic.fields import FieldInfo

from fusion.bridging.registry import BRIDGE_METHODS
from fusion.config import (
    AIRSPEED_MODES,
    ALIGN_MODES,
    ALTITUDE_METHODS,
    DEFAULT_AIRSPEED_MODE,
    DEFAULT_ALIGN_MODE,
)
from scenarios.schema.base import Strict, first_error, key_error, listing, unknown_name
from sim import presets
from sim.baro import BaroConfig
from sim.flight import StartState
from sim.gnss import GnssConfig
from sim.imu import AccelConfig, GyroConfig
from sim.mag import MagConfig
from sim.pitot import PitotConfig

__all__ = [
    "AccelOverrides",
    "BaroSection",
    "FusionSection",
    "GnssSection",
    "GyroOverrides",
    "ImuSection",
    "MagSection",
    "PitotSection",
    "Sensors",
    "StartSection",
]


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
    base: type[BaseModel] = Strict,
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
class _PresetSection(Strict):
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
            raise ValueError(unknown_name(f"{cls._kind} preset", value, cls._names))
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
            loc, msg = first_error(error)
            raise key_error(msg, loc) from None
        return self


def _section_field(kind: str, names: list[str], default: str) -> Any:
    return Field(
        default=default,
        description=f"{kind} preset (sim.presets): {', '.join(names)}",
        json_schema_extra=listing("enum", list(names)),
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


class _OptionalSensorSection(_PresetSection):
    """A sensor an aircraft may lack: the preset ``none`` gives no sensor (and no overrides)."""

    def config(self) -> Any:
        """The preset with this section's overrides applied; None for preset ``none``."""
        if self.preset != "none":
            return super().config()
        extra = [k for k in self.model_dump(exclude_unset=True) if k not in self._not_config]
        if extra:
            raise ValueError(
                f"{self._kind} preset 'none' fits no sensor: remove {', '.join(extra)}"
            )
        return None


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
    section_base: type[_PresetSection] = _PresetSection,
) -> type[_PresetSection]:
    """A sensor section whose overrides sit next to ``preset`` (the sensor's config fields)."""
    names = available()
    fields: dict[str, Any] = {"preset": (str, _section_field(kind, names, default))}
    if with_rate:
        fields["rate_hz"] = (
            float, Field(default=50.0, gt=0.0, description=f"{kind} output rate, Hz."),
        )
    base: Any = create_model(
        f"_{name}Base", __base__=section_base, __module__=__name__, **fields
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

    class PitotSection(_PresetSection):
        """Pitot section (typing stand-in)."""

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
    PitotSection = _flat_section(
        PitotConfig, "PitotSection", "pitot", presets.available_pitot_presets,
        presets.pitot_preset, presets.DEFAULT_PITOT_PRESET, with_rate=True,
        doc="Pitot-static airspeed sensor: preset (none = the aircraft has no pitot), output "
        "rate, then overrides (Pa, rad², deg...).",
        section_base=_OptionalSensorSection,
    )


class Sensors(Strict):
    """The sensor suite."""

    imu: ImuSection = ImuSection()
    gnss: GnssSection = GnssSection()
    baro: BaroSection = BaroSection()
    mag: MagSection = MagSection()
    pitot: PitotSection = PitotSection()


# -------------------------------------------------------------------------------- fusion
_FUSION_CHOICES: dict[str, tuple[str, tuple[str, ...]]] = {
    "bridge": ("bridging method", tuple(BRIDGE_METHODS)),
    "altitude": ("altitude method", tuple(ALTITUDE_METHODS)),
    "airspeed": ("airspeed mode", tuple(AIRSPEED_MODES)),
    "align": ("alignment", tuple(ALIGN_MODES)),
}
"""The fusion section's named choices: what the error calls them, and the valid ones."""


class FusionSection(Strict):
    """Fusion settings: outage-bridging and vertical-channel methods."""

    bridge: str = Field(
        default="none", description="GNSS-outage bridging method.",
        json_schema_extra=listing("enum", list(BRIDGE_METHODS)),
    )
    altitude: str = Field(
        default="ekf", description="Vertical-channel method.",
        json_schema_extra=listing("enum", list(ALTITUDE_METHODS)),
    )
    airspeed: str = Field(
        default=DEFAULT_AIRSPEED_MODE,
        description="Air data: on (fused when the stream carries a pitot), off, "
        "synthetic (on, plus synthetic airspeed for a fixed-wing without a pitot).",
        json_schema_extra=listing("enum", list(AIRSPEED_MODES)),
    )
    align: str = Field(
        default=DEFAULT_ALIGN_MODE,
        description="Alignment: auto (static at rest, GNSS track when moving, magnetometer "
        "heading when slow), static, in-flight.",
        json_schema_extra=listing("enum", list(ALIGN_MODES)),
    )

    @field_validator("bridge", "altitude", "airspeed", "align")
    @classmethod
    def _known_choice(cls, value: str, info: ValidationInfo) -> str:
        what, valid = _FUSION_CHOICES[str(info.field_name)]
        if value not in valid:
            raise ValueError(unknown_name(what, value, valid))
        return value


AUTOPILOT_KINDS: tuple[str, ...] = ("none", "px4", "ardupilot")
"""Who flies: hilnav's own guidance (none) or an autopilot in the loop."""


class AutopilotSection(Strict):
    """An autopilot in the loop: who flies, where it connects, where its telemetry
    (its own estimate) arrives, and how long to wait for it. ``autopilot: px4`` is short for
    ``autopilot: {kind: px4}``; ``none`` (the default) flies hilnav's own guidance law."""

    kind: Literal["none", "px4", "ardupilot"] = Field(
        default="none", description="none (hilnav's guidance flies), px4 or ardupilot.")
    link: str | None = Field(
        default=None, min_length=1,
        description="Where the simulator meets the autopilot: PX4 tcpin:HOST:4560 (PX4 SITL "
        "connects) or serial:DEVICE:BAUD (HITL); ArduPilot udpin:HOST:9002 (its JSON "
        "backend). Default: the backend's.")
    telemetry: str | None = Field(
        default="udpin:127.0.0.1:14550", description="MAVLink link on which the autopilot "
        "reports its estimate (GLOBAL_POSITION_INT, ATTITUDE, ...); null: not recorded.")
    telemetry_rate_hz: float = Field(
        default=10.0, gt=0.0, le=250.0,
        description="Rate asked of the autopilot for its estimate messages, Hz.")
    actuator_map: str | None = Field(
        default=None, min_length=1,
        description="PX4: actuator map YAML (channel -> control surface); default: the legacy "
        "HIL order. Relative to this file.")
    servo_map: str | None = Field(
        default=None, min_length=1,
        description="ArduPilot: servo map YAML (servo output -> control surface, PWM range); "
        "default: ArduPlane's outputs. Relative to this file.")
    mavlink: str | None = Field(
        default=None, min_length=1,
        description="ArduPilot: its MAVLink port (e.g. tcp:127.0.0.1:5760) over which the "
        "scenario's GNSS events are set as its simulated-GPS parameters.")
    binary: str | None = Field(
        default=None, min_length=1,
        description="The autopilot's SITL binary (ArduPilot: arduplane; PX4: the px4 of a SITL "
        "build folder): hilnav starts it on free loopback ports, points link, telemetry and "
        "mavlink at it and stops it at the end. Relative to this file; ~ expanded.")
    speed: float | None = Field(
        default=None, gt=0.0, le=100.0,
        description="null: lockstep (SITL); else simulated s per wall s (HITL: 1).")
    connect_timeout_s: float = Field(
        default=120.0, gt=0.0, le=3600.0, description="Wait this long for the autopilot, s.")
    stall_timeout_s: float = Field(
        default=10.0, gt=0.0, le=600.0,
        description="End the run as stalled after this long without controls, s.")

    @model_validator(mode="after")
    def _consistent(self) -> Self:
        for key, only in (("actuator_map", "px4"), ("servo_map", "ardupilot"),
                          ("mavlink", "ardupilot")):
            if getattr(self, key) is not None and self.kind != only:
                raise key_error(f"{key} is a setting of autopilot kind {only!r}, not "
                                f"{self.kind!r}", (key,))
        if self.binary is not None and self.kind == "none":
            raise key_error("binary needs autopilot kind px4 or ardupilot", ("binary",))
        return self

    @property
    def flies(self) -> bool:
        """Whether an autopilot (not hilnav's guidance) is at the controls."""
        return self.kind != "none"


def _autopilot_shorthand(value: Any) -> Any:
    return {"kind": value} if isinstance(value, str) else value


AutopilotSetting = Annotated[
    AutopilotSection,
    BeforeValidator(_autopilot_shorthand,
                    json_schema_input_type=AutopilotSection | Literal["none", "px4", "ardupilot"]),
]
"""The ``autopilot`` key: a section, or just the kind (``autopilot: px4``)."""
