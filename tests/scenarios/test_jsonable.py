"""Strict-JSON helpers shared by summary.json, compare.json and the bench scorecards."""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from scenarios.jsonable import json_safe, plain_dict, write_json


def test_json_safe_turns_nan_and_infinity_into_null_everywhere() -> None:
    data = {"a": math.nan, "b": [1.0, math.inf, (np.float64(-np.inf), np.float32(2.5))],
            "c": {"d": np.int64(7), "e": np.bool_(True), "f": "x", "g": None, "h": False}}
    out = json_safe(data)
    assert out == {"a": None, "b": [1.0, None, [None, 2.5]],
                   "c": {"d": 7, "e": True, "f": "x", "g": None, "h": False}}
    assert type(out["c"]["d"]) is int and type(out["c"]["e"]) is bool
    json.dumps(out, allow_nan=False)  # strict JSON: raises on any NaN left


def test_json_safe_leaves_the_input_alone() -> None:
    data = {"a": [math.nan]}
    json_safe(data)
    assert math.isnan(data["a"][0])


def test_write_json_writes_strict_json_with_a_final_newline(tmp_path: Path) -> None:
    path = tmp_path / "x.json"
    write_json({"rmse": np.float64(math.nan), "n": np.int32(3)}, path)
    text = path.read_text()
    assert text.endswith("}\n") and "NaN" not in text
    assert json.loads(text) == {"rmse": None, "n": 3}


@dataclass
class _Inner:
    x: float = 1.0
    pair: tuple[int, int] = (1, 2)


@dataclass
class _Outer:
    name: str = "o"
    inner: _Inner = field(default_factory=_Inner)


def test_plain_dict_flattens_nested_dataclasses_and_copies_dicts() -> None:
    assert plain_dict(_Outer()) == {"name": "o", "inner": {"x": 1.0, "pair": [1, 2]}}
    d = {"k": 1}
    copy = plain_dict(d)
    assert copy == d and copy is not d
    # no counters (None, a plain object, a dataclass *class*) -> nothing to report
    assert plain_dict(None) == {} and plain_dict(object()) == {} and plain_dict(_Outer) == {}
