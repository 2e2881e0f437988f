"""Units of scenario files: quantities with an optional unit ("5 min", "25 m", "2 m/s") and the
human units of sensor faults (hPa, deg/h, mg...), converted once, on load."""

from __future__ import annotations

import math
import re
from collections.abc import Callable
from typing import Any

from physconst import G0_MPS2

__all__ = ["TIME_PATTERN", "parse_quantity", "si_unit", "to_si"]

# unit -> (dimension, factor to the dimension's base). Bases are the units of summary.json:
# m, s, m/s and *degrees* (the summary reports angles in degrees).
_UNITS: dict[str, tuple[str, float]] = {
    "m": ("length", 1.0),
    "km": ("length", 1000.0),
    "cm": ("length", 0.01),
    "ft": ("length", 0.3048),
    "nmi": ("length", 1852.0),
    "s": ("time", 1.0),
    "ms": ("time", 1e-3),
    "min": ("time", 60.0),
    "h": ("time", 3600.0),
    "deg": ("angle", 1.0),
    "°": ("angle", 1.0),
    "rad": ("angle", 180.0 / math.pi),
    "mrad": ("angle", 0.18 / math.pi),
    "arcmin": ("angle", 1.0 / 60.0),
    "m/s": ("speed", 1.0),
    "km/h": ("speed", 1.0 / 3.6),
    "kn": ("speed", 1852.0 / 3600.0),
    "ft/min": ("speed", 0.3048 / 60.0),
}
_QUANTITY = re.compile(
    r"^\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*([A-Za-z°/]+(?:/[A-Za-z]+)?)?\s*$"
)


def parse_quantity(value: Any, unit: str | None) -> float:
    """A number with an optional unit, converted to ``unit``.

    Parameters
    ----------
    value : a number (already in ``unit``) or a string such as ``"5 min"``, ``"25 m"``,
        ``"0.5 deg"``, ``"2 m/s"`` (a string without a unit is in ``unit``).
    unit : the target unit (a key of the unit table: m, s, deg, m/s...), or None for a
        dimensionless quantity (then only plain numbers are accepted).

    Returns
    -------
    float : the value in ``unit``.

    Raises
    ------
    ValueError
        Not a number, an unknown unit, or a unit of the wrong dimension; the message names
        the accepted units.
    """
    if isinstance(value, bool):
        raise ValueError(f"expected a number, got {value!r}")
    if isinstance(value, int | float):
        number, given = float(value), None
    elif isinstance(value, str):
        m = _QUANTITY.match(value)
        if m is None:
            raise ValueError(f"cannot read {value!r} as a number with a unit, e.g. '25 m'")
        number, given = float(m.group(1)), m.group(2)
    else:
        raise ValueError(f"expected a number or a string with a unit, got {value!r}")
    if not math.isfinite(number):
        raise ValueError(f"{value!r} is not finite")
    if given is None:
        return number
    if given not in _UNITS:
        raise ValueError(f"unknown unit {given!r} in {value!r}; known units: {', '.join(_UNITS)}")
    if unit is None:
        raise ValueError(f"{value!r}: this value has no unit, give a plain number")
    dim, factor = _UNITS[given]
    want_dim, want_factor = _UNITS[unit]
    if dim != want_dim:
        same = ", ".join(u for u, (d, _) in _UNITS.items() if d == want_dim)
        article = "an" if dim[0] in "aeiou" else "a"
        raise ValueError(f"{value!r} is {article} {dim}, expected a {want_dim} ({same})")
    return number * factor / want_factor


TIME_PATTERN = r"^\s*[+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?\s*(s|ms|min|h)?\s*$"
"""JSON Schema pattern of a time >= 0 written as a string ("90 s", "5 min", "1.5 h")."""


# File unit -> (SI unit, conversion). Each conversion is written as the scenario format has
# always computed it: the operation order decides the last bit of the result.
_TO_SI: dict[str, tuple[str, Callable[[float], float]]] = {
    "Pa": ("Pa", lambda x: x),
    "hPa": ("Pa", lambda x: 100.0 * x),
    "Pa/s": ("Pa/s", lambda x: x),
    "hPa/h": ("Pa/s", lambda x: x * 100.0 / 3600.0),
    "hPa/10min": ("Pa/s", lambda x: x * 100.0 / 600.0),
    "deg/h": ("rad/s", lambda x: x * math.pi / 180.0 / 3600.0),
    "deg/s": ("rad/s", lambda x: x * math.pi / 180.0),
    "mg": ("m/s^2", lambda x: x * 1e-3 * G0_MPS2),
    "g": ("m/s^2", lambda x: x * G0_MPS2),
    "uT": ("T", lambda x: x * 1e-6),
}


def si_unit(unit: str) -> str:
    """The SI unit a file unit converts to (``"hPa/h"`` -> ``"Pa/s"``).

    Raises
    ------
    KeyError
        Not a unit of :func:`to_si`.
    """
    return _TO_SI[unit][0]


def to_si(value: float, unit: str) -> float:
    """A value written in a file unit (hPa, hPa/h, hPa/10min, deg/h, deg/s, mg, g, uT, and
    the SI units Pa, Pa/s themselves), in SI (Pa, Pa/s, rad/s, m/s², T).

    Parameters
    ----------
    value : the number, in ``unit``.
    unit : the file unit.

    Returns
    -------
    float : the value in :func:`si_unit` of ``unit``.
    """
    return _TO_SI[unit][1](value)
