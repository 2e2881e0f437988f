"""From a pydantic ValidationError to the one-line ScenarioError ``FILE:LINE: KEY: message``:
the line of a key, the keys allowed where an unknown one stands, the wording."""

from __future__ import annotations

import difflib
import functools
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import yaml
from pydantic import BaseModel, ValidationError

from scenarios.schema.base import clean_msg, unknown_name
from scenarios.schema.events import file_loc
from sim.faults.events import EVENT_TYPES

__all__ = ["KeyLines", "ScenarioError", "allowed_keys", "dotted", "scenario_error", "schema_of"]


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


class KeyLines:
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


def dotted(loc: Sequence[str | int]) -> str:
    """``events[2].at`` for ``("events", 2, "at")``."""
    out = ""
    for part in loc:
        out += f"[{part}]" if isinstance(part, int) else (f".{part}" if out else str(part))
    return out


@functools.lru_cache(maxsize=4)
def schema_of(model: type[BaseModel]) -> dict[str, Any]:
    """The JSON Schema of ``model`` as files write it (aliases), computed once per model."""
    return model.model_json_schema(by_alias=True)


def allowed_keys(schema: dict[str, Any], loc: Sequence[str | int], data: Any) -> list[str]:
    """Keys ``schema`` allows in the mapping at ``loc`` of ``data`` (for 'did you mean')."""
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


# pydantic's bound errors: type -> (operator, context key of the bound).
_BOUNDS = {"greater_than_equal": (">=", "ge"), "greater_than": (">", "gt"),
           "less_than_equal": ("<=", "le"), "less_than": ("<", "lt")}

# Error types whose message already says enough without echoing the input value.
_NO_INPUT_ECHO = frozenset({"scenario", "value_error", "assertion_error", "extra_forbidden",
                            "missing", "union_tag_invalid", "union_tag_not_found"})


def _at_file_key(
    e: Any, loc: tuple[str | int, ...], data: Any, given: Any, msg: str
) -> tuple[tuple[str | int, ...], Any, str]:
    """An error at an SI field of an event moved to the file's key and value: ``(loc,
    value, message)``; other errors unchanged."""
    if len(loc) < 3 or loc[0] != "events" or not isinstance(loc[1], int):
        return loc, given, msg
    events = data.get("events") if isinstance(data, dict) else None
    if not isinstance(events, list) or not 0 <= loc[1] < len(events):
        return loc, given, msg
    event, inner = events[loc[1]], loc[2:]
    if inner[0] not in EVENT_TYPES:  # a check of the timeline, at a field of the event
        tag = event.get("type") if isinstance(event, dict) else None
        tagged, given, key = file_loc(event, (str(tag), *inner))
        inner = tagged[1:]
    elif e["type"] != "scenario":  # the event model's own check, at a field
        inner, given, key = file_loc(event, inner)
    else:  # found while reading the file's event: already at a file key
        return loc, given, msg
    if key is not None and key.quantity and e["type"] in _BOUNDS:
        # "90 s" and "5 min" are both accepted: a bound names its unit
        op, bound = _BOUNDS[e["type"]]
        msg, given = f"must be {op} {e['ctx'][bound]:g} {key.unit} (got {given!r})", None
    return (*loc[:2], *inner), given, msg


def _misspelt_instead_of_missing(errors: Sequence[Any]) -> Any:
    """The error to report: the first one, unless it is a missing key and the same mapping
    holds an unknown key that is a near miss of it (``duraton_s`` for ``duration_s``). Then
    the misspelling is the cause, and naming it tells the user what to fix."""
    first = errors[0]
    if first["type"] != "missing" or not first["loc"]:
        return first
    *parent, wanted = first["loc"]
    for e in errors[1:]:
        *where, key = e["loc"] or ("",)
        if (e["type"] == "extra_forbidden" and where == parent and isinstance(key, str)
                and difflib.get_close_matches(key, [str(wanted)], n=1)):
            return e
    return first


def scenario_error(
    error: ValidationError,
    model: type[BaseModel],
    path: Path | None,
    lines: KeyLines | None,
    data: Any,
    *,
    file_units: bool = False,
) -> ScenarioError:
    """The first validation problem as a one-line ScenarioError (file, line, key, message).

    Parameters
    ----------
    error : what validating ``data`` as ``model`` raised.
    model : the model validated (its JSON Schema lists the keys allowed where an unknown one
        stands).
    path, lines : the file and the line numbers of its keys, if the data came from a file.
    data : the data validated.
    file_units : ``data``'s events are written as in a file: a problem the event model found
        in an SI field is reported at the file's key, with the file's value.
    """
    e = _misspelt_instead_of_missing(error.errors())
    loc: tuple[str | int, ...] = tuple(e["loc"])
    ctx = e.get("ctx") or {}
    msg = clean_msg(e["msg"])
    given = e.get("input")
    other_line = None
    if e["type"] == "scenario":
        loc = loc + tuple(ctx.get("loc", ()))
        msg = ctx.get("message", msg)
        if lines is not None and ctx.get("other"):
            other_line, _ = lines.locate(tuple(ctx["other"]))
    if file_units:
        loc, given, msg = _at_file_key(e, loc, data, given, msg)
    line, kept = lines.locate(loc) if lines is not None else (None, list(loc))
    if e["type"] == "extra_forbidden" and kept:
        allowed = allowed_keys(schema_of(model), kept[:-1], data if isinstance(data, dict) else {})
        key = str(kept[-1])
        msg = unknown_name("key", key, allowed) if allowed else f"unknown key {key!r}"
    elif e["type"] == "missing":
        msg = "required key is missing"
    elif e["type"] == "union_tag_invalid":
        msg = unknown_name("event type", str(ctx.get("tag")), list(EVENT_TYPES))
        kept = [*kept, "type"]
        if lines is not None:
            line, _ = lines.locate(kept)
    elif e["type"] == "union_tag_not_found":
        msg = f"each event needs a 'type': one of {', '.join(EVENT_TYPES)}"
    if other_line is not None:
        msg += f" (see line {other_line})"
    elif e["type"] not in _NO_INPUT_ECHO and isinstance(given, str | int | float):
        msg += f" (got {given!r})"
    return ScenarioError(msg, path=path, line=line, key=dotted(kept))

