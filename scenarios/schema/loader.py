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

__all__ = ["LIBRARY_DIR", "MAX_DEPTH", "MAX_FILE_BYTES", "json_schema", "list_library",
           "load_scenario"]

MAX_FILE_BYTES = 1 << 20
"""Largest scenario file read, bytes (the library's largest is ~3 kB)."""
MAX_DEPTH = 32
"""Deepest nesting of mappings and sequences in a scenario file (the schema needs 4)."""


def _check_structure(text: str, path: Path) -> None:
    """Refuse YAML aliases and deep nesting before anything is built from the file.

    An alias (``*name``) lets a few hundred bytes expand into gigabytes when the document is
    built ("billion laughs"), and deep nesting exhausts the recursion of the YAML composer;
    the event stream is read in one linear pass, so neither costs more than the file's size.
    """
    def line(event: yaml.Event) -> int | None:
        return None if event.start_mark is None else event.start_mark.line + 1

    depth = 0
    for event in yaml.parse(text, Loader=yaml.SafeLoader):
        if isinstance(event, yaml.AliasEvent):
            raise ScenarioError(
                f"YAML aliases (*{event.anchor}) are not allowed in scenario files; write the "
                "value out", path=path, line=line(event))
        if isinstance(event, yaml.MappingStartEvent | yaml.SequenceStartEvent):
            depth += 1
            if depth > MAX_DEPTH:
                raise ScenarioError(f"nested deeper than {MAX_DEPTH} levels", path=path,
                                    line=line(event))
        elif isinstance(event, yaml.MappingEndEvent | yaml.SequenceEndEvent):
            depth -= 1


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
    if path.is_dir():
        raise ScenarioError("is a directory, not a scenario file", path=path)
    try:
        size = path.stat().st_size
        if size > MAX_FILE_BYTES:
            raise ScenarioError(f"file too large for a scenario ({size} bytes, the limit is "
                                f"{MAX_FILE_BYTES})", path=path)
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ScenarioError("no such scenario file", path=path) from None
    except (OSError, UnicodeDecodeError) as error:
        raise ScenarioError(f"cannot read the file ({error})", path=path) from None
    try:
        _check_structure(text, path)
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
