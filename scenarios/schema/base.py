"""Building blocks of the scenario models: the strict frozen base, validation errors that
point at a key, and "unknown name" messages with a suggestion."""

from __future__ import annotations

import difflib
from collections.abc import Sequence
from typing import Any

from pydantic import BaseModel, ConfigDict, ValidationError
from pydantic_core import PydanticCustomError


class Strict(BaseModel):
    """Frozen, and unknown keys are errors."""

    model_config = ConfigDict(frozen=True, extra="forbid")


def key_error(
    message: str, loc: tuple[str | int, ...] = (), other: tuple[str | int, ...] = ()
) -> PydanticCustomError:
    """A validation error whose ``loc`` (relative to the raising model) rides in its context,
    so :func:`~scenarios.schema.errors.scenario_error` can point at the right key of a
    cross-field check (and, with ``other``, at the line of a second key)."""
    return PydanticCustomError("scenario", "{message}", {"message": message, "loc": loc,
                                                         "other": other})


def listing(keyword: str, values: Sequence[str]) -> Any:
    """``json_schema_extra`` listing the accepted names (enum) or typical ones (examples)."""
    return {keyword: list(values)}


def first_error(error: ValidationError) -> tuple[tuple[str | int, ...], str]:
    """``(loc, message)`` of the first problem of ``error``."""
    e = error.errors()[0]
    return tuple(e["loc"]), clean_msg(e["msg"])


def clean_msg(msg: str) -> str:
    """pydantic's message without its "Value error, " / "Assertion failed, " prefix."""
    return msg.removeprefix("Value error, ").removeprefix("Assertion failed, ")


def unknown_name(kind: str, value: str, valid: Sequence[str]) -> str:
    """``unknown KIND 'VALUE' (did you mean '...'?); valid: ...``."""
    close = difflib.get_close_matches(str(value), list(valid), n=1)
    hint = f" (did you mean {close[0]!r}?)" if close else ""
    return f"unknown {kind} {value!r}{hint}; valid: {', '.join(valid)}"
