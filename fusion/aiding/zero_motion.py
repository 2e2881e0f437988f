"""Zero-velocity (ZUPT) and zero-angular-rate (ZARU) updates while the vehicle is at rest: what
keeps a parked vehicle from drifting when GNSS is gone, and the fine alignment at rest.

*When* — :class:`StillnessDetector`. The IMU output of a vehicle at rest is gravity, the Earth
rate and sensor noise. Over blocks of ``window_s`` the detector takes, per axis, the standard
deviation of the specific force and of the angular rate, and the magnitude of the mean rate.
The block is *still* when

- every specific-force standard deviation is below ``max(accel_floor, k * N_a * sqrt(f / 2))``
  (``N_a`` the accelerometer noise density, ``f`` the IMU rate, so ``N_a sqrt(f/2)`` is the
  per-sample white-noise sigma of a sensor band-limited at Nyquist, ``k`` = ``noise_factor``),
- every angular-rate standard deviation is below the same bound with ``N_g``, and the mean rate
  is below ``max_rate_rps`` (far above the Earth rate and a MEMS bias, far below any
  manoeuvre),
- and the INS speed is below ``max_speed_mps``. The IMU alone cannot tell rest from
  unaccelerated straight flight (both read ``-g`` and zero rate); the speed gate, checked on
  every sample before anything is accumulated, makes a cruising aircraft never even
  accumulate a block (and keeps the hot path at one comparison).

*How* — :func:`zero_velocity_model`: ``z = v^_n - 0`` with ``H`` the identity on the velocity
error, ``R = sigma^2 I``; ``sigma`` (``velocity_sigma_mps``) covers the sway of a vehicle
standing in wind. The update is fused at ``fuse_rate_hz`` while blocks stay still, through the
filter's gated update (a vehicle that starts moving fails the gate before the detector's next
block says so).

*Zero angular rate* — :func:`zero_rate_model`: at the end of every still block its mean
measured rate minus the gyro bias estimate is compared with the Earth rate in body axes; the
difference is the gyro bias error (``H = -I``), with the block's own standard error as sigma
(floored by ``rate_sigma_floor_rps``). This is the fine alignment's gyro calibration: at rest
nothing else observes the vertical gyro's bias, which otherwise turns straight into heading
drift.

The thresholds are documented in :class:`fusion.config.ZeroMotionTuning`.
"""

from __future__ import annotations

import math

import numpy as np

from fusion import earth, kalman
from fusion.aiding import Observation, Update
from fusion.config import ImuTuning, ZeroMotionTuning
from fusion.estimate import AidSource, HealthCounters
from fusion.rotations import quat_to_dcm
from fusion.state_layout import StateLayout
from fusion.strapdown import InsState


def zero_velocity_model(layout: StateLayout, ins: InsState, sigma_mps: float) -> Observation:
    """Zero-velocity observation of the error state.

    Parameters
    ----------
    layout : StateLayout
    ins : InsState
    sigma_mps : float
        1-sigma per axis of the true velocity of a vehicle at rest, m/s.

    Returns
    -------
    Observation
    """
    z = np.array(ins.v_ned_mps, dtype=float)
    H = np.zeros((3, layout.n))
    v = layout.VEL
    for i in range(3):
        H[i, v + i] = 1.0
    R = np.eye(3) * (sigma_mps * sigma_mps)
    return Observation(z, H, R)


def zero_rate_model(
    layout: StateLayout, ins: InsState, rate_b_rps: tuple[float, float, float],
    gyro_bias_b_rps: tuple[float, float, float], sigma_rps: float,
) -> Observation:  # fmt: skip
    """Zero-angular-rate observation of the gyro bias error: at rest the gyros measure the
    Earth rate and their bias.

    Parameters
    ----------
    layout : StateLayout
    ins : InsState
        Gives the latitude and the attitude that carries the Earth rate into body axes.
    rate_b_rps : 3 floats
        Mean measured (uncompensated) angular rate over a still block, body, rad/s.
    gyro_bias_b_rps : 3 floats
        The filter's gyro bias estimate, rad/s.
    sigma_rps : float
        1-sigma per axis of that mean, rad/s.

    Returns
    -------
    Observation
        ``z = (rate - b^_g) - C_bn omega_ie^n = b_g - b^_g = -dbg`` (scale factor and
        misalignment times the Earth rate are below 1e-8 rad/s and neglected), so ``H = -I``
        on the gyro bias error.
    """
    w_ie_b = quat_to_dcm(ins.q_nb).T @ earth.earth_rate_n(ins.lat_rad)
    z = np.array([rate_b_rps[i] - gyro_bias_b_rps[i] - float(w_ie_b[i]) for i in range(3)])
    H = np.zeros((3, layout.n))
    g = layout.BG
    for i in range(3):
        H[i, g + i] = -1.0
    return Observation(z, H, np.eye(3) * (sigma_rps * sigma_rps))


class StillnessDetector:
    """Block-wise rest detection from the IMU and the INS speed (module docstring).

    Parameters
    ----------
    cfg : ZeroMotionTuning
    imu : ImuTuning
        Its noise densities set the per-sample noise bounds.
    """

    def __init__(self, cfg: ZeroMotionTuning, imu: ImuTuning) -> None:
        self._window_s = cfg.window_s
        self._max_speed2 = cfg.max_speed_mps**2
        self._max_rate = cfg.max_rate_rps
        self._k = cfg.noise_factor
        self._accel_floor = cfg.accel_std_floor_mps2
        self._gyro_floor = cfg.gyro_std_floor_rps
        self._na = imu.accel_noise_density_mps2_rthz
        self._ng = imu.gyro_noise_density_rps_rthz
        self.still = False
        """Verdict of the last complete block."""
        self.blocks = 0
        """Complete blocks judged so far."""
        self.block_rate_b_rps = (0.0, 0.0, 0.0)
        """Mean angular rate of the last complete block (as sampled, body), rad/s."""
        self.block_rate_sem_rps = 0.0
        """Standard error of that mean (the largest axis's sample sigma / sqrt(n)), rad/s."""
        self._clear()

    def _clear(self) -> None:
        self._n = 0
        self._dt = 0.0
        self._s = [0.0] * 6
        self._s2 = [0.0] * 6

    def add(self, fw: tuple[float, ...], dt: float, v_ned_mps: tuple[float, float, float]) -> bool:
        """Add one IMU sample (``fw``: specific force m/s^2 then rate rad/s, body); returns
        whether the vehicle is at rest (the last complete block's verdict)."""
        vn, ve, vd = v_ned_mps
        if vn * vn + ve * ve + vd * vd > self._max_speed2:
            if self._n or self.still:
                self._clear()
                self.still = False
            return False
        s, s2 = self._s, self._s2
        for i in range(6):
            x = fw[i]
            s[i] += x
            s2[i] += x * x
        self._n += 1
        self._dt += dt
        if self._dt >= self._window_s:
            self.still = self._judge()
            self._clear()
        return self.still

    def _judge(self) -> bool:
        n = self._n
        self.blocks += 1
        if n < 3:
            return False
        rate_hz = n / self._dt
        half = math.sqrt(rate_hz / 2.0)
        a_max = max(self._accel_floor, self._k * self._na * half)
        g_max = max(self._gyro_floor, self._k * self._ng * half)
        s, s2 = self._s, self._s2
        mean_rate2 = 0.0
        still = True
        worst_rate_var = 0.0
        for i in range(6):
            mean = s[i] / n
            var = max(s2[i] / n - mean * mean, 0.0)
            if math.sqrt(var) > (a_max if i < 3 else g_max):
                still = False
            if i >= 3:
                mean_rate2 += mean * mean
                worst_rate_var = max(worst_rate_var, var)
        self.block_rate_b_rps = (s[3] / n, s[4] / n, s[5] / n)
        self.block_rate_sem_rps = math.sqrt(worst_rate_var / n)
        return still and math.sqrt(mean_rate2) <= self._max_rate


class ZeroMotionAiding:
    """Rest detection and the zero-velocity and zero-angular-rate updates, counted.

    Parameters
    ----------
    cfg : ZeroMotionTuning
    imu : ImuTuning
    layout : StateLayout
    counters : HealthCounters
        ``zupt_fused`` / ``zupt_rejected``, ``zaru_fused`` / ``zaru_rejected``.
    update : Update
        The filter's gated update.
    """

    def __init__(self, cfg: ZeroMotionTuning, imu: ImuTuning, layout: StateLayout,
                 counters: HealthCounters, update: Update) -> None:
        self.detector = StillnessDetector(cfg, imu)
        self._layout = layout
        self._c = counters
        self._update = update
        self._sigma = cfg.velocity_sigma_mps
        self._period_us = round(1e6 / cfg.fuse_rate_hz)
        self._next_us = 0
        self.gate = kalman.chi2_gate(3, cfg.gate_probability)
        self._rate_on = cfg.zero_rate
        self._rate_floor = cfg.rate_sigma_floor_rps
        self.rate_gate = kalman.chi2_gate(3, cfg.gate_probability)

    def on_imu(self, t_us: int, fw: tuple[float, ...], dt: float, ins: InsState,
               gyro_bias_b_rps: tuple[float, float, float]) -> None:
        """One integrated IMU sample: detect rest; at rest, fuse zero velocity at the rate and,
        at the end of every still block, the block's zero angular rate."""
        det = self.detector
        blocks = det.blocks
        if not det.add(fw, dt, ins.v_ned_mps):
            return
        if self._rate_on and det.blocks != blocks:
            sigma = max(det.block_rate_sem_rps, self._rate_floor)
            obs = zero_rate_model(self._layout, ins, det.block_rate_b_rps, gyro_bias_b_rps, sigma)
            res = self._update(obs, self.rate_gate, AidSource.ZERO_RATE, t_us)
            if res.test_ratio <= 1.0:
                self._c.zaru_fused += 1
            else:
                self._c.zaru_rejected += 1
        if t_us < self._next_us:
            return
        self._next_us = t_us + self._period_us
        obs = zero_velocity_model(self._layout, ins, self._sigma)
        res = self._update(obs, self.gate, AidSource.ZERO_VEL, t_us)
        if res.test_ratio <= 1.0:
            self._c.zupt_fused += 1
        else:
            self._c.zupt_rejected += 1
