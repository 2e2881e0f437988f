"""IMU error model: specific force and angular rate in body FRD from datasheet / Allan figures.

Per axis, the output of an IMU sample is::

    y = Q( sat( T·u + b_on + b_gm + b_rrw + n ) )

- ``u``: the true specific force / angular rate averaged over the sample interval (the caller
  averages; see ``sim.sensors.SensorSuite``).
- ``T = I + diag(scale) + M``: scale-factor errors and six small off-diagonal
  misalignment / non-orthogonality angles, drawn once at construction.
- ``b_on``: turn-on bias, drawn once at construction.
- ``b_gm``: bias instability, a first-order Gauss–Markov process (stationary standard
  deviation ``sigma_gm``, correlation time ``tau``), started from its stationary distribution.
- ``b_rrw``: rate random walk, ``b[k+1] = b[k] + K·sqrt(dt)·w``; Allan deviation ``K·sqrt(τ/3)``.
- ``n``: white noise, standard deviation ``N / sqrt(dt)`` per sample (angle / velocity random
  walk ``N``; Allan deviation ``N / sqrt(τ)``; ``dt`` the IMU interval). The datasheet noise
  density in unit/s/√Hz is numerically ``N`` in unit/√s (``N[°/√h] = 60·density[°/s/√Hz]``).
- ``sat``: clip to ± range; ``Q``: round to the output resolution (LSB), if one is given.

Bias instability and the Gauss–Markov sigma
-------------------------------------------
Datasheets quote "in-run bias stability" as the minimum ("floor") of the measured Allan
deviation. A first-order Gauss–Markov process alone has an Allan deviation that peaks at
``0.6174·sigma_gm`` at averaging time ``τ_avg = 1.893·tau`` (computed from the closed-form
Allan variance of the process; the often-quoted 0.664 is the flicker-noise floor constant
``sqrt(2·ln2/π)``, not the Gauss–Markov one). With ``bias_instability_spec="allan_floor"``
(default) hilnav sets ``sigma_gm = B / 0.6174`` so that the Gauss–Markov bump reaches the
datasheet floor ``B`` at ``1.893·tau``; white noise and rate random walk add on top there
(a few per cent for the shipped presets, whose ``tau`` is chosen for that). With
``bias_instability_spec="gm_sigma"`` the number *is* ``sigma_gm`` (the way papers such as P2
state "gyro drift 0.1 °/h first-order Markov, correlation time 100 s").

Random numbers are drawn in blocks of ``BLOCK_STEPS`` samples (18 normals per sample, fixed
layout) and the bias processes are propagated a whole block at a time
(:func:`first_order_filter`: the Gauss–Markov recurrence as ``scipy.signal.lfilter`` computes
it, bit for bit, without importing ``scipy.signal``); the per-sample path only indexes into the
block. The stream for a given generator is therefore the same whether samples are taken one by
one (:meth:`ImuModel.measure`) or in bulk (:meth:`ImuModel.measure_block`); the outputs agree to
floating-point rounding (the per-sample path works on Python floats for speed).

Compiled kernel: :func:`first_order_filter` and the per-sample output (:func:`imu_output`) run
in ``sim/_simkernel.c`` when the package was built with a C compiler (same bits as the Python
references :func:`first_order_filter_python` and :func:`imu_output_python`; see
:mod:`sim.kernel`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from physconst import G0_MPS2
from sim import kernel
from sim._sensor_common import BLOCK_STEPS, NonNegative, Positive, SensorConfigModel

DEG = math.pi / 180.0
GM_ALLAN_PEAK_RATIO = 0.6174
"""Peak Allan deviation of a first-order Gauss–Markov process divided by its sigma."""
GM_ALLAN_PEAK_TAU_RATIO = 1.893
"""Averaging time of that peak divided by the correlation time."""

BiasSpec = Literal["allan_floor", "gm_sigma"]


def first_order_filter_python(
    x: NDArray[np.float64],
    b0: Sequence[float],
    a1: Sequence[float],
    zi: Sequence[float],
    out: NDArray[np.float64],
) -> None:
    """Column ``j`` of ``out`` = ``scipy.signal.lfilter([b0[j]], [1.0, a1[j]], x[:, j],
    zi=[zi[j]])[0]``, bit for bit (Python reference of the compiled kernel).

    scipy's direct form II transposed pads ``b`` with a zero to the length of ``a``, so its one
    delay is ``z = x·0.0 − y·a1`` (not ``−a1·y``: the two differ for an infinite input, and in
    the sign of a zero), and each output is ``y = z + b0·x``. Written out here so that the IMU
    model does not import ``scipy.signal`` (~0.5 s at every start).

    Parameters
    ----------
    x : ndarray, shape (n, k), float64
        Input columns.
    b0, a1, zi : sequences of k floats
        Numerator, denominator ``a[1]`` (``a[0] = 1``) and initial delay of each column.
    out : ndarray, shape (n, k), float64
        Written in place.
    """
    z = [float(v) for v in zi]
    b = [float(v) for v in b0]
    a = [float(v) for v in a1]
    cols = range(len(z))
    rows = x.tolist()
    for row in rows:
        for j in cols:
            xv = row[j]
            y = z[j] + b[j] * xv
            z[j] = xv * 0.0 - y * a[j]
            row[j] = y
    out[...] = np.array(rows, dtype=np.float64).reshape(x.shape)


def imu_output_python(u: Sequence[float], e: Sequence[float], p: Sequence[float]) -> list[float]:
    """One IMU output ``Q(sat(T·u + e))`` in plain floats (Python reference of the kernel).

    Parameters
    ----------
    u : 6 floats
        True ``[fx, fy, fz (m/s²), wx, wy, wz (rad/s)]`` averaged over the interval.
    e : 6 floats
        The sample's error row (biases + white noise), same order and units.
    p : 22 floats
        Accelerometer then gyro transfer matrix row-major (9 + 9), accelerometer and gyro
        range, accelerometer and gyro LSB (0 = no quantisation) (:attr:`ImuModel.output_params`).

    Returns
    -------
    list of 6 float
        Measured values. Quantisation is ``round(y / lsb) * lsb`` (half to even; raises as
        ``round`` does for an infinite or NaN quotient).
    """
    fx, fy, fz, wx, wy, wz = u
    (a00, a01, a02, a10, a11, a12, a20, a21, a22, g00, g01, g02, g10, g11, g12, g20, g21, g22,
     r_acc, r_gyr, q_acc, q_gyr) = p
    e0, e1, e2, e3, e4, e5 = e
    y0 = a00 * fx + a01 * fy + a02 * fz + e0
    y1 = a10 * fx + a11 * fy + a12 * fz + e1
    y2 = a20 * fx + a21 * fy + a22 * fz + e2
    y3 = g00 * wx + g01 * wy + g02 * wz + e3
    y4 = g10 * wx + g11 * wy + g12 * wz + e4
    y5 = g20 * wx + g21 * wy + g22 * wz + e5
    # saturate at the range, then quantise to the LSB (round half to even); written out per
    # axis (a loop over the six costs ~1 us at every sample)
    r = r_acc
    y0 = r if y0 > r else -r if y0 < -r else y0
    y1 = r if y1 > r else -r if y1 < -r else y1
    y2 = r if y2 > r else -r if y2 < -r else y2
    r = r_gyr
    y3 = r if y3 > r else -r if y3 < -r else y3
    y4 = r if y4 > r else -r if y4 < -r else y4
    y5 = r if y5 > r else -r if y5 < -r else y5
    q = q_acc
    if q > 0.0:
        y0, y1, y2 = round(y0 / q) * q, round(y1 / q) * q, round(y2 / q) * q
    q = q_gyr
    if q > 0.0:
        y3, y4, y5 = round(y3 / q) * q, round(y4 / q) * q, round(y5 / q) * q
    return [y0, y1, y2, y3, y4, y5]


_FilterFn = Callable[
    [NDArray[np.float64], Sequence[float], Sequence[float], Sequence[float], NDArray[np.float64]],
    None,
]
_OutputFn = Callable[[Sequence[float], Sequence[float], Sequence[float]], list[float]]

_compiled = kernel.bind_imu(first_order_filter_python, imu_output_python)
#: The Gauss–Markov block filter: :func:`first_order_filter_python`, compiled when
#: :data:`sim.kernel.KERNEL` is ``"c"``.
first_order_filter: _FilterFn = (
    first_order_filter_python if _compiled is None else _compiled.first_order_filter
)
#: One IMU output: :func:`imu_output_python`, compiled when :data:`sim.kernel.KERNEL` is ``"c"``.
imu_output: _OutputFn = imu_output_python if _compiled is None else _compiled.imu_output


class GyroConfig(SensorConfigModel):
    """Gyroscope triad errors in datasheet units (all magnitudes are 1σ unless noted).

    Attributes
    ----------
    range_dps : measurement range ±, °/s (output saturates there).
    angle_random_walk_deg_per_rth : ARW ``N``, °/√h.
    bias_instability_deg_per_h : in-run bias instability, °/h (see ``bias_instability_spec``).
    bias_instability_spec : ``"allan_floor"`` (datasheet Allan minimum) or ``"gm_sigma"``
        (the Gauss–Markov process standard deviation itself).
    bias_correlation_time_s : Gauss–Markov correlation time, s.
    rate_random_walk_deg_per_h_per_rth : RRW ``K``, °/h/√h.
    turn_on_bias_deg_per_h : bias repeatability (drawn once per run), °/h.
    scale_factor_ppm : scale-factor error, ppm.
    misalignment_mrad : axis misalignment / non-orthogonality per off-diagonal term, mrad.
    resolution_dps : output LSB, °/s; 0 = no quantisation.
    """

    range_dps: Positive
    angle_random_walk_deg_per_rth: NonNegative
    bias_instability_deg_per_h: NonNegative
    bias_instability_spec: BiasSpec = "allan_floor"
    bias_correlation_time_s: Positive
    rate_random_walk_deg_per_h_per_rth: NonNegative = 0.0
    turn_on_bias_deg_per_h: NonNegative = 0.0
    scale_factor_ppm: NonNegative = 0.0
    misalignment_mrad: NonNegative = 0.0
    resolution_dps: NonNegative = 0.0


class AccelConfig(SensorConfigModel):
    """Accelerometer triad errors in datasheet units (all magnitudes are 1σ unless noted).

    Attributes
    ----------
    range_g : measurement range ±, g (9.80665 m/s²).
    velocity_random_walk_mps_per_rth : VRW ``N``, m/s/√h (1 µg/√Hz = 5.884e-4 m/s/√h).
    bias_instability_ug : in-run bias instability, µg (see ``bias_instability_spec``).
    bias_instability_spec : ``"allan_floor"`` or ``"gm_sigma"`` (as for the gyro).
    bias_correlation_time_s : Gauss–Markov correlation time, s.
    rate_random_walk_ug_per_rth : acceleration random walk ``K``, µg/√h.
    turn_on_bias_mg : bias repeatability (drawn once per run), mg.
    scale_factor_ppm : scale-factor error, ppm.
    misalignment_mrad : misalignment / non-orthogonality per off-diagonal term, mrad.
    resolution_mg : output LSB, mg; 0 = no quantisation.
    """

    range_g: Positive
    velocity_random_walk_mps_per_rth: NonNegative
    bias_instability_ug: NonNegative
    bias_instability_spec: BiasSpec = "allan_floor"
    bias_correlation_time_s: Positive
    rate_random_walk_ug_per_rth: NonNegative = 0.0
    turn_on_bias_mg: NonNegative = 0.0
    scale_factor_ppm: NonNegative = 0.0
    misalignment_mrad: NonNegative = 0.0
    resolution_mg: NonNegative = 0.0


class ImuConfig(SensorConfigModel):
    """A six-axis IMU: accelerometer and gyroscope triads."""

    accel: AccelConfig
    gyro: GyroConfig


@dataclass(frozen=True)
class ImuParams:
    """An :class:`ImuConfig` in SI, per axis in the order ``[fx, fy, fz, wx, wy, wz]``.

    Units: m/s² for the accelerometer axes, rad/s for the gyro axes, in every array below
    (``white_density`` per √s, ``rate_random_walk`` per √s, ``gm_tau_s`` in s). Shapes (6,).
    """

    white_density: NDArray[np.float64]
    gm_sigma: NDArray[np.float64]
    gm_tau_s: NDArray[np.float64]
    rate_random_walk: NDArray[np.float64]
    turn_on_sigma: NDArray[np.float64]
    scale_sigma: NDArray[np.float64]
    misalignment_sigma_rad: NDArray[np.float64]
    range: NDArray[np.float64]
    resolution: NDArray[np.float64]

    @property
    def allan_floor(self) -> NDArray[np.float64]:
        """Allan-deviation peak of the Gauss–Markov bias alone, (6,), SI."""
        return GM_ALLAN_PEAK_RATIO * self.gm_sigma

    @classmethod
    def from_config(cls, config: ImuConfig) -> ImuParams:
        """Convert the human-unit configuration to SI, once."""
        a, g = config.accel, config.gyro
        ug = 1e-6 * G0_MPS2
        a_gm = a.bias_instability_ug * ug
        g_gm = g.bias_instability_deg_per_h * DEG / 3600.0
        if a.bias_instability_spec == "allan_floor":
            a_gm /= GM_ALLAN_PEAK_RATIO
        if g.bias_instability_spec == "allan_floor":
            g_gm /= GM_ALLAN_PEAK_RATIO

        def pair(acc: float, gyr: float) -> NDArray[np.float64]:
            return np.array([acc, acc, acc, gyr, gyr, gyr], dtype=np.float64)

        return cls(
            white_density=pair(
                a.velocity_random_walk_mps_per_rth / 60.0,
                g.angle_random_walk_deg_per_rth * DEG / 60.0,
            ),
            gm_sigma=pair(a_gm, g_gm),
            gm_tau_s=pair(a.bias_correlation_time_s, g.bias_correlation_time_s),
            rate_random_walk=pair(
                a.rate_random_walk_ug_per_rth * ug / 60.0,
                g.rate_random_walk_deg_per_h_per_rth * DEG / 3600.0 / 60.0,
            ),
            turn_on_sigma=pair(
                a.turn_on_bias_mg * 1e-3 * G0_MPS2, g.turn_on_bias_deg_per_h * DEG / 3600.0
            ),
            scale_sigma=pair(a.scale_factor_ppm * 1e-6, g.scale_factor_ppm * 1e-6),
            misalignment_sigma_rad=pair(a.misalignment_mrad * 1e-3, g.misalignment_mrad * 1e-3),
            range=pair(a.range_g * G0_MPS2, g.range_dps * DEG),
            resolution=pair(a.resolution_mg * 1e-3 * G0_MPS2, g.resolution_dps * DEG),
        )


def model_allan_deviation(
    params: ImuParams, tau_s: NDArray[np.float64], dt_s: float
) -> NDArray[np.float64]:
    """Allan deviation the model should produce, per axis.

    Sum of the Allan variances of white noise (including the quantisation noise
    ``LSB²·dt/12`` of a well-dithered quantiser), the Gauss–Markov bias and the rate random
    walk; valid for ``tau_s ≥ dt_s``.

    Parameters
    ----------
    params : ImuParams
    tau_s : ndarray, shape (m,)
        Averaging times, s.
    dt_s : float
        IMU sample interval, s.

    Returns
    -------
    ndarray, shape (m, 6)
        Allan deviation, SI units of each axis.
    """
    tau = np.asarray(tau_s, dtype=np.float64)[:, None]
    white = params.white_density**2 + params.resolution**2 * dt_s / 12.0
    x = tau / params.gm_tau_s
    # Closed-form Allan variance of a first-order Gauss–Markov process.
    gm = (
        (params.gm_sigma**2)
        * (2.0 / x)
        * (1.0 - (3.0 - 4.0 * np.exp(-x) + np.exp(-2.0 * x)) / (2.0 * x))
    )
    rrw = params.rate_random_walk**2 * tau / 3.0
    return np.asarray(np.sqrt(white / tau + gm + rrw), dtype=np.float64)


class ImuModel:
    """Stateful IMU error model with its own random generator.

    Parameters
    ----------
    config : ImuConfig
        Error figures (converted to SI once, :attr:`params`).
    rng : numpy.random.Generator
        Used only by this model: turn-on draws at construction, then blocks of noise.
    rate_hz : float
        IMU output rate, Hz (sample interval ``dt_s = 1/rate_hz``).

    Attributes
    ----------
    params : ImuParams
    dt_s : float
    turn_on_bias : ndarray (6,)
        The drawn turn-on biases ``[f (m/s²), ω (rad/s)]``.
    transfer : ndarray (6, 6)
        Block-diagonal ``I + scale + misalignment`` matrix applied to the true input.
    """

    def __init__(self, config: ImuConfig, rng: np.random.Generator, rate_hz: float) -> None:
        if not (math.isfinite(rate_hz) and rate_hz > 0.0):
            raise ValueError(f"rate_hz must be a positive finite number (got {rate_hz!r})")
        self.config = config
        self.params = ImuParams.from_config(config)
        self.rate_hz = float(rate_hz)
        self.dt_s = 1.0 / self.rate_hz
        self._rng = rng
        p = self.params

        # One-time draws, fixed order: turn-on bias, scale, misalignment, GM initial state.
        self.turn_on_bias = rng.standard_normal(6) * p.turn_on_sigma
        scale = rng.standard_normal(6) * p.scale_sigma
        # Six independent off-diagonal terms per triad (misalignment + non-orthogonality).
        mis = rng.standard_normal(12) * np.repeat(p.misalignment_sigma_rad, 2)
        transfer = np.eye(6) + np.diag(scale)
        off_diagonal = [(0, 1), (0, 2), (1, 0), (1, 2), (2, 0), (2, 1)]
        for triad in (0, 1):
            for n, (r, c) in enumerate(off_diagonal):
                transfer[3 * triad + r, 3 * triad + c] = mis[6 * triad + n]
        self.transfer = transfer
        self._gm_state = rng.standard_normal(6) * p.gm_sigma
        self._rrw_state = np.zeros(6)

        self._gm_phi = np.exp(-self.dt_s / p.gm_tau_s)
        self._gm_q = p.gm_sigma * np.sqrt(1.0 - self._gm_phi**2)
        self._white_sigma = p.white_density / math.sqrt(self.dt_s)
        self._rrw_step = p.rate_random_walk * math.sqrt(self.dt_s)
        self._lo = -p.range
        self._hi = p.range.copy()
        self._quantise = bool(np.any(p.resolution > 0.0))
        self._q_mask = p.resolution > 0.0
        self._q = np.where(self._q_mask, p.resolution, 1.0)

        # Plain-float copies for the per-sample path (NumPy calls on 6-vectors cost more than
        # the arithmetic here).
        #: What :func:`imu_output` takes after the error row: both transfer blocks row-major,
        #: the two ranges, the two LSBs (22 floats).
        self.output_params: tuple[float, ...] = (
            *(float(v) for v in transfer[0:3, 0:3].ravel()),
            *(float(v) for v in transfer[3:6, 3:6].ravel()),
            float(p.range[0]),
            float(p.range[3]),
            float(p.resolution[0]),
            float(p.resolution[3]),
        )
        self._gm_b0 = self._gm_q.tolist()
        self._gm_a1 = (-self._gm_phi).tolist()  # lfilter's a = [1.0, -phi]

        self._err = np.empty((0, 6))
        self._err_rows: list[list[float]] | None = None
        self._bias = np.empty((0, 6))
        self._idx = 0
        self._initial_bias = self.turn_on_bias + self._gm_state

    # ------------------------------------------------------------------ noise stream
    def _refill(self) -> None:
        z = self._rng.standard_normal((BLOCK_STEPS, 18))
        gm = np.empty((BLOCK_STEPS, 6))
        # x[k] = phi·x[k−1] + q·w[k], continuing from the previous block's last state.
        first_order_filter(
            z[:, 6:12], self._gm_b0, self._gm_a1, (self._gm_phi * self._gm_state).tolist(), gm
        )
        self._gm_state = gm[-1].copy()
        rrw = self._rrw_state + np.cumsum(z[:, 12:18] * self._rrw_step, axis=0)
        self._rrw_state = rrw[-1].copy()
        self._bias = self.turn_on_bias + gm + rrw
        self._err = self._bias + z[:, 0:6] * self._white_sigma
        self._err_rows = None  # converted to lists on first per-sample use (measure_list)
        self._idx = 0

    def _take(self, n: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        errs, biases = [], []
        while n > 0:
            if self._idx >= len(self._err):
                self._refill()
            k = min(n, len(self._err) - self._idx)
            errs.append(self._err[self._idx : self._idx + k])
            biases.append(self._bias[self._idx : self._idx + k])
            self._idx += k
            n -= k
        return np.concatenate(errs), np.concatenate(biases)

    # ------------------------------------------------------------------ outputs
    def measure_list(self, u: list[float], extra_bias: list[float] | None = None) -> list[float]:
        """One IMU sample, plain floats (the suite's hot path).

        Parameters
        ----------
        u : list of 6 float
            True ``[fx, fy, fz (m/s²), wx, wy, wz (rad/s)]`` averaged over the interval.
        extra_bias : list of 6 float, optional
            A bias from outside this model (a thermal one, :mod:`sim.imu_thermal`), same
            order and units, added to the sample's error row before saturation and
            quantisation.

        Returns
        -------
        list of 6 float
            Measured values, same order and units.
        """
        if self._idx >= len(self._err):
            self._refill()
        rows = self._err_rows
        if rows is None:
            rows = self._err_rows = self._err.tolist()
        e = rows[self._idx]
        self._idx += 1
        if extra_bias is not None:
            e = [a + b for a, b in zip(e, extra_bias, strict=True)]
        return imu_output(u, e, self.output_params)

    def measure6(self, u: NDArray[np.float64]) -> NDArray[np.float64]:
        """One IMU sample from the true interval-averaged input.

        Parameters
        ----------
        u : ndarray, shape (6,)
            True ``[f_b (m/s²), ω_ib_b (rad/s)]`` averaged over the sample interval.

        Returns
        -------
        ndarray, shape (6,)
            Measured ``[f_b, ω_ib_b]`` (a new array).
        """
        return np.array(self.measure_list([float(v) for v in u]))

    def measure(
        self, specific_force_b_mps2: NDArray[np.float64], omega_ib_b_rps: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """One sample: true ``f_b`` (3,) m/s² and ``ω_ib_b`` (3,) rad/s -> measured pair."""
        y = self.measure6(np.concatenate((specific_force_b_mps2, omega_ib_b_rps)))
        return y[:3], y[3:]

    def measure_block(
        self, specific_force_b_mps2: NDArray[np.float64], omega_ib_b_rps: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Many consecutive samples at once (same stream as repeated :meth:`measure`).

        Parameters
        ----------
        specific_force_b_mps2 : ndarray, shape (n, 3)
            True interval-averaged specific force, m/s².
        omega_ib_b_rps : ndarray, shape (n, 3)
            True interval-averaged angular rate, rad/s.

        Returns
        -------
        f_b : ndarray, shape (n, 3)
            Measured specific force, m/s².
        omega_b : ndarray, shape (n, 3)
            Measured angular rate, rad/s.
        """
        f = np.asarray(specific_force_b_mps2, dtype=np.float64)
        w = np.asarray(omega_ib_b_rps, dtype=np.float64)
        if f.ndim != 2 or f.shape[1] != 3 or w.shape != f.shape:
            raise ValueError("specific force and angular rate must both have shape (n, 3)")
        u = np.concatenate((f, w), axis=1)
        err, _ = self._take(len(u))
        y = u @ self.transfer.T + err
        np.minimum(np.maximum(y, self._lo, out=y), self._hi, out=y)
        if self._quantise:
            # Same rule as measure_list: round(v / lsb) * lsb (half to even).
            y = np.where(self._q_mask, np.round(y / self._q) * self._q, y)
        return y[:, :3], y[:, 3:]

    def current_bias(self) -> NDArray[np.float64]:
        """True total bias (turn-on + Gauss–Markov + rate random walk) of the last sample.

        Returns
        -------
        ndarray, shape (6,)
            ``[accelerometer bias (m/s²), gyro bias (rad/s)]``; a copy.
        """
        if self._idx > 0:
            return np.array(self._bias[self._idx - 1])
        return np.array(self._initial_bias)
