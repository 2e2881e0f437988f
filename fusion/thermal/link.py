"""What :class:`fusion.filter.NavFilter` does with the IMU's temperature, per strategy.

Per IMU sample :meth:`ThermalLink.pre` reads ``temperature_k`` (a sample without one has none:
NaN, counted once), screens it (:class:`fusion.thermal.screen.TemperatureScreen`) and, with
``cal``, returns the sample corrected by the calibration polynomial at the last good
temperature. After the INS step :meth:`ThermalLink.bias_step` says how far the bias estimate
moves for the temperature change since the last good reading:

- ``states``: ``k^ dT`` per axis (the temperature-coefficient states' estimate), and the same
  ``dT`` goes to the covariance transition (:attr:`fusion.propagation.CovariancePropagator.
  thermal_dt_k`);
- ``--bridge gmdh-thermal`` (any mode) during a GNSS outage: the learned model's predicted
  change, for the axes its gate lets through, while the temperature is inside its trained
  range (:class:`fusion.thermal.bias_model.ThermalBiasModel`).

A rejected reading moves nothing: the corrections hold where they were (the blind filter).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass
from typing import Any

import numpy as np

from fusion.estimate import HealthCounters
from fusion.nominal import NominalState
from fusion.propagation import CovariancePropagator
from fusion.state_layout import StateLayout
from fusion.thermal.bias_model import ThermalBiasModel
from fusion.thermal.screen import TemperatureScreen
from fusion.thermal.tuning import ThermalTuning

Vec3 = tuple[float, float, float]
_ZERO3: Vec3 = (0.0, 0.0, 0.0)


@dataclass(frozen=True, slots=True)
class ThermalStatus:
    """The thermal strategy at one moment (``fusion/status`` ``thermal``, ``summary.json``
    ``health.thermal``)."""

    mode: str
    """``off``, ``blind``, ``states`` or ``cal``."""
    temperature_k: float
    """The last good die temperature, K (NaN before the first)."""
    temperature_good: bool
    """The latest reading was accepted (false: the corrections hold)."""
    rate_k_per_s: float
    """Die-temperature rate over the last minute, K/s."""
    tempco_accel_mps2_per_k: tuple[float, float, float]
    """``states``: the accelerometer coefficient estimates (zero otherwise)."""
    tempco_gyro_rps_per_k: tuple[float, float, float]
    """``states``: the gyro coefficient estimates (zero otherwise)."""


class CalibratedImu:
    """An IMU sample with the calibration's offsets removed (the attributes of
    :class:`fusion.samples.ImuSample`)."""

    __slots__ = ("angular_rate_b_rps", "dt_s", "specific_force_b_mps2", "temperature_k",
                 "time_us")  # fmt: skip

    def __init__(self, time_us: int, dt_s: float, f: np.ndarray, w: np.ndarray,
                 temperature_k: float) -> None:  # fmt: skip
        self.time_us = time_us
        self.dt_s = dt_s
        self.specific_force_b_mps2 = f
        self.angular_rate_b_rps = w
        self.temperature_k = temperature_k


class ThermalLink:
    """The filter's thermal strategy state (module docstring).

    Parameters
    ----------
    tuning : ThermalTuning
    layout : StateLayout
        The filter's layout (``+therm`` for ``states``).
    counters : HealthCounters
    model : ThermalBiasModel, optional
        The learned bias model of ``--bridge gmdh-thermal``.

    Attributes
    ----------
    tempco_accel, tempco_gyro : list of 3 float
        ``states``: the coefficient estimates, m/s^2/K and rad/s/K.
    rate_k_per_s : float
        Die-temperature rate, least squares over the last ``rate_window_s``, K/s.
    """

    rate_window_s = 60.0

    def __init__(self, tuning: ThermalTuning, layout: StateLayout, counters: HealthCounters,
                 model: ThermalBiasModel | None = None) -> None:  # fmt: skip
        self.tuning = tuning
        self.layout = layout
        self.screen = TemperatureScreen(tuning, counters)
        self.model = model
        self._states = layout.has_thermal
        self._cal = tuning.calibration if tuning.mode == "cal" else None
        self.tempco_accel = [0.0, 0.0, 0.0]
        self.tempco_gyro = [0.0, 0.0, 0.0]
        self._anchor_k = math.nan  # temperature the bias estimate last moved for
        self._pred_anchor: tuple[float, ...] | None = None
        self._cal_g: Vec3 = _ZERO3
        self._cal_a: Vec3 = _ZERO3
        self._hist: deque[tuple[float, float]] = deque()
        self.rate_k_per_s = 0.0
        self._new = False
        self._missing_counted = False

    @property
    def temperature_k(self) -> float:
        """The last good die temperature (NaN before the first), K."""
        return self.screen.temperature_k

    def pre(self, s: Any) -> Any:
        """Screen the sample's temperature; the sample to integrate (calibrated with
        ``cal``)."""
        temp = getattr(s, "temperature_k", math.nan)
        t_us = int(getattr(s, "time_us", 0))
        scr = self.screen
        try:
            temp = float(temp)
        except (TypeError, ValueError):
            temp = math.nan
        if scr.add(t_us, temp):
            self._new = True
            if self.model is not None:
                self.model.has_inputs = True
            self._update_rate(t_us * 1e-6, temp)
            if self._cal is not None:
                self._cal_g, self._cal_a = self._cal.offsets(temp)
        cal = self._cal
        if cal is None or math.isnan(scr.temperature_k):
            return s
        try:
            f = np.asarray(s.specific_force_b_mps2, dtype=float)
            w = np.asarray(s.angular_rate_b_rps, dtype=float)
        except (TypeError, ValueError):
            return s
        if f.shape != (3,) or w.shape != (3,):
            return s
        return CalibratedImu(s.time_us, s.dt_s, f - self._cal_a,
                             w - self._cal_g, temp)  # fmt: skip

    def _update_rate(self, t_s: float, temp_k: float) -> None:
        h = self._hist
        h.append((t_s, temp_k))
        while h and t_s - h[0][0] > self.rate_window_s:
            h.popleft()
        if len(h) < 3:
            return
        ts = np.array([p[0] for p in h])
        ys = np.array([p[1] for p in h])
        tc = ts - ts.mean()
        den = float(tc @ tc)
        self.rate_k_per_s = float(tc @ (ys - ys.mean()) / den) if den > 0 else 0.0

    def start(self) -> None:
        """The filter (re)started from an alignment: the bias estimate refers to now."""
        self._anchor_k = self.screen.temperature_k
        self._pred_anchor = None

    def bias_step(self, gnss_active: bool, time_us: int,
                  bias: tuple[Vec3, Vec3]) -> tuple[Vec3, Vec3, float] | None:  # fmt: skip
        """After an IMU step: ``(d accel bias, d gyro bias, dT)`` to add to the estimate, or
        ``None`` when nothing moves (no new good temperature).

        ``bias``: the filter's current ``(accel, gyro)`` estimate (the learned model's
        training target while GNSS is good).
        """
        if not self._new:
            model = self.model
            # a reading that holds is still the die's temperature: the learner keeps pairing
            # (it stores one pair per its own period), or a coarse part would starve it
            if model is not None and gnss_active and self.screen.good:
                model.add(time_us, self.screen.temperature_k, self.rate_k_per_s,
                          (*bias[0], *bias[1]))  # fmt: skip
            return None
        self._new = False
        temp = self.screen.temperature_k
        anchor = self._anchor_k
        self._anchor_k = temp
        if math.isnan(anchor):
            return None
        d_t = temp - anchor
        da, dg = [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]
        if self._states:
            ka, kg = self.tempco_accel, self.tempco_gyro
            for i in range(3):
                da[i] += ka[i] * d_t
                dg[i] += kg[i] * d_t
        model = self.model
        if model is not None:
            rate = self.rate_k_per_s
            if gnss_active:
                self._pred_anchor = None
                model.active = False
                model.add(time_us, temp, rate, (*bias[0], *bias[1]))
            else:
                model.outage_restart()
                pred = model.predict(temp, rate)
                prev = self._pred_anchor
                model.active = pred is not None and any(v != 0.0 for v in pred)
                if pred is not None:
                    if prev is not None:
                        for i in range(3):
                            da[i] += pred[i] - prev[i]
                            dg[i] += pred[3 + i] - prev[3 + i]
                    self._pred_anchor = pred
                # outside the trained range: hold, and restart from the next prediction
                else:
                    self._pred_anchor = None
        return (da[0], da[1], da[2]), (dg[0], dg[1], dg[2]), d_t

    def status(self) -> ThermalStatus:
        """The strategy's state now."""
        ka, kg = self.tempco_accel, self.tempco_gyro
        return ThermalStatus(self.tuning.mode, self.screen.temperature_k, self.screen.good,
                             self.rate_k_per_s, (ka[0], ka[1], ka[2]),
                             (kg[0], kg[1], kg[2]))  # fmt: skip

    def move_bias(self, nom: NominalState, gnss_active: bool, time_us: int,
                  cov: CovariancePropagator) -> NominalState:  # fmt: skip
        """After an IMU step: ``nom`` with its bias estimate moved by :meth:`bias_step`, the
        temperature change handed to the covariance transition (``cov.thermal_dt_k``)."""
        ba, bg = nom.accel_bias_b_mps2, nom.gyro_bias_b_rps
        step = self.bias_step(gnss_active, time_us, (ba, bg))
        if step is None:
            return nom
        da, dg, d_t = step
        cov.thermal_dt_k += d_t
        if da == _ZERO3 and dg == _ZERO3:
            return nom
        return nom._replace(
            accel_bias_b_mps2=(ba[0] + da[0], ba[1] + da[1], ba[2] + da[2]),
            gyro_bias_b_rps=(bg[0] + dg[0], bg[1] + dg[1], bg[2] + dg[2]))  # fmt: skip

    def correct_tempco(self, d: list[float]) -> None:
        """Feedback of the temperature-coefficient error estimate (``+therm`` layouts)."""
        lay = self.layout
        a, g = lay.KA, lay.KG
        ka, kg = self.tempco_accel, self.tempco_gyro
        for i in range(3):
            ka[i] -= d[a + i]
            kg[i] -= d[g + i]
