"""The scenario model: aircraft, start, plan, duration, sensors, fusion, criteria and the fault
timeline, checked for consistency, with builders of the simulator's SI objects."""

from __future__ import annotations

import datetime as dt
import re
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, Literal, Self

from pydantic import (
    BeforeValidator,
    ConfigDict,
    Discriminator,
    Field,
    PrivateAttr,
    Tag,
    ValidationError,
    ValidationInfo,
    field_validator,
    model_validator,
)
from pydantic_core import PydanticCustomError

from physconst.geomag import DEFAULT_DECIMAL_YEAR, decimal_year
from scenarios.schema.base import Strict, first_error, key_error, listing, unknown_name
from scenarios.schema.criteria import CriterionSpec
from scenarios.schema.errors import scenario_error
from scenarios.schema.events import Event
from scenarios.schema.sections import (
    AutopilotSection,
    AutopilotSetting,
    FusionSection,
    Sensors,
    StartSection,
    StartSetting,
)
from scenarios.summary import Criterion
from sim import presets
from sim.faults.events import FaultEvent, GnssJamming, GnssOutage, GnssRate
from sim.faults.timeline import Conflict, OutsideFlight, timeline_problems
from sim.flight import FlightConfig, StartState, available_aircraft, suggested_start
from sim.imu import ImuConfig
from sim.plans import FlightPlan, available_plans, load_plan
from sim.sensors import SensorSuiteConfig

if TYPE_CHECKING:
    from hil.autopilot.commander import Script

__all__ = ["InlinePlan", "Scenario"]

# Turbulence names -> severity of sim.flight's MIL-F-8785C mapping (see sim/flight.py).
_TURBULENCE: dict[str, float] = {"none": 0.0, "light": 0.43, "moderate": 0.57, "severe": 0.86}


def _turbulence(value: Any) -> Any:
    if isinstance(value, str):
        if value not in _TURBULENCE:
            raise ValueError(unknown_name("turbulence level", value, list(_TURBULENCE)))
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


class Scenario(Strict):
    """One scenario (see :mod:`scenarios.schema`; ``hilnav schema`` prints the JSON Schema).

    Build the simulation objects with :meth:`flight_config`, :meth:`flight_plan`,
    :meth:`sensor_config`, :meth:`fault_events` and :meth:`criteria`.

    ``events`` are the :mod:`sim.faults` event models. :func:`~scenarios.schema.load_scenario`
    reads them as files write them (``at``, ``offset_hpa``...); ``Scenario.model_validate``
    without that context takes their SI fields, as ``model_dump`` gives them.
    """

    model_config = ConfigDict(frozen=True, extra="forbid", populate_by_name=True,
                              title="hilnav scenario")

    name: str = Field(default="", description="Scenario name; default: the file name.")
    description: str = ""
    aircraft: str = Field(
        default="c172x", description="JSBSim aircraft (hilnav list).",
        json_schema_extra=listing("enum", available_aircraft()),
    )
    start: StartSetting = Field(
        default_factory=lambda: StartSection(),
        description="Where the flight starts: in the air, trimmed (the default), or on the "
        "ground at rest on a runway (kind: ground, or just start: ground; needs an autopilot).")
    plan: PlanRef = Field(
        default="racetrack",
        description="A packaged plan name, a plan YAML path relative to this file, or an "
        "inline plan (description, frame, legs, repeat).",
        json_schema_extra=listing("examples", available_plans()),
    )
    duration_s: float = Field(gt=0.0, le=86400.0, description="Simulated flight time, s.")
    seed: int = Field(default=1, ge=0, le=2**31 - 1, description="Seed of every random stream.")
    date: dt.date | None = Field(
        default=None,
        description="Date of the simulated world, e.g. 2026-06-15: the Earth's magnetic field "
        "(World Magnetic Model) of the simulated magnetometer and of the filter's reference is "
        "evaluated at it; default 2026-01-01.")
    sim_rate_hz: float = Field(default=200.0, ge=50.0, le=400.0,
                               description="Flight dynamics (JSBSim) rate, Hz.")
    wind_ned_mps: tuple[float, float, float] = Field(
        default=(0.0, 0.0, 0.0), description="Steady wind the air moves *towards*, NED m/s."
    )
    wind_shear_exponent: float = Field(
        default=0.0, ge=0.0, le=1.0,
        description="Power-law shear of the horizontal wind: w(h) = wind_ned_mps "
        "(h_agl / wind_ref_agl_m)^p; 1/7 = neutral boundary layer; 0 = no shear.",
    )
    wind_ref_agl_m: float | None = Field(
        default=None, gt=0.0, le=20000.0,
        description="Height above ground where wind_ned_mps holds, m; default: start altitude.",
    )
    wind_table: tuple[tuple[float, float, float], ...] = Field(
        default=(),
        description="Horizontal wind profile [alt_msl_m, north_mps, east_mps] rows, altitude "
        "increasing, linear in between, constant beyond; replaces wind_ned_mps' north/east.",
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
    autopilot: AutopilotSetting = Field(
        default_factory=lambda: AutopilotSection(),
        description="Who flies: none (hilnav's guidance law, the default), px4 or ardupilot "
        "(an autopilot in the loop, at its actuators), with its link settings.")

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
            raise ValueError(unknown_name("aircraft", value, valid))
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
            raise key_error(_message(error), ("start",)) from None
        self._check_ground_start()
        try:
            self.flight_config()
        except (ValueError, ValidationError) as error:
            where = "wind_table" if self.wind_table else "wind_ned_mps"
            raise key_error(_message(error), (where,)) from None
        self._check_rates()
        self._check_heater()
        problem = _timeline_problem(self)
        if problem is not None:
            raise problem
        self._check_criteria()
        if self.autopilot.scripted:
            try:
                self.autopilot_script()
            except ValueError as error:  # the parameter file: FILE:LINE: reason
                raise key_error(str(error), ("autopilot", "params")) from None
        return self

    # -- validation helpers ------------------------------------------------------------
    def _check_ground_start(self) -> None:
        if self.start.kind != "ground":
            return
        if self.start.airspeed_mps is not None:
            raise key_error("a ground start is at rest: remove airspeed_mps",
                            ("start", "airspeed_mps"))
        if not self.autopilot.flies:
            raise key_error(
                "a ground start needs an autopilot to take off (autopilot: px4 or ardupilot); "
                "hilnav's guidance law flies from an in-air start", ("start",))

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
            loc, msg = first_error(error)
            where = ".".join(str(p) for p in loc)
            raise key_error(f"flight plan {path}: {where}: {msg}", ("plan",)) from None
        except ValueError as error:
            raise key_error(str(error), ("plan",)) from None

    def _check_rates(self) -> None:
        sim = self.sim_rate_hz
        imu = self.sensors.imu.rate_hz
        if imu is not None:
            ratio = sim / imu
            if round(ratio) < 1 or abs(ratio - round(ratio)) > 1e-9 * ratio:
                raise key_error(
                    f"IMU rate {imu:g} Hz must divide sim_rate_hz ({sim:g} Hz)",
                    ("sensors", "imu", "rate_hz"),
                )
        for key, rate in (
            ("gnss", self.sensors.gnss.config().rate_hz),
            ("baro", self.sensors.baro.rate_hz),
            ("mag", self.sensors.mag.rate_hz),
            ("pitot", self.sensors.pitot.rate_hz),
        ):
            if rate > sim * (1.0 + 1e-12):
                raise key_error(
                    f"{key} rate {rate:g} Hz exceeds sim_rate_hz ({sim:g} Hz)",
                    ("sensors", key, "rate_hz"),
                )

    def _check_heater(self) -> None:
        thermal = self.sensors.imu.thermal
        heater = None if thermal is None else thermal.heater
        if heater is not None and heater.fails_at_s is not None and (
                heater.fails_at_s >= self.duration_s):
            raise key_error(
                f"the heater fails at {heater.fails_at_s:g} s, at or after the end of the "
                f"flight (duration_s {self.duration_s:g})",
                ("sensors", "imu", "thermal", "heater", "fails_at_s"),
            )

    def _check_criteria(self) -> None:
        spans = [
            (e.duration_s if e.duration_s is not None else self.duration_s - e.start_s)
            for e in self.events if isinstance(e, GnssOutage | GnssJamming)
        ]
        for i, c in enumerate(self.pass_criteria):
            if c.metric.startswith("events.") and not self.events:
                raise key_error(
                    f"metric {c.metric!r} scores the scenario's events, and it has none",
                    ("criteria", i, "metric"),
                )
            if not c.metric.startswith("outages."):
                continue
            if not spans:
                raise key_error(
                    f"metric {c.metric!r} is measured during GNSS outages, and this scenario "
                    "has no gnss_outage or gnss_jamming event",
                    ("criteria", i, "metric"),
                )
            m = re.fullmatch(r"outages\.(?:horizontal|vertical)_error_m_at\.(\d+)", c.metric)
            if m and max(spans) < float(m.group(1)):
                raise key_error(
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

    def setup_record(self) -> dict[str, Any]:
        """What is flown, in words a scorecard shows: aircraft, plan, sensor presets (``+
        overrides`` where the file changes a preset), wind and turbulence."""
        def preset(section: Any) -> str:
            extra = section.model_dump(exclude_defaults=True, exclude={"preset", "thermal"})
            return str(section.preset) + (" + overrides" if extra else "")

        plan = self.plan if isinstance(self.plan, str) else "inline plan"
        thermal = self.sensors.imu.thermal
        extra: dict[str, Any] = {}
        if thermal is not None and thermal.preset != presets.IMU_THERMAL_OFF:
            state = thermal.model_dump(exclude_unset=True, exclude={"preset"})
            extra["imu_thermal"] = " ".join(
                [thermal.preset, *(f"{k}={v}" for k, v in state.items())])
        return {
            "description": self.description,
            "aircraft": self.aircraft,
            "plan": plan,
            "sensors": {name: preset(getattr(self.sensors, name))
                        for name in ("imu", "gnss", "baro", "mag", "pitot")},
            "wind_ned_mps": list(self.wind_ned_mps),
            "wind_shear_exponent": self.wind_shear_exponent,
            "turbulence": self.turbulence,
            **extra,
        }

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
            wind_shear_exponent=self.wind_shear_exponent,
            wind_ref_agl_m=self.wind_ref_agl_m,
            wind_table=self.wind_table,
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
            pitot=s.pitot.config(),
            imu_rate_hz=s.imu.rate_hz,
            baro_rate_hz=s.baro.rate_hz,
            mag_rate_hz=s.mag.rate_hz,
            pitot_rate_hz=s.pitot.rate_hz,
            decimal_year=self.decimal_year,
            imu_thermal=None if s.imu.thermal is None else s.imu.thermal.config(),
        )

    @property
    def decimal_year(self) -> float:
        """The scenario's date as a decimal year (:data:`physconst.geomag.DEFAULT_DECIMAL_YEAR`
        without one)."""
        return DEFAULT_DECIMAL_YEAR if self.date is None else decimal_year(self.date)

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

    def fault_events(self) -> tuple[FaultEvent, ...]:
        """The timeline as ``sim.faults`` events, SI units, in file order."""
        return self.events

    def autopilot_path(self, path: str | None) -> Path | None:
        """A file named in the ``autopilot`` section, relative to this scenario's folder."""
        if path is None:
            return None
        p = Path(path).expanduser()
        return p if p.is_absolute() or self._base_dir is None else self._base_dir / p

    def autopilot_script(self) -> Script:
        """What the ``autopilot`` section tells the autopilot (its parameter file read, its
        mission at absolute positions). ValueError: a parameter file that cannot be read."""
        from scenarios.schema.autopilot_script import build_script

        start = self.start_state()
        return build_script(self.autopilot, (start.lat_deg, start.lon_deg, start.alt_msl_m),
                            self.autopilot_path(self.autopilot.params),
                            heading_deg=start.heading_deg)

    def criteria(self) -> tuple[Criterion, ...]:
        """Pass criteria for :func:`scenarios.summary.build_summary`."""
        return tuple(c.criterion() for c in self.pass_criteria)

    def outage_windows(self) -> tuple[tuple[float, float], ...]:
        """``(start_s, end_s)`` of every gnss_outage and gnss_jamming event, clipped to the
        flight, in file order (the spans the summary's ``outages`` are meant to score)."""
        return tuple(
            (e.start_s,
             min(self.duration_s, e.start_s + e.duration_s) if e.duration_s else self.duration_s)
            for e in self.events if isinstance(e, GnssOutage | GnssJamming)
        )

    def with_overrides(
        self,
        *,
        seed: int | None = None,
        bridge: str | None = None,
        altitude: str | None = None,
        duration_s: float | None = None,
        airspeed: str | None = None,
        align: str | None = None,
        thermal: str | None = None,
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
        if any(v is not None for v in (bridge, altitude, airspeed, align, thermal)):
            fusion = dict(data.get("fusion", {}))
            if bridge is not None:
                fusion["bridge"] = bridge
            if altitude is not None:
                fusion["altitude"] = altitude
            if airspeed is not None:
                fusion["airspeed"] = airspeed
            if align is not None:
                fusion["align"] = align
            if thermal is not None:
                fusion["thermal"] = thermal
            data["fusion"] = fusion
        try:
            return Scenario.model_validate(data, context={"base_dir": self._base_dir})
        except ValidationError as error:
            raise scenario_error(error, Scenario, None, None, data) from None


def _message(error: Exception) -> str:
    if isinstance(error, ValidationError):
        loc, msg = first_error(error)
        return f"{'.'.join(str(p) for p in loc)}: {msg}" if loc else msg
    return str(error)


def _timeline_problem(s: Scenario) -> PydanticCustomError | None:
    """The first of: an event outside the flight or above the receiver's rate (in file order),
    two events that contradict each other (the pair whose later event comes first)."""
    names = [e.type_name for e in s.events]
    problems = timeline_problems(s.events, s.duration_s)
    outside = {p.index: p for p in problems if isinstance(p, OutsideFlight)}
    for i, e in enumerate(s.events):
        p = outside.get(i)
        if p is not None and p.field == "start_s":
            return key_error(
                f"{names[i]} starts at {p.time_s:g} s, at or after the end of the flight "
                f"(duration_s {p.flight_s:g})", ("events", i, "start_s"),
            )
        if p is not None:
            return key_error(
                f"{names[i]} ends at {p.time_s:g} s, after the end of the flight (duration_s "
                f"{p.flight_s:g}); shorten it or leave duration out to last until the end",
                ("events", i, "duration_s"),
            )
        if isinstance(e, GnssRate):
            receiver = s.sensors.gnss.config().rate_hz
            if e.rate_hz > receiver:
                return key_error(
                    f"gnss_rate {e.rate_hz:g} Hz is above the receiver's {receiver:g} Hz",
                    ("events", i, "rate_hz"),
                )
    conflicts = sorted((p for p in problems if isinstance(p, Conflict)),
                       key=lambda p: (p.second, p.first))
    if conflicts:
        c = conflicts[0]
        return key_error(c.describe(lambda k: f"events[{k}] ({names[k]})"),
                         ("events", c.second), ("events", c.first))
    return None
