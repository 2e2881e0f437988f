"""Shared helpers of the hil.codec tests: the wire quantisation every round trip is allowed
(float32 and integer fields), and decoding one frame."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from hypothesis import settings
from numpy.typing import ArrayLike

from hil.codec import Decoder, mavlink2

G0 = 9.80665
DEGE7_PER_RAD = 1e7 * 180.0 / math.pi
FAST = settings(max_examples=60, deadline=None)


# --- wire quantisation: the tolerance of every round trip ----------------------------------
def f32_tol(si_value: float, si_per_wire: float, offset: float = 0.0) -> float:
    """Largest SI error of a float32 wire field: half a float32 ulp of the wire value, in SI,
    plus a few float64 ulps for the unit conversion arithmetic."""
    wire = (si_value - offset) / si_per_wire
    half_ulp = float(np.spacing(np.float32(abs(wire)))) / 2.0
    return half_ulp * si_per_wire + 4.0 * float(np.spacing(abs(si_value) + abs(offset)))


def int_tol(si_per_count: float, si_value: float = 0.0) -> float:
    """Largest SI error of an integer wire field: half a count, plus float64 slack."""
    return 0.5 * si_per_count + 4.0 * float(np.spacing(abs(si_value) + 1.0))


def assert_f32_close(
    got: ArrayLike, want: ArrayLike, si_per_wire: float, offset: float = 0.0
) -> None:
    for g, w in zip(np.atleast_1d(got), np.atleast_1d(want), strict=True):
        assert abs(g - w) <= f32_tol(float(w), si_per_wire, offset), (g, w)


def assert_int_close(got: ArrayLike, want: ArrayLike, si_per_count: float) -> None:
    for g, w in zip(np.atleast_1d(got), np.atleast_1d(want), strict=True):
        assert abs(g - w) <= int_tol(si_per_count, float(w)), (g, w)


def angle_diff(a: float, b: float) -> float:
    return (a - b + math.pi) % (2 * math.pi) - math.pi


def one(decoder: Decoder, frame: bytes) -> list[Any]:
    return [d.sample for d in decoder.feed(frame)]


def parse_raw(frame: bytes) -> Any:
    mav = mavlink2.MAVLink(None)
    msgs = mav.parse_buffer(frame)
    assert msgs is not None and len(msgs) == 1
    return msgs[0]
