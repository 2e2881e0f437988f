"""JUnit XML of a run's pass criteria, for CI systems (one test case per criterion).

The layout is the common JUnit schema that Jenkins, GitLab, GitHub Actions reporters and
pytest's ``--junitxml`` share::

    <testsuites name tests failures errors time>
      <testsuite name tests failures errors skipped time>
        <properties><property name value/>...</properties>
        <testcase classname name time>
          <failure message type>details</failure>      (only when the criterion failed)
        </testcase>
      </testsuite>
    </testsuites>

Only the suite carries a time (the run's wall time): the criteria are evaluated together, so a
per-criterion time would be invented.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from collections.abc import Mapping
from pathlib import Path
from typing import Any

#: Summary fields written as suite properties.
_PROPERTIES = ("scenario", "seed", "bridge", "altitude", "sim_duration_s", "passed")


def _fmt(value: Any) -> str:
    if value is None:
        return "none"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return f"{value:.6g}" if math.isfinite(value) else str(value)
    return str(value)


def failure_message(criterion: Mapping[str, Any]) -> str:
    """One line saying why a criterion failed, e.g. ``"value 41.2 > limit 30"``."""
    value, limit = criterion.get("value"), criterion.get("limit")
    op = criterion.get("op", "<=")
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return f"no value measured (limit {op} {_fmt(limit)})"
    broken = ">" if op == "<=" else "<"
    return f"value {_fmt(value)} {broken} limit {_fmt(limit)}"


def junit_tree(summary: Mapping[str, Any], suite_name: str) -> ET.ElementTree:
    """The JUnit XML tree of ``summary["criteria"]`` (see the module docstring).

    Parameters
    ----------
    summary : mapping
        A ``summary.json`` dict with ``criteria: [{name, limit, value, ok[, op, path]}]``.
    suite_name : str
        Test suite name (also the test cases' ``classname``).
    """
    if not suite_name:
        raise ValueError("suite_name must not be empty")
    criteria = list(summary.get("criteria") or [])
    failures = sum(1 for c in criteria if not c.get("ok"))
    wall = summary.get("wall_s")
    time_s = _fmt(float(wall)) if isinstance(wall, int | float) and math.isfinite(wall) else "0"
    counts = {"tests": str(len(criteria)), "failures": str(failures), "errors": "0"}
    root = ET.Element("testsuites", {"name": suite_name, **counts, "time": time_s})
    suite = ET.SubElement(root, "testsuite",
                          {"name": suite_name, **counts, "skipped": "0", "time": time_s})
    props = ET.SubElement(suite, "properties")
    for key in _PROPERTIES:
        if key in summary:
            ET.SubElement(props, "property", {"name": key, "value": _fmt(summary[key])})
    for c in criteria:
        case = ET.SubElement(suite, "testcase",
                             {"classname": suite_name, "name": str(c.get("name")), "time": "0"})
        if not c.get("ok"):
            msg = failure_message(c)
            fail = ET.SubElement(case, "failure", {"message": msg, "type": "CriterionFailed"})
            detail = [f"criterion: {c.get('name')}", msg]
            if c.get("path"):
                detail.append(f"summary path: {c['path']}")
            fail.text = "\n".join(detail)
    ET.indent(root)
    return ET.ElementTree(root)


def write_junit(summary: Mapping[str, Any], path: Path, suite_name: str = "hilnav") -> None:
    """Write the run's criteria as JUnit XML to ``path`` (UTF-8, with an XML declaration).

    Parameters
    ----------
    summary : mapping
        The ``summary.json`` dict.
    path : Path
    suite_name : str
        e.g. ``"hilnav.<scenario>"``.
    """
    junit_tree(summary, suite_name).write(path, encoding="utf-8", xml_declaration=True)
