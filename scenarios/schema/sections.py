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
from fusion.choices import DEFAULT_THERMAL_MODE, THERMAL_MODES
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
from sim.imu_thermal import ImuThermalConfig, ImuThermalPart
from sim.mag import MagConfig
from sim.pitot import PitotConfig

__all__ = [
    "AccelOverrides",
    "BaroSection",
    "FusionSection",
    "GnssSection",
    "GyroOverrides",
    "HeaterSection",
    "ImuSection",
    "ImuThermalSection",
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
    ThermalPartOverrides = ImuThermalPart
else:
    StartSection = _overrides(StartState, "StartSection")
    StartSection.__doc__ = (
        "Start state; omitted fields take the aircraft's suggested trim altitude and airspeed "
        "(sim.flight.suggested_start) and sim.flight.StartState's defaults."
    )
    GyroOverrides = _overrides(GyroConfig, "GyroOverrides")
    AccelOverrides = _overrides(AccelConfig, "AccelOverrides")
    ThermalPartOverrides = _overrides(ImuThermalPart, "ThermalPartOverrides")


def _start_shorthand(value: Any) -> Any:
    return {"kind": value} if isinstance(value, str) else value


StartSetting = Annotated[
    StartSection,
    BeforeValidator(_start_shorthand,
                    json_schema_input_type=StartSection | Literal["air", "ground"]),
]
"""The ``start`` key: a section, or just the kind (``start: ground``)."""


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


class HeaterSection(Strict):
    """A heated IMU: the heater holds its case at least at the set point until it fails."""

    setpoint_c: float = Field(
        ge=-40.0, le=85.0, description="Heater set point, °C (PX4's SENS_IMU_TEMP is 55).")
    fails_at_s: float | None = Field(
        default=None, ge=0.0, allow_inf_nan=False,
        description="When the heater stops, s from the start; omitted: it never does.")


class ImuThermalSection(Strict):
    """The IMU's temperature (sim.imu_thermal): a part's thermal preset, the flight's thermal
    state, and overrides of the part's figures. Preset ``off`` (the default) gives the IMU
    no temperature model."""

    preset: str = Field(
        default=presets.IMU_THERMAL_OFF,
        description="Thermal preset of the IMU part (sim.presets): "
        + ", ".join(presets.available_imu_thermal_presets()),
        json_schema_extra=listing("enum", presets.available_imu_thermal_presets()),
    )
    start_temperature_c: float | None = Field(
        default=None, ge=-60.0, le=85.0,
        description="Temperature of the IMU's case at the start, °C (a cold soak); omitted: "
        "in equilibrium with the air (with a heater: at its set point).")
    power_on_s: float = Field(
        default=0.0, le=0.0, ge=-86400.0,
        description="When the IMU was powered on, s from the start (<= 0); 0: it warms up "
        "during the flight.")
    ambient_offset_k: float = Field(
        default=0.0, ge=-30.0, le=60.0,
        description="Air around the IMU minus the outside air, K (a hot day on the ramp, a "
        "warm avionics bay).")
    heater: HeaterSection | None = None
    part: ThermalPartOverrides | None = None

    @field_validator("preset", mode="before")
    @classmethod
    def _yaml_off(cls, value: Any) -> Any:
        # YAML 1.1 reads a bare ``off`` as false
        return presets.IMU_THERMAL_OFF if value is False else value

    @field_validator("preset")
    @classmethod
    def _known_preset(cls, value: str) -> str:
        names = presets.available_imu_thermal_presets()
        if value not in names:
            raise ValueError(unknown_name("IMU thermal preset", value, names))
        return value

    def config(self) -> ImuThermalConfig | None:
        """The thermal model's configuration; None for preset ``off``."""
        part = presets.imu_thermal_preset(self.preset)
        if part is None:
            return None
        if self.part is not None:
            part = part.model_copy(update=self.part.model_dump(exclude_unset=True))
        heater = self.heater
        return ImuThermalConfig(
            part=part,
            preset=self.preset,
            start_temperature_c=self.start_temperature_c,
            power_on_s=self.power_on_s,
            ambient_offset_k=self.ambient_offset_k,
            heater_setpoint_c=None if heater is None else heater.setpoint_c,
            heater_fails_at_s=None if heater is None else heater.fails_at_s,
        )

    @model_validator(mode="after")
    def _consistent(self) -> Self:
        if self.preset == presets.IMU_THERMAL_OFF:
            extra = [k for k in self.model_dump(exclude_unset=True) if k != "preset"]
            if extra:
                raise ValueError(
                    f"IMU thermal preset 'off' has no temperature model: remove "
                    f"{', '.join(extra)}")
            return self
        try:
            self.config()
        except ValidationError as error:
            loc, msg = first_error(error)
            raise key_error(msg, ("part", *loc[1:]) if loc[:1] == ("part",) else loc) from None
        return self


class ImuSection(_PresetSection):
    """IMU: preset, output rate and datasheet-unit overrides of the gyro and accelerometer."""

    _kind = "IMU"
    _names = tuple(presets.available_imu_presets())
    _lookup = staticmethod(presets.imu_preset)
    _not_config = ("preset", "rate_hz", "thermal")

    preset: str = _section_field("IMU", presets.available_imu_presets(), "industrial-mems")
    rate_hz: float | None = Field(
        default=None, gt=0.0, description="IMU output rate, Hz (must divide sim_rate_hz); "
        "omitted: the simulation rate."
    )
    gyro: GyroOverrides | None = None
    accel: AccelOverrides | None = None
    thermal: ImuThermalSection | None = Field(
        default=None, description="The IMU's temperature and thermal errors; omitted: none.")


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
    "thermal": ("thermal strategy", tuple(THERMAL_MODES)),
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

    thermal: str = Field(
        default=DEFAULT_THERMAL_MODE,
        description="IMU thermal strategy: off, blind (bias noise widened for the part's "
        "thermal drift), states (temperature-coefficient states), cal (thermal_cal file).",
        json_schema_extra=listing("enum", list(THERMAL_MODES)),
    )
    thermal_cal: str | None = Field(
        default=None, min_length=1,
        description="IMU thermal calibration file (PX4 TC_G0_*/TC_A0_* or ArduPilot "
        "INS_TCAL1_* parameters), relative to the scenario file; with thermal: cal.",
    )

    @field_validator("bridge", "altitude", "airspeed", "align", "thermal")
    @classmethod
    def _known_choice(cls, value: str, info: ValidationInfo) -> str:
        what, valid = _FUSION_CHOICES[str(info.field_name)]
        if value not in valid:
            raise ValueError(unknown_name(what, value, valid))
        return value


AUTOPILOT_KINDS: tuple[str, ...] = ("none", "px4", "ardupilot")
"""Who flies: hilnav's own guidance (none) or an autopilot in the loop."""

MISSION_ITEM_TYPES: tuple[str, ...] = ("takeoff", "waypoint", "loiter", "rtl")
"""What a mission item of the ``autopilot`` section can be."""
_ITEM_KEYS: dict[str, tuple[set[str], set[str]]] = {  # type: (required, allowed) keys
    "takeoff": ({"alt_m"}, {"alt_m", "lat_deg", "lon_deg", "north_m", "east_m", "pitch_deg"}),
    "waypoint": ({"alt_m"}, {"alt_m", "lat_deg", "lon_deg", "north_m", "east_m"}),
    "loiter": ({"radius_m"}, {"alt_m", "lat_deg", "lon_deg", "north_m", "east_m", "radius_m",
                              "turns", "time_s"}),
    "rtl": (set(), set()),
}


class MissionItemSection(Strict):
    """One item of the autopilot's mission. Positions are ``lat_deg``/``lon_deg`` or
    ``north_m``/``east_m`` from the scenario's start; ``alt_m`` is the height above the
    start's altitude (sent as an altitude above mean sea level)."""

    type: Literal["takeoff", "waypoint", "loiter", "rtl"] = Field(
        description="takeoff (climb out to alt_m), waypoint, loiter (radius_m and turns or "
        "time_s; at the given position, else the previous item's), rtl (return to launch).",
        json_schema_extra=listing("enum", list(MISSION_ITEM_TYPES)))
    lat_deg: float | None = Field(default=None, ge=-90.0, le=90.0, description="Latitude, deg.")
    lon_deg: float | None = Field(default=None, ge=-180.0, le=180.0,
                                  description="Longitude, deg.")
    north_m: float | None = Field(default=None, description="North of the start, m.")
    east_m: float | None = Field(default=None, description="East of the start, m.")
    alt_m: float | None = Field(default=None, ge=-1000.0, le=20000.0,
                                description="Height above the start's altitude, m.")
    radius_m: float | None = Field(default=None, description="Loiter radius, m (> 0 "
                                   "clockwise, < 0 counter-clockwise).")
    turns: float | None = Field(default=None, gt=0.0, le=255.0, description="Loiter turns.")
    time_s: float | None = Field(default=None, gt=0.0, le=86400.0,
                                 description="Loiter time, s.")
    pitch_deg: float = Field(default=15.0, ge=0.0, le=45.0,
                             description="Takeoff: climb pitch, deg.")

    @model_validator(mode="after")
    def _keys_of_type(self) -> Self:
        required, allowed = _ITEM_KEYS[self.type]
        given = {k for k in self.model_fields_set if k != "type"}
        for key in sorted(given - allowed):
            raise key_error(f"{key} is not a key of a {self.type} item (its keys: "
                            f"{', '.join(sorted(allowed)) or 'none'})", (key,))
        for key in sorted(required - given):
            raise key_error(f"a {self.type} item needs {key}", ())
        latlon = {"lat_deg", "lon_deg"} & given
        ne = {"north_m", "east_m"} & given
        if latlon and ne:
            raise key_error("give lat_deg/lon_deg or north_m/east_m, not both",
                            (sorted(ne)[0],))
        for pair in (latlon, ne):
            if len(pair) == 1:
                (key,) = pair
                other = {"lat_deg": "lon_deg", "lon_deg": "lat_deg", "north_m": "east_m",
                         "east_m": "north_m"}[key]
                raise key_error(f"{key} needs {other}", (key,))
        if self.type == "waypoint" and not (latlon or ne):
            raise key_error("a waypoint needs lat_deg/lon_deg or north_m/east_m", ())
        if self.type == "loiter":
            if (self.turns is None) == (self.time_s is None):
                raise key_error("a loiter item takes turns or time_s (one of them)", ())
            if self.radius_m == 0.0:
                raise key_error("radius_m must not be 0", ("radius_m",))
        return self


class ScriptTimeouts(Strict):
    """Simulated seconds each scripted step may take before the run fails."""

    heartbeat_s: float = Field(default=60.0, gt=0.0, le=3600.0,
                               description="Until the autopilot's HEARTBEAT on its link, s.")
    params_s: float = Field(default=60.0, gt=0.0, le=3600.0,
                            description="Until every parameter is echoed back, s.")
    mission_s: float = Field(default=60.0, gt=0.0, le=3600.0,
                             description="Until the mission upload is acknowledged, s.")
    arm_s: float = Field(default=120.0, gt=0.0, le=3600.0,
                         description="Until it reports itself armed (its pre-arm checks "
                         "may need time), s.")
    mode_s: float = Field(default=30.0, gt=0.0, le=3600.0,
                          description="Until its HEARTBEAT reports the mode, s.")


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
    # -- the script: what hilnav tells the autopilot, in this order, over its telemetry link
    params: str | None = Field(
        default=None, min_length=1,
        description="Parameter file pushed with PARAM_SET and read back: ArduPilot NAME VALUE "
        "lines (.parm/.param) or PX4 QGroundControl lines SYSID COMPID NAME VALUE TYPE "
        "(.params). Relative to this file.")
    mission: list[MissionItemSection] | None = Field(
        default=None, min_length=1, max_length=500,
        description="Mission uploaded with the MAVLink mission protocol (takeoff, waypoint, "
        "loiter, rtl items).")
    arm: bool = Field(default=False, description="Arm the autopilot (retried while its "
                      "pre-arm checks fail).")
    mode: str | None = Field(
        default=None, min_length=1,
        description="Flight mode to set after arming, e.g. ArduPlane AUTO, CRUISE, FBWA; PX4 "
        "MISSION, HOLD, RTL.")
    timeouts: ScriptTimeouts = Field(default_factory=lambda: ScriptTimeouts(),
                                     description="Time each scripted step may take.")
    aiding: Literal["none", "hilnav", "disabled"] = Field(
        default="none", description="hilnav: hilnav's estimate is sent to the autopilot as its "
        "navigation source over the telemetry link (ArduPilot GPS_INPUT on GPS2, PX4 ODOMETRY "
        "as external vision), the parameters for it set by the script; disabled: nothing is "
        "sent and the script sets those parameters off (the unaided autopilot).")
    unaided_baseline: bool = Field(
        default=False, description="With aiding: hilnav, first fly the same scenario and seed "
        "with aiding: disabled (into the run folder's unaided/) and score the unaided autopilot "
        "beside the aided one.")

    @model_validator(mode="after")
    def _consistent(self) -> Self:
        for key, only in (("actuator_map", "px4"), ("servo_map", "ardupilot"),
                          ("mavlink", "ardupilot")):
            if getattr(self, key) is not None and self.kind != only:
                raise key_error(f"{key} is a setting of autopilot kind {only!r}, not "
                                f"{self.kind!r}", (key,))
        scripted = [k for k in ("params", "mission", "mode") if getattr(self, k) is not None]
        scripted += ["arm"] if self.arm else []
        scripted += ["aiding"] if self.aiding != "none" else []
        if scripted and self.kind == "none":
            raise key_error(f"{scripted[0]} scripts an autopilot: set kind to px4 or ardupilot",
                            (scripted[0],))
        if scripted and self.telemetry is None:
            raise key_error(f"{scripted[0]} is sent over the autopilot's telemetry link: set "
                            "telemetry", (scripted[0],))
        if self.unaided_baseline and self.aiding != "hilnav":
            raise key_error("unaided_baseline compares the autopilot aided by hilnav with it "
                            f"unaided: set aiding to hilnav (it is {self.aiding!r})",
                            ("unaided_baseline",))
        if self.mode is not None:
            from hil.autopilot.modes import mode_names

            valid = mode_names(self.kind)
            if self.mode.upper() not in valid:
                raise key_error(unknown_name(f"{self.kind} mode", self.mode, valid), ("mode",))
        if self.binary is not None and self.kind == "none":
            raise key_error("binary needs autopilot kind px4 or ardupilot", ("binary",))
        return self

    @property
    def scripted(self) -> bool:
        """Whether hilnav tells the autopilot anything (parameters, mission, arm, mode)."""
        return bool(self.params or self.mission or self.arm or self.mode
                    or self.aiding != "none")

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
