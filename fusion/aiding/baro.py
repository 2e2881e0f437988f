"""Barometric height aiding with a baro-bias state.

Pressure to height, ICAO standard atmosphere (ISA), troposphere and lower stratosphere::

    h = T0 / L * (1 - (p / p0)^(R L / g0))            p >= p11 (h <= 11 km)
    h = h11 + R T11 / g0 * ln(p11 / p)               p <  p11 (isothermal layer)

with T0 = 288.15 K, L = 0.0065 K/m (temperature decreasing upwards), p0 = 101 325 Pa,
R = 287.05287 J/(kg K), g0 = 9.80665 m/s^2, T11 = 216.65 K, p11 = 22 632.06 Pa. This is paper
P4's ``Hp = (T0/L)((Ps/P0)^(-L R / g) - 1) + H0`` written with a positive lapse rate; P4's
non-standard-atmosphere corrections (scale ``s`` and offset ``b``) belong to the later altitude
channel. Here the whole difference between pressure height and the navigation height (weather,
non-standard temperature, geoid) is one slowly varying Gauss-Markov bias ``b`` (state BARO)::

    h_baro = h + b + n        ->   z = (h^ + b^) - h_baro,  H = [.. -1 (pos D) .. +1 (BARO) ..]

*When* — :class:`BaroControl`: initialise the bias from the first sample (``b^ = h_baro - h^``,
exactly correlated with the height error: the bias error is ``-dh + n``), report a timeout,
re-initialise after a long run of gate rejections.
"""

from __future__ import annotations

import math

import numpy as np

from fusion.aiding import Observation
from fusion.config import BaroTuning
from fusion.error_model import StateLayout
from physconst import G0_MPS2, ISA_L0_KPM, ISA_LAYER_BASE_M, ISA_P0_PA, ISA_R_AIR_JPKGK, ISA_T0_K

ISA_LAPSE_K_PER_M = -ISA_L0_KPM  # temperature decrease with height, K/m (> 0)
ISA_R_J_PER_KG_K = ISA_R_AIR_JPKGK
ISA_G0_MPS2 = G0_MPS2
ISA_H11_M = ISA_LAYER_BASE_M[1]
ISA_T11_K = ISA_T0_K - ISA_LAPSE_K_PER_M * ISA_H11_M
_EXP = ISA_R_J_PER_KG_K * ISA_LAPSE_K_PER_M / ISA_G0_MPS2
ISA_P11_PA = ISA_P0_PA * (ISA_T11_K / ISA_T0_K) ** (1.0 / _EXP)


def pressure_to_height(pressure_pa: float) -> float:
    """ISA pressure altitude, m, for a static pressure in Pa (NaN for non-positive input)."""
    if not pressure_pa > 0.0:
        return math.nan
    if pressure_pa >= ISA_P11_PA:
        return ISA_T0_K / ISA_LAPSE_K_PER_M * (1.0 - (pressure_pa / ISA_P0_PA) ** _EXP)
    return ISA_H11_M + ISA_R_J_PER_KG_K * ISA_T11_K / ISA_G0_MPS2 * math.log(
        ISA_P11_PA / pressure_pa
    )


def height_to_pressure(height_m: float) -> float:
    """Inverse of :func:`pressure_to_height`: ISA static pressure (Pa) at a pressure altitude."""
    if height_m <= ISA_H11_M:
        return ISA_P0_PA * (1.0 - ISA_LAPSE_K_PER_M * height_m / ISA_T0_K) ** (1.0 / _EXP)
    return ISA_P11_PA * math.exp(
        -(height_m - ISA_H11_M) * ISA_G0_MPS2 / (ISA_R_J_PER_KG_K * ISA_T11_K)
    )


def height_model(
    layout: StateLayout, ins_alt_m: float, baro_bias_m: float, baro_height_m: float, noise_m: float
) -> Observation | None:
    """Baro height observation ``z = (h^ + b^) - h_baro``.

    Parameters
    ----------
    layout : StateLayout
    ins_alt_m : float
        INS height at the sample time, m.
    baro_bias_m : float
        Current baro-bias estimate, m.
    baro_height_m : float
        ISA pressure height of the sample, m.
    noise_m : float
        1-sigma, m.

    Returns
    -------
    Observation or None
        ``None`` for non-finite input.
    """
    if not (math.isfinite(baro_height_m) and math.isfinite(ins_alt_m)) or not noise_m > 0.0:
        return None
    z = np.array([ins_alt_m + baro_bias_m - baro_height_m])
    H = np.zeros((1, layout.n))
    H[0, layout.POS + 2] = -1.0  # dh = -dr_D
    H[0, layout.BARO] = 1.0
    return Observation(z, H, np.array([[noise_m * noise_m]]))


class BaroControl:
    """When to fuse baro height and when to (re)initialise its bias.

    Parameters
    ----------
    cfg : BaroTuning
    """

    def __init__(self, cfg: BaroTuning) -> None:
        self.cfg = cfg
        self._timeout_us = round(cfg.timeout_s * 1e6)
        self._reset_us = round(cfg.reset_after_rejected_s * 1e6)
        self.last_sample_us: int | None = None
        self.bias_initialised = False
        self._period_us = round(1e6 / cfg.fuse_rate_hz)
        self._sum_t = 0
        self._sum_h = 0.0
        self._count = 0
        self._batch_end_us: int | None = None
        self._rejected_since_us: int | None = None

    def add_sample(self, time_us: int, height_m: float) -> tuple[int, float, int] | None:
        """Accumulate one pressure height; once ``1 / fuse_rate_hz`` has passed since the last
        batch returns ``(mean time_us, mean height_m, count)`` to fuse, else ``None``. The very
        first sample is a batch of its own (it initialises the bias)."""
        self._sum_t += time_us
        self._sum_h += height_m
        self._count += 1
        self.last_sample_us = time_us
        if self._batch_end_us is not None and time_us - self._batch_end_us < self._period_us - 1:
            return None
        out = (self._sum_t // self._count, self._sum_h / self._count, self._count)
        self._sum_t = 0
        self._sum_h = 0.0
        self._count = 0
        self._batch_end_us = time_us
        return out

    def is_active(self, now_us: int) -> bool:
        """A baro sample arrived within ``timeout_s``."""
        return self.last_sample_us is not None and now_us - self.last_sample_us <= self._timeout_us

    def need_bias_init(self, time_us: int) -> bool:
        """True when the bias must be set from this sample instead of fusing it.

        After a pause longer than the timeout the bias is *kept* (it is a slowly varying state
        whose covariance grew meanwhile); only a long run of rejections re-initialises it.
        """
        return not self.bias_initialised

    def on_bias_init(self) -> None:
        """The filter set the bias from a sample."""
        self.bias_initialised = True
        self._rejected_since_us = None

    def on_result(self, time_us: int, accepted: bool) -> bool:
        """Record the gate's verdict; True when the bias should be re-initialised."""
        if accepted:
            self._rejected_since_us = None
            return False
        if self._rejected_since_us is None:
            self._rejected_since_us = time_us
        return time_us - self._rejected_since_us >= self._reset_us
