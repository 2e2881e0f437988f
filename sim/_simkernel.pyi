"""Compiled simulator kernel (sim/_simkernel.c), bit for bit the Python references in
:mod:`sim.imu`; optional (built only where a C compiler was available)."""

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

def bind_imu(
    first_order_filter_ref: Callable[..., object], imu_output_ref: Callable[..., object]
) -> None: ...
def first_order_filter(
    x: NDArray[np.float64],
    b0: Sequence[float],
    a1: Sequence[float],
    zi: Sequence[float],
    out: NDArray[np.float64],
) -> None: ...
def imu_output(u: Sequence[float], e: Sequence[float], p: Sequence[float]) -> list[float]: ...
def bind_guidance(
    law_ref: Callable[..., object], controls_type: type, constants: tuple[float, ...]
) -> None: ...
def law(
    s: tuple[float, ...],
    course_err: float | None,
    phi_fixed: float,
    limit: float,
    pitch_direct: bool,
    theta_fixed: float,
    alt_target_m: float,
    airspeed_target_mps: float,
    climb_rate_mps: float,
    integrators: list[float],
    params: tuple[float, ...],
) -> Any: ...
