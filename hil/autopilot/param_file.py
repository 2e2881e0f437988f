"""Autopilot parameter files: ArduPilot's ``NAME VALUE`` lines and PX4's QGroundControl format.

Two formats are read, told apart line by line:

* ArduPilot (``.parm`` / ``.param``, as Mission Planner and MAVProxy save them): one parameter
  per line, ``NAME VALUE`` separated by blanks or a comma (``NAME,VALUE``); ``#`` starts a
  comment, blank lines are skipped.
* PX4 / QGroundControl (``.params``): tab- or blank-separated ``SYSID COMPID NAME VALUE TYPE``
  (``1 1 FW_AIRSPD_TRIM 45.0 9``), ``TYPE`` a ``MAV_PARAM_TYPE`` (6 = INT32, 9 = REAL32);
  ``#`` lines are QGroundControl's header and comments.

Names follow MAVLink's ``param_id``: at most 16 characters of letters, digits and ``_``.
Values must be finite numbers. A name given twice is an error (which one wins would be a
guess). Every problem is a :class:`ParamFileError` whose message is one line
``FILE:LINE: what is wrong``.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Final

__all__ = ["PARAM_TYPE_INT32", "PARAM_TYPE_REAL32", "ParamFileError", "ParamValue",
           "read_param_file"]

PARAM_TYPE_INT32: Final = 6
"""MAV_PARAM_TYPE_INT32 (PX4's integer parameters)."""
PARAM_TYPE_REAL32: Final = 9
"""MAV_PARAM_TYPE_REAL32 (ArduPilot sends every value as a float on the wire)."""
_VALID_TYPES: Final = frozenset(range(1, 11))
_NAME: Final = re.compile(r"[A-Za-z][A-Za-z0-9_]{0,15}")


class ParamFileError(ValueError):
    """A parameter file that cannot be read (one line: ``FILE:LINE: reason``)."""


@dataclass(frozen=True)
class ParamValue:
    """One parameter to set: its ``name``, ``value`` and MAVLink ``param_type``
    (:data:`PARAM_TYPE_REAL32` unless the file says otherwise), and where it came from."""

    name: str
    value: float
    param_type: int = PARAM_TYPE_REAL32
    line: int = 0


def read_param_file(path: Path) -> list[ParamValue]:
    """The parameters of ``path`` in file order (see the module docstring).

    Raises
    ------
    ParamFileError
        A file that cannot be read, a line in neither format, a bad name or value, a name
        given twice, a file with no parameter at all.
    """
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        reason = exc.strerror if isinstance(exc, OSError) and exc.strerror else str(exc)
        raise ParamFileError(f"{path}: cannot read the parameter file ({reason})") from None
    out: list[ParamValue] = []
    seen: dict[str, int] = {}
    for number, raw in enumerate(text.splitlines(), start=1):
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        param = _parse_line(line, number, path)
        if param.name in seen:
            raise ParamFileError(f"{path}:{number}: {param.name} is set twice (also on line "
                                 f"{seen[param.name]})")
        seen[param.name] = number
        out.append(param)
    if not out:
        raise ParamFileError(f"{path}:1: no parameter in the file (expected NAME VALUE lines "
                             "or QGroundControl's SYSID COMPID NAME VALUE TYPE lines)")
    return out


def _parse_line(line: str, number: int, path: Path) -> ParamValue:
    fields = line.replace(",", " ").split()
    where = f"{path}:{number}"
    if len(fields) == 2:
        name, value_text, param_type = fields[0], fields[1], PARAM_TYPE_REAL32
    elif len(fields) == 5:
        if not (fields[0].isdigit() and fields[1].isdigit()):
            raise ParamFileError(f"{where}: expected SYSID COMPID NAME VALUE TYPE (numbers "
                                 f"first), got {line!r}")
        name, value_text = fields[2], fields[3]
        if not fields[4].isdigit() or int(fields[4]) not in _VALID_TYPES:
            raise ParamFileError(f"{where}: parameter type {fields[4]!r} of {name} is not a "
                                 "MAV_PARAM_TYPE (1-10; 6 = INT32, 9 = REAL32)")
        param_type = int(fields[4])
    else:
        raise ParamFileError(f"{where}: expected NAME VALUE (ArduPilot) or SYSID COMPID NAME "
                             f"VALUE TYPE (PX4 / QGroundControl), got {line!r}")
    if not _NAME.fullmatch(name):
        raise ParamFileError(f"{where}: {name!r} is not a parameter name (letters, digits "
                             "and _, at most 16 characters)")
    try:
        value = float(value_text)
    except ValueError:
        raise ParamFileError(f"{where}: the value of {name} is not a number: "
                             f"{value_text!r}") from None
    if not math.isfinite(value):
        raise ParamFileError(f"{where}: the value of {name} must be finite, got {value_text}")
    return ParamValue(name, value, param_type, number)
