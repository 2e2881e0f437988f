"""Barometric height aiding with a baro-bias state.

The height of a pressure is its ISA pressure altitude (:func:`physconst.isa.pressure_altitude_m`,
paper P4's ``Hp = (T0/L)((Ps/P0)^(-L R / g) - 1) + H0`` in the troposphere); P4's
non-standard-atmosphere corrections (scale ``s`` and offset ``b``) belong to the altitude
channel. Here the whole difference between pressure height and the navigation height (weather,
non-standard temperature, geoid) is one slowly varying Gauss-Markov bias ``b`` (state BARO)::

    h_baro = h + b + n        ->   z = (h^ + b^) - h_baro,  H = [.. -1 (pos D) .. +1 (BARO) ..]

*When* — :class:`BaroControl`: samples averaged over ``1 / fuse_rate_hz``, the bias initialised
from the first batch (``b^ = h_baro - h^``, exactly correlated with the height error: the bias
error is ``-dh + n``), a timeout reported, the bias re-initialised after a long run of gate
rejections.

*Fusion step* — :class:`BaroAiding`: a pressure through the range check, a batch through the
bias initialisation or the height update, counted.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from fusion import kalman
from fusion.aiding import Observation, Update
from fusion.altitude.atmosphere import P_MAX_PA, P_MIN_PA
from fusion.config import BaroTuning
from fusion.estimate import AidSource, HealthCounters
from fusion.samples import BaroSample
from fusion.state_layout import StateLayout


def height_model(
    layout: StateLayout, ins_alt_m: float, baro_bias_m: float, baro_height_m: float, noise_m: float,
    baro_scale: float = 0.0, reference_alt_m: float = 0.0,
) -> Observation | None:  # fmt: skip
    """Baro height observation ``z = (h^ + b^ + s^ (h^ - h_ref)) - h_baro``.

    The scale term is there only in layouts with the baro scale-factor state
    (``h_baro = h + b + s (h - h_ref)``, ``h_ref`` the height at which the bias was set), with
    ``H = [.. -(1 + s^) (pos D) .. 1 (BARO) .. h^ - h_ref (BS) ..]``.

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
    baro_scale : float
        Current baro scale-factor estimate (layouts with the state).
    reference_alt_m : float
        ``h_ref``, m (layouts with the state).

    Returns
    -------
    Observation or None
        ``None`` for non-finite input.
    """
    if not (math.isfinite(baro_height_m) and math.isfinite(ins_alt_m)) or not noise_m > 0.0:
        return None
    H = np.zeros((1, layout.n))
    H[0, layout.BARO] = 1.0
    if layout.has_baro_scale:
        dh = ins_alt_m - reference_alt_m
        z = np.array([ins_alt_m + baro_bias_m + baro_scale * dh - baro_height_m])
        H[0, layout.POS + 2] = -(1.0 + baro_scale)  # dh = -dr_D
        H[0, layout.BS] = dh
    else:
        z = np.array([ins_alt_m + baro_bias_m - baro_height_m])
        H[0, layout.POS + 2] = -1.0  # dh = -dr_D
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


class BaroAiding:
    """Barometric aiding of :class:`fusion.filter.NavFilter`: range check, control, bias
    initialisation and the height update.

    Parameters
    ----------
    cfg : BaroTuning
    layout : StateLayout
    counters : HealthCounters
        Where samples are counted (``baro_*``).
    update : Update
        The filter's shared measurement update.
    init_bias : callable ``(bias_m, reference_alt_m) -> None``
        Sets the filter's baro-bias estimate (and its covariance row) from a sample taken at
        the INS height ``reference_alt_m`` (the scale factor's reference from then on).
    """

    def __init__(
        self, cfg: BaroTuning, layout: StateLayout, counters: HealthCounters, update: Update,
        init_bias: Callable[[float, float], None],
    ) -> None:  # fmt: skip
        self.cfg = cfg
        self.layout = layout
        self.control = BaroControl(cfg)
        self.gate = kalman.chi2_gate(1, cfg.gate_probability)
        self._c = counters
        self._update = update
        self._init_bias = init_bias

    def pressure(self, s: BaroSample) -> float | None:
        """The sample's static pressure, Pa, or ``None`` (counted as invalid) when it is not
        finite, ``<= 0`` or outside the atmosphere model (-5 km .. 47 km pressure altitude)."""
        try:
            p = float(s.pressure_pa)
        except (TypeError, ValueError):
            p = math.nan
        if not P_MIN_PA <= p <= P_MAX_PA:  # also NaN and p <= 0
            self._c.baro_invalid += 1
            return None
        return p

    def fuse(
        self, batch: tuple[int, float, int], ins_alt_m: float, baro_bias_m: float, step_us: int,
        baro_scale: float = 0.0, reference_alt_m: float = 0.0,
    ) -> None:  # fmt: skip
        """One averaged batch (:meth:`BaroControl.add_sample`): initialise the bias from it, or
        fuse its height and re-initialise the bias after a long run of rejections.

        Parameters
        ----------
        batch : (int, float, int)
            Mean time (us), mean ISA pressure height (m) and sample count.
        ins_alt_m : float
            INS height at the batch's mean time, m.
        baro_bias_m : float
            Current baro-bias estimate, m.
        step_us : int
            Time of the stepped sample (labels the update).
        baro_scale, reference_alt_m : float
            Baro scale-factor estimate and its reference height (layouts with the state).
        """
        ctl, c = self.control, self._c
        t_mean, h_mean, count = batch
        if ctl.need_bias_init(t_mean):
            self._init_bias(h_mean - ins_alt_m, ins_alt_m)
            ctl.on_bias_init()
            return
        obs = height_model(
            self.layout, ins_alt_m, baro_bias_m, h_mean, self.cfg.noise_m / math.sqrt(count),
            baro_scale, reference_alt_m,
        )
        if obs is None:
            c.baro_invalid += 1
            return
        res = self._update(obs, self.gate, AidSource.BARO_HGT, step_us)
        ok = res.test_ratio <= 1.0
        if ok:
            c.baro_fused += 1
        else:
            c.baro_rejected += 1
        if ctl.on_result(t_mean, ok):
            self._init_bias(h_mean - ins_alt_m, ins_alt_m)
            ctl.on_bias_init()
            c.baro_resets += 1
