"""Turn run results into strict JSON: one place for the NaN scrubbing and dataclass flattening
that ``summary.json``, ``compare.json`` and the bench scorecards all need."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np


def json_safe(obj: Any) -> Any:
    """A copy of ``obj`` that :func:`json.dumps` writes as strict JSON.

    JSON has no NaN or infinity: they become ``null``. NumPy scalars become Python ones;
    tuples become lists. Anything else is returned as it is.

    Parameters
    ----------
    obj : Any
        Nested dicts, lists and tuples of numbers, strings, bools and ``None``.

    Returns
    -------
    Any
        The same structure with only JSON-safe leaves.
    """
    if isinstance(obj, dict):
        return {k: json_safe(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [json_safe(v) for v in obj]
    if isinstance(obj, float | np.floating):
        f = float(obj)
        return f if math.isfinite(f) else None
    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, np.bool_):
        return bool(obj)
    return obj


def write_json(obj: Any, path: Path) -> None:
    """Write ``obj`` as indented strict JSON (:func:`json_safe`) with a final newline."""
    path.write_text(json.dumps(json_safe(obj), indent=2) + "\n")


def plain_dict(obj: object) -> dict[str, Any]:
    """The fields of a dataclass instance (or a copy of a dict) as a dict.

    Nested dataclasses become dicts and tuples lists, so the result can go into a summary;
    anything that is neither a dict nor a dataclass gives ``{}`` (a counter object that a
    component does not have is simply left out).
    """
    if isinstance(obj, dict):
        return dict(obj)
    fields = getattr(obj, "__dataclass_fields__", None)
    if fields is not None and not isinstance(obj, type):
        return {k: _plain(getattr(obj, k)) for k in fields}
    return {}


def _plain(v: Any) -> Any:
    if hasattr(v, "__dataclass_fields__") and not isinstance(v, type):
        return plain_dict(v)
    if isinstance(v, tuple | list):
        return [_plain(x) for x in v]
    return v
