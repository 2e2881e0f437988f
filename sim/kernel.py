"""Which implementation of the simulator's compiled kernel runs (``sim/_simkernel.c``).

The kernel is an optional C extension (``setup.py``): ``pip install`` builds it when a C
compiler is there. Each function in it is a Python reference function of a ``sim`` module
(e.g. :func:`sim.imu.imu_output_python`), operation for operation, with the same bits; the
module binds its references here and uses the compiled function when :data:`KERNEL` is ``"c"``.
Inputs the kernel does not take (ints, numpy scalars, other sequences, arrays that are not
float64) go to the bound reference unchanged. The environment variable ``HILNAV_KERNEL=python``
(the variable ``fusion.strapdown`` reads for its own kernel) forces the references.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from types import ModuleType
from typing import Any

from physconst.kernel import python_forced


def _load() -> ModuleType | None:
    try:
        from sim import _simkernel
    except ImportError:  # built without a C compiler: the Python references, same numbers
        return None
    return _simkernel


#: The compiled module whether or not it is used (tests compare it with the references).
compiled = _load()
_forced_python = python_forced(os.environ)
#: ``"c"`` (the compiled kernel runs) or ``"python"`` (no compiler at install time, or
#: ``HILNAV_KERNEL=python``).
KERNEL = "python" if compiled is None or _forced_python else "c"


def bind_imu(
    first_order_filter_ref: Callable[..., Any], imu_output_ref: Callable[..., Any]
) -> ModuleType | None:
    """Hand the IMU model's references to the kernel (its fallback for inputs it does not
    take); the kernel module when it is to be used, else None."""
    if compiled is None:
        return None
    compiled.bind_imu(first_order_filter_ref, imu_output_ref)
    return None if KERNEL == "python" else compiled


def bind_guidance(
    law_ref: Callable[..., Any], controls_type: type, constants: tuple[float, ...]
) -> ModuleType | None:
    """Hand the guidance law's reference, its result type and its constants (g0, pi, 2 pi,
    3 deg in rad) to the kernel; the kernel module when it is to be used, else None."""
    if compiled is None:
        return None
    compiled.bind_guidance(law_ref, controls_type, constants)
    return None if KERNEL == "python" else compiled
