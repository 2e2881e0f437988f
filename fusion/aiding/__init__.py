"""Aiding sensors. Each module splits *how* (a pure model returning ``(z, H, R)`` or ``None``)
from *when* (a small control class: start / continue / stop, timeouts, outage detection), as in
PX4 ekf2's ``aid_sources``.

Observation convention (all models): ``z = h(INS) - measurement`` so that ``z = H dx + v`` with
``dx`` the error state of :mod:`fusion.error_model` (estimated minus true).
"""

from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray


class Observation(NamedTuple):
    """One linearised observation of the error state."""

    z: NDArray[np.float64]
    """(m,) INS-predicted minus measured."""
    H: NDArray[np.float64]
    """(m, n) observation matrix."""
    R: NDArray[np.float64]
    """(m, m) measurement noise covariance."""
