"""Scenario files: reading and validating them, their JSON Schema, the shipped library."""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

import yaml
from pydantic import ValidationError

from scenarios.schema.errors import KeyLines, ScenarioError, scenario_error, schema_of
from scenarios.schema.events import FILE_UNITS
from scenarios.schema.scenario import Scenario

LIBRARY_DIR = Path(__file__).resolve().parent.parent / "library"
"""The scenario library shipped with hilnav."""

__all__ = ["LIBRARY_DIR", "json_schema", "list_library", "load_scenario"]


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
        scenario = Scenario.model_validate(
            data, context={"base_dir": path.parent, FILE_UNITS: True}
        )
    except ValidationError as error:
        raise scenario_error(error, Scenario, path, KeyLines(root), data,
                             file_units=True) from None
    return scenario


def json_schema() -> dict[str, Any]:
    """JSON Schema (Draft 2020-12) of scenario files, for editor completion and CI checks.

    Returns
    -------
    dict : a fresh copy (``hilnav schema`` prints it as JSON).
    """
    schema = copy.deepcopy(schema_of(Scenario))
    schema["$schema"] = "https://json-schema.org/draft/2020-12/schema"
    return schema


def list_library() -> list[Path]:
    """The scenario files shipped in ``scenarios/library``, sorted by name."""
    return sorted(LIBRARY_DIR.glob("*.yaml"))
