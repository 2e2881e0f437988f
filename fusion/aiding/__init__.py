"""Aiding sources of :class:`fusion.filter.NavFilter`, one module each, as PX4 ekf2's
``aid_sources``: a pure model (*how*: returns an :class:`Observation` ``(z, H, R)`` or ``None``),
a control class (*when*: start / continue / stop, timeouts, outage detection, resets) and the
fusion step that ties them to the filter's shared update (:class:`Update`: innovation, gate,
Joseph update, feedback, status).

Observation convention (all models): ``z = h(INS) - measurement`` so that ``z = H dx + v`` with
``dx`` the error state of :mod:`fusion.error_model` (estimated minus true).
"""

from typing import NamedTuple, Protocol

import numpy as np
from numpy.typing import NDArray

from fusion.estimate import AidSource
from fusion.kalman import Correction


class Observation(NamedTuple):
    """One linearised observation of the error state."""

    z: NDArray[np.float64]
    """(m,) INS-predicted minus measured."""
    H: NDArray[np.float64]
    """(m, n) observation matrix."""
    R: NDArray[np.float64]
    """(m, m) measurement noise covariance."""


class Update(Protocol):
    """The filter's shared measurement update: the gated Joseph-form update of ``obs`` with
    the chi-square threshold ``gate``; on acceptance the error estimate is fed back at once.
    ``source`` and ``time_us`` (the stepped sample's time) label the recorded
    :class:`~fusion.estimate.Innovation`."""

    def __call__(
        self, obs: Observation, gate: float, source: AidSource, time_us: int
    ) -> Correction: ...
