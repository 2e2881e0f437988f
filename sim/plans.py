"""Flight plans as data: legs with targets, loaded from YAML.

A plan is a sequence of legs the guidance law in ``sim.guidance`` flies one after the other;
with ``repeat: true`` (the default) it starts again at the first leg when the last one ends,
so any plan keeps the aircraft flying for as long as the caller steps the simulation.

Geometry is relative to the start state, so one plan works at any start position, altitude and
heading:

* ``alt_m`` is the altitude target in metres *above the start altitude* (negative = below).
* The plan frame: with ``frame: start`` (default) the x axis points along the start heading
  and y to its right; ``heading_deg`` is then relative to the start heading. With
  ``frame: ned`` x is north, y is east and headings are true headings.
* Waypoints (``x_m``, ``y_m``) are metres from the start position in the plan frame.

Leg kinds (fields that a kind does not use are rejected):

``heading``
    Hold ``heading_deg`` (ground track / course) for ``duration_s``. ``bank_deg`` caps the bank
    angle (default 30).
``waypoint``
    Fly the straight line from where the leg began to (``x_m``, ``y_m``), following the ground
    track; the leg ends when the target's perpendicular is crossed. ``bank_deg`` caps bank.
``turn``
    Turn by ``turn_deg`` (positive = right / clockwise) at ``bank_deg`` (default 25).
``attitude``
    Hold ``bank_deg`` (default 0) and, if given, ``pitch_deg`` for ``duration_s``: the
    manoeuvre primitive for S-turns and pitch changes. Without ``pitch_deg`` the altitude loop
    stays in charge of pitch.

Every kind also accepts ``alt_m``, ``climb_rate_mps`` (magnitude limit for climbs and
descents) and ``airspeed_mps`` (true airspeed target); a leg that leaves one out keeps the
previous leg's value (initially: start altitude, 2.5 m/s, start airspeed).
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path
from typing import Any, Literal

import yaml
from pydantic import BaseModel, ConfigDict, Field, model_validator

LegKind = Literal["heading", "waypoint", "turn", "attitude"]

# Which optional geometry fields each leg kind accepts / requires. The common targets
# (alt_m, climb_rate_mps, airspeed_mps) are accepted by every kind.
_ALLOWED: dict[str, frozenset[str]] = {
    "heading": frozenset({"heading_deg", "duration_s", "bank_deg"}),
    "waypoint": frozenset({"x_m", "y_m", "bank_deg"}),
    "turn": frozenset({"turn_deg", "bank_deg"}),
    "attitude": frozenset({"bank_deg", "pitch_deg", "duration_s"}),
}
_REQUIRED: dict[str, frozenset[str]] = {
    "heading": frozenset({"heading_deg", "duration_s"}),
    "waypoint": frozenset({"x_m", "y_m"}),
    "turn": frozenset({"turn_deg"}),
    "attitude": frozenset({"duration_s"}),
}
_GEOMETRY = ("heading_deg", "duration_s", "x_m", "y_m", "turn_deg", "bank_deg", "pitch_deg")


class Leg(BaseModel):
    """One leg of a flight plan (see the module docstring for the kinds)."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    kind: LegKind
    heading_deg: float | None = Field(default=None, ge=-360.0, le=360.0)
    duration_s: float | None = Field(default=None, gt=0.0, le=86400.0)
    x_m: float | None = Field(default=None, ge=-1.0e6, le=1.0e6)
    y_m: float | None = Field(default=None, ge=-1.0e6, le=1.0e6)
    turn_deg: float | None = Field(default=None, ge=-1080.0, le=1080.0)
    bank_deg: float | None = Field(default=None, ge=-60.0, le=60.0)
    pitch_deg: float | None = Field(default=None, ge=-20.0, le=25.0)
    alt_m: float | None = Field(default=None, ge=-5000.0, le=10000.0)
    climb_rate_mps: float | None = Field(default=None, gt=0.0, le=30.0)
    airspeed_mps: float | None = Field(default=None, gt=0.0, le=400.0)

    @model_validator(mode="after")
    def _fields_match_kind(self) -> Leg:
        given = {name for name in _GEOMETRY if getattr(self, name) is not None}
        extra = given - _ALLOWED[self.kind]
        if extra:
            raise ValueError(
                f"{self.kind} leg does not take {', '.join(sorted(extra))}; "
                f"it takes {', '.join(sorted(_ALLOWED[self.kind]))}"
            )
        missing = _REQUIRED[self.kind] - given
        if missing:
            raise ValueError(f"{self.kind} leg needs {', '.join(sorted(missing))}")
        if self.kind == "turn" and self.turn_deg == 0.0:
            raise ValueError("turn leg needs a non-zero turn_deg")
        if self.kind in ("heading", "waypoint", "turn") and self.bank_deg is not None:
            if self.bank_deg <= 0.0:
                raise ValueError(f"bank_deg of a {self.kind} leg is a bank limit and must be > 0")
        return self


class FlightPlan(BaseModel):
    """A named sequence of legs; ``repeat`` loops it for as long as the flight runs.

    With ``repeat: false`` the aircraft holds its last course, altitude and speed after the
    final leg.
    """

    model_config = ConfigDict(frozen=True, extra="forbid")

    name: str = Field(min_length=1)
    description: str = ""
    frame: Literal["start", "ned"] = "start"
    legs: tuple[Leg, ...] = Field(min_length=1)
    repeat: bool = True


def _packaged_dir() -> Any:
    return resources.files("sim").joinpath("plans")


def available_plans() -> list[str]:
    """Names of the flight plans packaged with hilnav (``sim/plans/*.yaml``), sorted."""
    return sorted(
        entry.name[: -len(".yaml")]
        for entry in _packaged_dir().iterdir()
        if entry.name.endswith(".yaml")
    )


def _parse_yaml(text: str, source: str) -> Any:
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError as error:
        first = str(error).splitlines()[0] if str(error) else type(error).__name__
        raise ValueError(f"flight plan {source}: not valid YAML ({first})") from None


def plan_from_dict(data: Any, default_name: str = "plan") -> FlightPlan:
    """Validate a mapping (parsed YAML) into a :class:`FlightPlan`.

    ``name`` defaults to ``default_name`` when the mapping has none.
    """
    if not isinstance(data, dict):
        raise ValueError(f"flight plan {default_name!r} must be a YAML mapping with 'legs'")
    return FlightPlan.model_validate({"name": default_name, **data})


def load_plan(name_or_path: str) -> FlightPlan:
    """Load a packaged plan by name or a plan YAML file by path.

    Parameters
    ----------
    name_or_path : a name from :func:`available_plans` or a path to a ``.yaml``/``.yml`` file.

    Raises
    ------
    ValueError
        Unknown name / missing file (the message lists the valid names), or invalid content
        (pydantic's ``ValidationError``, itself a ``ValueError``, names the bad field).
    """
    names = available_plans()
    if name_or_path in names:
        text = _packaged_dir().joinpath(f"{name_or_path}.yaml").read_text(encoding="utf-8")
        return plan_from_dict(_parse_yaml(text, name_or_path), default_name=name_or_path)
    path = Path(name_or_path)
    if path.suffix in (".yaml", ".yml") and path.is_file():
        text = path.read_text(encoding="utf-8")
        return plan_from_dict(_parse_yaml(text, str(path)), default_name=path.stem)
    raise ValueError(
        f"unknown flight plan {name_or_path!r}: valid plans are {', '.join(names)} "
        "(or a path to an existing .yaml file)"
    )
