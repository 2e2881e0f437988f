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

Modules: :mod:`~scenarios.schema.units` (quantities with units), :mod:`~scenarios.schema.base`
(model base, key errors), :mod:`~scenarios.schema.sections` (start, sensors, fusion),
:mod:`~scenarios.schema.criteria`, :mod:`~scenarios.schema.events`,
:mod:`~scenarios.schema.scenario` (the whole file), :mod:`~scenarios.schema.errors`
(one-line errors), :mod:`~scenarios.schema.loader` (reading files, the JSON Schema, the
library).
"""

from fusion.bridging.registry import BRIDGE_METHODS
from fusion.config import ALTITUDE_METHODS
from scenarios.schema.criteria import KNOWN_METRICS, CriterionSpec, metric_unit
from scenarios.schema.errors import ScenarioError
from scenarios.schema.loader import LIBRARY_DIR, json_schema, list_library, load_scenario
from scenarios.schema.scenario import Scenario
from scenarios.schema.units import parse_quantity

__all__ = [
    "ALTITUDE_METHODS",
    "BRIDGE_METHODS",
    "KNOWN_METRICS",
    "LIBRARY_DIR",
    "CriterionSpec",
    "Scenario",
    "ScenarioError",
    "json_schema",
    "list_library",
    "load_scenario",
    "metric_unit",
    "parse_quantity",
]
