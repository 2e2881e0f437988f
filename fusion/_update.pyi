"""Compiled Phi fill of the covariance time update (fusion/_update.c), bit for bit
:meth:`fusion.error_model.ErrorModel._fill`; optional (built only where a C compiler was
available)."""

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from fusion.earth import LocalTerms

def bind(local_terms_type: type[LocalTerms], earth_rate: float) -> None: ...
def transition_fill(
    phi: NDArray[np.float64],
    index: NDArray[np.intp],
    terms: LocalTerms,
    dg: tuple[float, float],
    v_ned_mps: Sequence[float],
    c_nb: Sequence[float],
    f_n_mps2: Sequence[float],
    f_b_mps2: Sequence[float],
    omega_ib_b_rps: Sequence[float],
    k: float,
    one: float,
    scale: bool,
    misalignment: bool,
    /,
) -> bool: ...
