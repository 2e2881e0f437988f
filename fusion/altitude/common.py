"""Pieces the altitude modules share: the squared Schuler frequency, exact ZOH discretisation,
argument checks and the frozen configuration base."""

from __future__ import annotations

import math

import numpy as np
import scipy.linalg
from numpy.typing import NDArray
from pydantic import BaseModel, ConfigDict

from physconst import G0_MPS2

FloatArray = NDArray[np.float64]


EARTH_MEAN_RADIUS_M = 6371008.8
"""Mean Earth radius (IUGG), m."""
OMEGA_S2 = G0_MPS2 / EARTH_MEAN_RADIUS_M
"""Squared Schuler frequency ``ωs² = g/R``, 1/s² (1.54e-6; ``ωs`` = 1.24e-3 rad/s)."""


class Frozen(BaseModel):
    """Base of the altitude configuration models: frozen, unknown keys rejected."""

    model_config = ConfigDict(frozen=True, extra="forbid")


def check_finite(name: str, value: float) -> None:
    """ValueError naming ``name`` unless ``value`` is finite."""
    if not math.isfinite(value):
        raise ValueError(f"{name} must be finite (got {value!r})")


def check_dt(dt_s: float) -> None:
    """ValueError unless ``dt_s`` is a finite, positive step."""
    if not (math.isfinite(dt_s) and dt_s > 0.0):
        raise ValueError(f"dt_s must be finite and > 0 (got {dt_s!r})")


def zoh_discretise(a: FloatArray, b: FloatArray, dt_s: float) -> tuple[FloatArray, FloatArray]:
    """Exact zero-order-hold discretisation of ``ẋ = A x + B u``.

    Parameters
    ----------
    a : ndarray, shape (n, n)
    b : ndarray, shape (n, m)
    dt_s : float
        Step, s (> 0).

    Returns
    -------
    phi : ndarray, shape (n, n)
        ``exp(A·dt)``.
    gamma : ndarray, shape (n, m)
        ``∫₀^dt exp(A·τ) dτ · B``.
    """
    check_dt(dt_s)
    n, m = a.shape[0], b.shape[1]
    blk = np.zeros((n + m, n + m))
    blk[:n, :n] = a * dt_s
    blk[:n, n:] = b * dt_s
    e = scipy.linalg.expm(blk)
    return e[:n, :n], e[:n, n:]
