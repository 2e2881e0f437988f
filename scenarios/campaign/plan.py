"""A campaign's plan: --vary grids, grid points applied to scenarios, run ids, the run list."""

from __future__ import annotations

import hashlib
import itertools
import json
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from pydantic import ValidationError

from scenarios.schema import Scenario, ScenarioError, load_scenario

SCHEMA_VERSION = 1

#: Keys accepted by ``--vary``: key -> (where it goes in the scenario file, what it is). The
#: one table that knows the schema's layout; every key is seed-independent. ``bridge`` and
#: ``altitude`` go through :meth:`Scenario.with_overrides`, the others replace the value at
#: their path in the scenario's data, which the schema validates again (so a sensor preset
#: changes under any field overrides the file gives for that sensor, which stay applied).
VARY_KEYS: dict[str, tuple[tuple[str, ...], str]] = {
    "imu": (("sensors", "imu", "preset"), "IMU preset (sim.presets)"),
    "gnss": (("sensors", "gnss", "preset"), "GNSS receiver preset (sim.presets)"),
    "baro": (("sensors", "baro", "preset"), "barometer preset (sim.presets)"),
    "mag": (("sensors", "mag", "preset"), "magnetometer preset (sim.presets)"),
    "pitot": (("sensors", "pitot", "preset"), "pitot (airspeed) preset, none = no pitot"),
    "bridge": (("fusion", "bridge"), "GNSS-outage bridging method"),
    "altitude": (("fusion", "altitude"), "vertical channel method"),
    "airspeed": (("fusion", "airspeed"), "air data: on, off, synthetic"),
    "align": (("fusion", "align"), "alignment: auto, static, in-flight"),
    "aircraft": (("aircraft",), "JSBSim aircraft (hilnav list)"),
    "plan": (("plan",), "flight plan: packaged name or YAML path relative to the scenario"),
}
_WITH_OVERRIDES = ("bridge", "altitude")

#: Seconds into an outage at which the horizontal error is aggregated (summary.json keys).
ERROR_AT_S = ("10", "30", "60", "120")

#: Aggregated metrics, in report order: name -> what one value is (all in metres).
METRICS: dict[str, str] = {
    "outage_horizontal_rmse_m": "horizontal RMSE over each outage",
    "outage_horizontal_max_m": "largest horizontal error in each outage",
    **{f"outage_horizontal_error_m_at_{s}s": f"horizontal error {s} s into each outage"
       for s in ERROR_AT_S},
    "outage_cep95_m": "95 % circular error of each outage",
    "outage_vertical_rmse_m": "vertical RMSE over each outage",
    "gnss_on_horizontal_rmse_m": "horizontal RMSE with GNSS (per run)",
    "gnss_on_vertical_rmse_m": "vertical RMSE with GNSS (per run)",
}

Point = dict[str, str]


# -- planning ----------------------------------------------------------------------------------


def parse_vary(items: Iterable[str]) -> dict[str, list[str]]:
    """Parse ``--vary`` options: ``["imu=a,b", "bridge=none"]`` -> ``{"imu": ["a", "b"], ...}``.

    Parameters
    ----------
    items : ``KEY=VALUE[,VALUE...]`` strings; keys from :data:`VARY_KEYS`.

    Returns
    -------
    dict
        Key -> values, in the order given (the grid's order).

    Raises
    ------
    ValueError
        Not ``KEY=VALUES``, an unknown key (the message lists the valid ones), a key given
        twice, an empty or repeated value.
    """
    grid: dict[str, list[str]] = {}
    for item in items:
        key, sep, rest = item.partition("=")
        key = key.strip()
        if not sep or not key:
            raise ValueError(f"--vary {item!r} must be KEY=VALUE[,VALUE...], e.g. "
                             "imu=consumer-mems,industrial-mems")
        if key not in VARY_KEYS:
            raise ValueError(f"--vary: unknown key {key!r}; valid keys: {', '.join(VARY_KEYS)}")
        if key in grid:
            raise ValueError(f"--vary: key {key!r} given twice; list its values once, "
                             "comma-separated")
        values = [v.strip() for v in rest.split(",")]
        if not rest.strip() or any(not v for v in values):
            raise ValueError(f"--vary {item!r}: empty value")
        if len(set(values)) != len(values):
            raise ValueError(f"--vary {item!r}: a value is listed twice")
        grid[key] = values
    return grid


def grid_points(vary: Mapping[str, Sequence[str]]) -> list[Point]:
    """The cartesian product of ``vary`` (first key varies slowest); ``[{}]`` when empty."""
    keys = list(vary)
    return [dict(zip(keys, combo, strict=True))
            for combo in itertools.product(*(vary[k] for k in keys))]


def apply_point(scenario: Scenario, point: Mapping[str, str]) -> Scenario:
    """``scenario`` with the grid point's values applied and validated again by the schema.

    Raises
    ------
    ValueError
        An unknown key, or a value the schema rejects (:class:`ScenarioError`, one line).
    """
    unknown = sorted(set(point) - set(VARY_KEYS))
    if unknown:
        raise ValueError(f"unknown grid key(s) {', '.join(unknown)}; "
                         f"valid keys: {', '.join(VARY_KEYS)}")
    nested = {k: v for k, v in point.items() if k not in _WITH_OVERRIDES}
    if nested:
        data = scenario.model_dump(by_alias=True, exclude_unset=True)
        data.setdefault("duration_s", scenario.duration_s)
        data.setdefault("name", scenario.name)
        for key, value in nested.items():
            path = VARY_KEYS[key][0]
            node = data
            for part in path[:-1]:
                node[part] = dict(node.get(part) or {})
                node = node[part]
            node[path[-1]] = value
        try:
            scenario = Scenario.model_validate(data, context={"base_dir": scenario.source_dir})
        except ValidationError as error:
            raise ScenarioError(one_line(error)) from None
    if "bridge" in point or "altitude" in point:
        scenario = scenario.with_overrides(bridge=point.get("bridge"),
                                           altitude=point.get("altitude"))
    return scenario


def _sha256_file(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def run_id(scenario_sha256: str, seed: int, point: Mapping[str, str]) -> str:
    """Stable id of one run: hash of the scenario file's bytes, the seed and the grid point."""
    key = json.dumps({"scenario_sha256": scenario_sha256, "seed": int(seed),
                      "point": dict(sorted(point.items()))}, sort_keys=True)
    return hashlib.sha256(key.encode()).hexdigest()[:16]


@dataclass(frozen=True)
class RunSpec:
    """One planned run: what it is (for the reports) and the scenario to fly (for the worker)."""

    id: str
    scenario_path: str
    scenario_name: str
    scenario_sha256: str
    seed: int
    point: Point
    scenario: Scenario = field(repr=False, compare=False)
    #: (scenario index, grid point index): the report order of the run's group
    order: tuple[int, int] = (0, 0)

    def describe(self) -> dict[str, Any]:
        return {"id": self.id, "scenario": self.scenario_name, "scenario_path": self.scenario_path,
                "seed": self.seed, "point": dict(self.point)}


def plan_runs(
    scenarios: Sequence[Path], seeds: Sequence[int], vary: Mapping[str, Sequence[str]]
) -> list[RunSpec]:
    """Load every scenario, apply every grid point and seed; sorted by run id.

    Raises
    ------
    ValueError
        No scenario, no seed, a scenario that does not load, a grid value the schema rejects,
        or the same scenario file content given twice.
    FileNotFoundError
        A scenario file that does not exist.
    """
    if not scenarios:
        raise ValueError("no scenario given")
    if not seeds:
        raise ValueError("need at least one seed")
    points = grid_points(vary)
    runs: dict[str, RunSpec] = {}
    seen: dict[str, Path] = {}
    for i_scn, path in enumerate(scenarios):
        path = Path(path)
        if not path.is_file():
            raise FileNotFoundError(f"scenario file not found: {path}")
        sha = _sha256_file(path)
        if sha in seen:
            raise ValueError(f"{path} has the same content as {seen[sha]}; give it once")
        seen[sha] = path
        base = load_scenario(path)
        if base.autopilot.flies:
            raise ValueError(f"{path}: autopilot: {base.autopilot.kind} needs the autopilot "
                             "connected, run by run; fly it with `hilnav run`, not a campaign")
        for i_pt, point in enumerate(points):
            try:
                varied = apply_point(base, point)
            except ValueError as exc:
                what = ", ".join(f"{k}={v}" for k, v in point.items())
                raise ValueError(f"{path.name} with {what}: {one_line(exc)}") from None
            for seed in seeds:
                rid = run_id(sha, seed, point)
                runs[rid] = RunSpec(rid, str(path), base.name, sha, int(seed), dict(point),
                                    varied.with_overrides(seed=int(seed)), (i_scn, i_pt))
    return [runs[k] for k in sorted(runs)]


def one_line(exc: BaseException) -> str:
    errors = getattr(exc, "errors", None)
    if callable(errors):  # pydantic ValidationError: name the field
        try:
            first = errors()[0]
            loc = ".".join(str(p) for p in first["loc"])
            msg = str(first["msg"]).removeprefix("Value error, ")
            return f"{loc}: {msg}" if loc else msg
        except (IndexError, KeyError, TypeError):
            pass
    text = str(exc).strip().splitlines()
    return text[0] if text else type(exc).__name__
