"""Initial alignment: in flight from GNSS, static (levelling + magnetometer / gyrocompass), or
automatic (:class:`AutoAlignment`, the default: the path follows from the data).

In flight (fixed wing, coordinated flight), from good fixes 1 and 2 spanning ``window_s`` (and
no gap longer than ``max_fix_interval_s`` between them):

- the specific force in NED over the interval comes from GNSS:
  ``f_n = (v2 - v1) / (t2 - t1) - g_n + (2 omega_ie + omega_en) × v``;
- the specific force in body is the mean accelerometer output over the same interval;
- the heading comes from the velocity track: body x (forward) is taken along ``v_n`` (zero
  sideslip and angle of attack assumed);
- TRIAD with ``f`` as the exact primary vector and the track as the secondary one: ``f``
  fixes roll and pitch (in unaccelerated flight this reduces to the usual levelling
  ``roll = atan2(-f_y, -f_z)``, ``pitch = atan2(f_x, sqrt(f_y^2 + f_z^2))``, and, unlike it,
  stays right in a steady turn); the track fixes only the rotation about ``f``, i.e. heading.

The track-derived heading is off by the crab angle in wind; the initial yaw sigma
(``InitConfig.yaw_sigma_rad``) covers it and the filter converges in turns or with the
magnetometer. The attitude found is that of the interval's middle; it is carried to the current
time with the buffered gyro increments.

Static: mean specific force over ``static_duration_s`` (levelling), heading from the
tilt-compensated mean magnetometer field against the reference field
(:func:`fusion.aiding.mag.reference_field_n`: the World Magnetic Model at the fix and the
configured date by default), or, without a magnetometer or a reference, gyrocompassing
(horizontal Earth rate; only meaningful for gyros far better than the Earth rate, its yaw
sigma is derived from the gyro bias).

The filter starts from an alignment with the error covariance of :func:`aligned_covariance`
(the default initial variances of :func:`initial_variances` with the alignment's sigmas).
"""

from __future__ import annotations

import math
from collections import deque
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from fusion import earth
from fusion.aiding.mag import reference_field_n
from fusion.aiding.zero_motion import StillnessDetector
from fusion.config import FilterConfig, GnssTuning, ImuTuning, InitConfig, MagTuning
from fusion.rotations import (
    dcm_to_quat,
    euler_to_dcm,
    quat_multiply,
    quat_to_dcm,
    rotvec_to_quat,
    wrap_pi,
)
from fusion.samples import GnssFix
from fusion.state_layout import StateLayout
from fusion.strapdown import InsState

FloatArray = NDArray[np.float64]


class AlignmentResult(NamedTuple):
    """An initial INS state and its 1-sigma uncertainties."""

    time_us: int
    state: InsState
    sigma_pos_ned_m: tuple[float, float, float]
    sigma_vel_mps: float
    sigma_att_ned_rad: tuple[float, float, float]
    method: str
    """``in_flight`` (heading from the GNSS track), ``in_flight_mag`` (moving slowly: heading
    from the magnetometer), ``static_mag`` or ``static_gyrocompass``."""


def initial_variances(layout: StateLayout, config: FilterConfig) -> FloatArray:
    """Default initial error variances from ``InitConfig`` and the sensor sigmas.

    Parameters
    ----------
    layout : StateLayout
    config : FilterConfig

    Returns
    -------
    ndarray, shape (n,)
        In ``layout``: position m^2, velocity (m/s)^2, attitude rad^2, sensor errors SI^2.
    """
    lay, cfg = layout, config
    d = np.zeros(lay.n)
    d[lay.pos] = cfg.init.pos_sigma_m**2
    d[lay.vel] = cfg.init.vel_sigma_mps**2
    d[lay.att] = [cfg.init.roll_pitch_sigma_rad**2] * 2 + [cfg.init.yaw_sigma_rad**2]
    # Initial bias uncertainty: the turn-on (repeatability) bias, a random constant, plus the
    # in-run Gauss-Markov part.
    d[lay.ba] = cfg.imu.accel_turn_on_sigma_mps2**2 + cfg.imu.accel_bias_sigma_mps2**2
    d[lay.bg] = cfg.imu.gyro_turn_on_sigma_rps**2 + cfg.imu.gyro_bias_sigma_rps**2
    d[lay.baro] = cfg.baro.bias_sigma_m**2
    if lay.has_gnss_bias:
        g = cfg.gnss
        d[lay.gnss] = [g.bias_sigma_h_m**2] * 2 + [g.bias_sigma_v_m**2]
    if lay.has_scale_factors:
        d[lay.sa] = cfg.imu.accel_scale_sigma**2
        d[lay.sg] = cfg.imu.gyro_scale_sigma**2
    if lay.has_misalignment:
        d[lay.ma] = cfg.imu.accel_misalignment_sigma_rad**2
        d[lay.mg] = cfg.imu.gyro_misalignment_sigma_rad**2
    if lay.has_baro_scale:
        d[lay.bs] = cfg.baro.scale_sigma**2
    if lay.has_thermal:  # the unit's coefficient: the part's tempco is its 1-sigma spread
        th = cfg.thermal
        d[lay.KA : lay.KA + 3] = th.accel_tempco_mps2_per_k**2
        d[lay.KG : lay.KG + 3] = th.gyro_tempco_rps_per_k**2
    return d


def aligned_covariance(
    layout: StateLayout, config: FilterConfig, result: AlignmentResult
) -> FloatArray:
    """Initial error covariance after an alignment.

    The alignment's sigmas replace the default position, velocity and attitude variances.
    With the GNSS bias states the aligned position is a fix: its error is the receiver's bias
    plus white noise, i.e. ``dr = -db + w`` (``db = b^ - b`` with ``b^ = 0``), a correlation of
    ``-sigma_b^2`` per axis (capped at 0.9 of the position variance).

    Parameters
    ----------
    layout : StateLayout
    config : FilterConfig
    result : AlignmentResult

    Returns
    -------
    ndarray, shape (n, n)
    """
    lay = layout
    d = initial_variances(lay, config)
    d[lay.pos] = np.square(result.sigma_pos_ned_m)
    d[lay.vel] = result.sigma_vel_mps**2
    d[lay.att] = np.square(result.sigma_att_ned_rad)
    cov = np.diag(d)
    if lay.has_gnss_bias:
        for i in range(3):
            pi, gi = lay.POS + i, lay.GNSS + i
            c = min(cov[gi, gi], 0.9 * cov[pi, pi])
            cov[pi, gi] = cov[gi, pi] = -c
    return cov


def triad(v1_b: FloatArray, v1_n: FloatArray, v2_b: FloatArray, v2_n: FloatArray) -> FloatArray:
    """Rotation ``C_nb`` from two vector pairs: ``v1`` matched exactly, ``v2`` only fixes the
    rotation about ``v1``.

    Parameters
    ----------
    v1_b, v1_n, v2_b, v2_n : ndarray, shape (3,)
        The same two physical directions expressed in body and in NED.

    Returns
    -------
    ndarray, shape (3, 3)
    """

    def frame(a: FloatArray, b: FloatArray) -> FloatArray:
        t1 = a / np.linalg.norm(a)
        t2 = np.cross(a, b)
        norm = np.linalg.norm(t2)
        if norm < 1e-9 * np.linalg.norm(a) * np.linalg.norm(b):
            raise ValueError("TRIAD vectors are parallel")
        t2 = t2 / norm
        return np.column_stack([t1, t2, np.cross(t1, t2)])

    return frame(v1_n, v2_n) @ frame(v1_b, v2_b).T


def level_from_specific_force(f_b: FloatArray) -> tuple[float, float]:
    """Roll and pitch (rad) of a body at rest (or in unaccelerated flight) from its specific
    force ``f_b`` (≈ ``[0, 0, -g]`` when level)."""
    fx, fy, fz = (float(v) for v in f_b)
    return math.atan2(-fy, -fz), math.atan2(fx, math.hypot(fy, fz))


def _ins_from_antenna(
    lat: float, lon: float, alt: float, c_nb: FloatArray, lever_arm_b: tuple[float, float, float]
) -> tuple[float, float, float]:
    arm_n = c_nb @ np.asarray(lever_arm_b, dtype=float)
    t = earth.local_terms(lat, alt)
    return (
        lat - float(arm_n[0]) / t.rho_n_m,
        lon - float(arm_n[1]) / (t.rho_e_m * t.cos_lat),
        alt + float(arm_n[2]),
    )


class _Imu(NamedTuple):
    time_us: int
    dt_s: float
    f_b: tuple[float, float, float]
    w_b: tuple[float, float, float]


class _Fix(NamedTuple):
    time_us: int
    lat: float
    lon: float
    alt: float
    v: FloatArray
    eph: float
    sacc: float


class InFlightAlignment:
    """Collects IMU samples and good fixes until an in-flight alignment is possible.

    Parameters
    ----------
    init : InitConfig
    gnss : GnssTuning
    """

    def __init__(self, init: InitConfig, gnss: GnssTuning) -> None:
        self.init = init
        self.gnss = gnss
        self._imu: deque[_Imu] = deque(maxlen=8192)
        self._fixes: deque[_Fix] = deque(maxlen=64)
        self._mag: deque[tuple[int, FloatArray]] = deque(maxlen=1024)

    def add_imu(
        self,
        time_us: int,
        dt_s: float,
        f_b: tuple[float, float, float],
        w_b: tuple[float, float, float],
    ) -> None:
        """A valid IMU sample (interval mean specific force and rate)."""
        self._imu.append(_Imu(time_us, dt_s, f_b, w_b))
        # keep only what the next alignment can use
        horizon = round((self.init.window_s + self.init.max_fix_interval_s + 1.0) * 1e6)
        while self._imu and self._imu[0].time_us < time_us - horizon:
            self._imu.popleft()

    def add_fix(self, fix: GnssFix) -> None:
        """A fix that passed the quality checks (a gap longer than ``max_fix_interval_s`` since
        the previous one restarts the collection)."""
        v = np.asarray(fix.v_ned_mps, dtype=float).copy()
        if not math.isfinite(v[2]):
            # vertical velocity not reported (GPS_RAW_INT): from the height change instead
            prev = self._fixes[-1] if self._fixes else None
            dt = (fix.time_us - prev.time_us) * 1e-6 if prev is not None else 0.0
            v[2] = -(float(fix.alt_msl_m) - prev.alt) / dt if prev is not None and dt > 0 else 0.0
        if self._fixes and (
            fix.time_us - self._fixes[-1].time_us > self.init.max_fix_interval_s * 1e6
            or fix.time_us <= self._fixes[-1].time_us
        ):
            self._fixes.clear()
        self._fixes.append(
            _Fix(
                int(fix.time_us), float(fix.lat_rad), float(fix.lon_rad), float(fix.alt_msl_m), v,
                float(fix.eph_m), float(fix.speed_accuracy_mps),
            )
        )  # fmt: skip

    def add_mag(self, time_us: int, field_b: FloatArray) -> None:
        """A valid magnetometer sample (body, T): the heading source of :meth:`poll_magnetic`."""
        self._mag.append((time_us, np.asarray(field_b, dtype=float)))

    def poll(self) -> AlignmentResult | None:
        """Try to align now (at the newest IMU sample's time), heading from the GNSS track:
        needs ``min_speed_mps`` over the whole window."""
        w = self._window()
        if w is None:
            return None
        f1, f2, window_fixes, f_b, f_n, v_mid = w
        speed = float(np.linalg.norm(v_mid[:2]))
        if (
            speed < self.init.min_speed_mps
            or min(float(np.linalg.norm(f.v[:2])) for f in window_fixes) < self.init.min_speed_mps
        ):
            return None
        try:
            c_nb = triad(f_b, f_n, np.array([1.0, 0.0, 0.0]), v_mid)
        except ValueError:
            return None
        return self._result(f1, f2, c_nb, self.init.yaw_sigma_rad, "in_flight")

    def poll_magnetic(self, mag: MagTuning) -> AlignmentResult | None:
        """Try to align now with the heading from the magnetometer against the reference field
        (:func:`fusion.aiding.mag.reference_field_n`), at any speed: a hovering or slowly
        moving vehicle, whose track says nothing about its heading. Level from the specific
        force minus the GNSS acceleration as in :meth:`poll`; the mean body field over the
        same window is the TRIAD's second vector."""
        w = self._window()
        if w is None:
            return None
        f1, f2, _, f_b, f_n, _ = w
        fields = [m for t, m in self._mag if f1.time_us < t <= f2.time_us]
        ref = reference_field_n(mag, 0.5 * (f1.lat + f2.lat), 0.5 * (f1.lon + f2.lon),
                                0.5 * (f1.alt + f2.alt))  # fmt: skip
        if not fields or ref is None:
            return None
        m_b = np.mean(fields, axis=0)
        try:
            c_nb = triad(f_b, f_n, m_b, ref)
        except ValueError:
            return None
        # the tilt error leaks into the magnetic heading through the vertical field
        tan_dip = abs(float(ref[2])) / max(math.hypot(float(ref[0]), float(ref[1])), 1e-9)
        sig_yaw = min(math.pi, math.hypot(self.init.static_yaw_sigma_rad,
                                          tan_dip * self.init.roll_pitch_sigma_rad))
        return self._result(f1, f2, c_nb, sig_yaw, "in_flight_mag")

    def _window(
        self,
    ) -> tuple[_Fix, _Fix, list[_Fix], FloatArray, FloatArray, FloatArray] | None:
        """Fixes 1 and 2, the fixes between them, the mean body specific force over the
        interval, the specific force in NED from GNSS, and the mean velocity; ``None`` until
        a window of good fixes and IMU samples spanning it exists."""
        if len(self._fixes) < 2 or not self._imu:
            return None
        f2 = self._fixes[-1]
        # the oldest fix at least window_s before the newest (GNSS velocity noise / window is
        # the specific-force noise: 0.15 m/s over 0.2 s would be ~6 deg of tilt, over 1 s ~1)
        f1 = next(
            (f for f in reversed(self._fixes)
             if (f2.time_us - f.time_us) * 1e-6 >= self.init.window_s - 1e-6),
            None,
        )  # fmt: skip
        if f1 is None:
            return None
        now_us = self._imu[-1].time_us
        dt_fix = (f2.time_us - f1.time_us) * 1e-6
        if now_us < f2.time_us or self._imu[0].time_us > f1.time_us:
            return None
        v_mid = 0.5 * (f1.v + f2.v)
        window_fixes = [f for f in self._fixes if f.time_us >= f1.time_us]
        window = [s for s in self._imu if f1.time_us < s.time_us <= f2.time_us]
        if len(window) < 2:
            return None
        f_b = np.mean([s.f_b for s in window], axis=0)
        lat_mid, alt_mid = 0.5 * (f1.lat + f2.lat), 0.5 * (f1.alt + f2.alt)
        w_ie = earth.earth_rate_n(lat_mid)
        w_en = earth.transport_rate_n(lat_mid, alt_mid, v_mid)
        g_n = np.array([0.0, 0.0, float(earth.gravity(lat_mid, alt_mid))])
        f_n = (f2.v - f1.v) / dt_fix - g_n + np.cross(2.0 * w_ie + w_en, v_mid)
        return f1, f2, window_fixes, f_b, f_n, v_mid

    def _result(
        self, f1: _Fix, f2: _Fix, c_nb: FloatArray, sig_yaw: float, method: str
    ) -> AlignmentResult:
        """The attitude ``c_nb`` of the window's middle carried to now with the gyro
        increments, the position and velocity carried from fix 2 to now."""
        now_us = self._imu[-1].time_us
        dt_fix = (f2.time_us - f1.time_us) * 1e-6
        t_mid = 0.5 * (f1.time_us + f2.time_us)
        q = dcm_to_quat(c_nb)
        for s in self._imu:
            if s.time_us > t_mid:
                dt = min(s.dt_s, (s.time_us - t_mid) * 1e-6)
                q = quat_multiply(q, rotvec_to_quat(np.asarray(s.w_b) * dt))
        q = q / np.linalg.norm(q)
        c_now = quat_to_dcm(q)
        # position/velocity carried from fix 2 to now with the GNSS velocity and acceleration
        lag = (now_us - f2.time_us) * 1e-6
        acc = (f2.v - f1.v) / dt_fix
        t = earth.local_terms(f2.lat, f2.alt)
        lat_a = f2.lat + float(f2.v[0]) * lag / t.rho_n_m
        lon_a = f2.lon + float(f2.v[1]) * lag / (t.rho_e_m * t.cos_lat)
        alt_a = f2.alt - float(f2.v[2]) * lag
        lat, lon, alt = _ins_from_antenna(lat_a, lon_a, alt_a, c_now, self.gnss.lever_arm_b_m)
        v_now = f2.v + acc * lag
        state = InsState.from_arrays(lat, lon, alt, v_now, q)
        sig_h = max(self.init.pos_sigma_m, f2.eph)
        sig_v = max(self.init.vel_sigma_mps, f2.sacc)
        rp = self.init.roll_pitch_sigma_rad
        return AlignmentResult(
            now_us, state, (sig_h, sig_h, sig_h), sig_v, (rp, rp, sig_yaw), method,
        )  # fmt: skip


class StaticAlignment:
    """Levelling plus magnetometer (or gyrocompass) heading for a vehicle at rest.

    Parameters
    ----------
    init : InitConfig
    gnss : GnssTuning
    mag : MagTuning
    imu : ImuTuning
    """

    def __init__(self, init: InitConfig, gnss: GnssTuning, mag: MagTuning, imu: ImuTuning,
                 max_rate_rps: float | None = None) -> None:
        self.init = init
        self.gnss = gnss
        self.mag = mag
        self.imu = imu
        self._max_rate = init.static_max_rate_rps if max_rate_rps is None else max_rate_rps
        self._restart()
        self._fix: _Fix | None = None

    def _restart(self) -> None:
        self._t0_us: int | None = None
        self._t1_us = 0
        self._sum_f = np.zeros(3)
        self._sum_w = np.zeros(3)
        self._n = 0
        self._sum_m = np.zeros(3)
        self._n_m = 0

    def add_imu(
        self,
        time_us: int,
        dt_s: float,
        f_b: tuple[float, float, float],
        w_b: tuple[float, float, float],
    ) -> None:
        """A valid IMU sample; a rate above ``static_max_rate_rps`` (or the ``max_rate_rps``
        given) restarts the window."""
        if max(abs(w) for w in w_b) > self._max_rate:
            self._restart()
            return
        if self._t0_us is None:
            self._t0_us = time_us
        self._t1_us = time_us
        self._sum_f += f_b
        self._sum_w += w_b
        self._n += 1

    def add_fix(self, fix: GnssFix) -> None:
        """A fix that passed the quality checks (gives the position)."""
        self._fix = _Fix(
            int(fix.time_us), float(fix.lat_rad), float(fix.lon_rad), float(fix.alt_msl_m),
            np.asarray(fix.v_ned_mps, dtype=float), float(fix.eph_m), float(fix.speed_accuracy_mps),
        )  # fmt: skip

    def add_mag(self, time_us: int, field_b: FloatArray) -> None:
        """A valid magnetometer sample (body, T)."""
        if self._t0_us is not None:
            self._sum_m += field_b
            self._n_m += 1

    def poll(self) -> AlignmentResult | None:
        """Align when the window is full and a fix is known."""
        if self._t0_us is None or self._fix is None or self._n < 2:
            return None
        if (self._t1_us - self._t0_us) * 1e-6 < self.init.static_duration_s:
            return None
        f_b = self._sum_f / self._n
        roll, pitch = level_from_specific_force(f_b)
        c_lev = euler_to_dcm(np.array([roll, pitch, 0.0]))
        fix = self._fix
        ref = reference_field_n(self.mag, fix.lat, fix.lon, fix.alt)
        if ref is not None and self._n_m > 0:
            m_lev = c_lev @ (self._sum_m / self._n_m)
            yaw = math.atan2(ref[1], ref[0]) - math.atan2(float(m_lev[1]), float(m_lev[0]))
            sig_yaw = self.init.static_yaw_sigma_rad
            method = "static_mag"
        else:
            # the Earth rate's horizontal part points north: in the levelled frame it is at -yaw
            w_lev = c_lev @ (self._sum_w / self._n)
            yaw = math.atan2(-float(w_lev[1]), float(w_lev[0]))
            horiz = earth.RATE * math.cos(fix.lat)
            sig_yaw = min(
                math.pi, max(self.init.static_yaw_sigma_rad, self.imu.gyro_bias_sigma_rps / horiz)
            )
            method = "static_gyrocompass"
        yaw = wrap_pi(yaw)
        c_nb = euler_to_dcm(np.array([roll, pitch, yaw]))
        lat, lon, alt = _ins_from_antenna(fix.lat, fix.lon, fix.alt, c_nb, self.gnss.lever_arm_b_m)
        state = InsState.from_arrays(lat, lon, alt, np.zeros(3), dcm_to_quat(c_nb))
        sig_h = max(self.init.pos_sigma_m, fix.eph)
        rp = self.init.roll_pitch_sigma_rad
        return AlignmentResult(
            self._t1_us, state, (sig_h, sig_h, sig_h), self.init.vel_sigma_mps, (rp, rp, sig_yaw),
            method,
        )  # fmt: skip


class AutoAlignment:
    """The default alignment (``InitConfig.mode="auto"``): the path follows from the data.

    - **at rest** (the rest detector of :mod:`fusion.aiding.zero_motion` judges its 1 s blocks
      still and GNSS says slower than ``ZeroMotionTuning.max_speed_mps``): the static
      alignment over ``static_duration_s`` of still blocks (levelling, magnetometer heading
      against the reference field, gyrocompassing without one); the zero-velocity and
      zero-angular-rate updates of the running filter are the fine alignment;
    - **moving at ``min_speed_mps`` or more**: the in-flight alignment, heading from the GNSS
      track (exactly the ``in_flight`` mode);
    - **moving slower** (hover, taxi; the last block was not still): levelling from the
      specific force minus the GNSS acceleration and heading from the magnetometer
      (:meth:`InFlightAlignment.poll_magnetic`); the heading updates of the magnetometer then
      hold yaw until GNSS velocity makes it observable. Without a magnetometer it waits for
      speed, as ``in_flight`` does.

    Parameters
    ----------
    config : FilterConfig
    """

    def __init__(self, config: FilterConfig) -> None:
        cfg = config
        self._flight = InFlightAlignment(cfg.init, cfg.gnss)
        # rest is the detector's verdict; its rate bound (3 deg/s) is above a consumer gyro's
        # turn-on bias (0.5 deg/s, 1 sigma), which the static mode's 0.02 rad/s is not
        self._static = StaticAlignment(cfg.init, cfg.gnss, cfg.mag, cfg.imu,
                                       max_rate_rps=cfg.zero_motion.max_rate_rps)
        self._detector = StillnessDetector(cfg.zero_motion, cfg.imu)
        self._mag_cfg = cfg.mag
        self._max_rest_speed = cfg.zero_motion.max_speed_mps
        self._v: tuple[float, float, float] = (0.0, 0.0, 0.0)
        self._has_fix = False
        self._has_mag = False
        self._block_imu: list[tuple[int, float, tuple[float, float, float],
                                    tuple[float, float, float]]] = []  # fmt: skip
        self._block_mag: list[tuple[int, FloatArray]] = []
        self.moving: bool | None = None
        """Verdict of the last judged block (``None`` before the first)."""

    @property
    def state(self) -> str:
        """What the alignment is waiting for, in words (health / status)."""
        if not self._has_fix:
            return "waiting for a GNSS fix"
        if self.moving is None:
            return "watching for rest or motion"
        if not self.moving:
            return "at rest: levelling"
        if self._has_mag:
            return "moving: magnetic heading"
        return "moving: waiting for speed (no magnetometer)"

    def add_imu(
        self,
        time_us: int,
        dt_s: float,
        f_b: tuple[float, float, float],
        w_b: tuple[float, float, float],
    ) -> None:
        """A valid IMU sample: into the in-flight window and, block by block once the rest
        detector judged the block still, into the static window."""
        self._flight.add_imu(time_us, dt_s, f_b, w_b)
        det = self._detector
        blocks = det.blocks
        vn, ve, vd = self._v
        if vn * vn + ve * ve + vd * vd > self._max_rest_speed**2:
            det.add((*f_b, *w_b), dt_s, self._v)  # clears the detector
            self._end_block(still=False)
            return
        self._block_imu.append((time_us, dt_s, f_b, w_b))
        still = det.add((*f_b, *w_b), dt_s, self._v)
        if det.blocks != blocks:
            self._end_block(still)

    def _end_block(self, still: bool) -> None:
        self.moving = not still
        if still:
            for s in self._block_imu:
                self._static.add_imu(*s)
            for t, m in self._block_mag:
                self._static.add_mag(t, m)
        else:
            self._static._restart()
        self._block_imu.clear()
        self._block_mag.clear()

    def add_fix(self, fix: GnssFix) -> None:
        """A fix that passed the quality checks."""
        self._flight.add_fix(fix)
        self._static.add_fix(fix)
        v = np.asarray(fix.v_ned_mps, dtype=float)
        self._v = (float(v[0]), float(v[1]), float(v[2]) if math.isfinite(v[2]) else 0.0)
        self._has_fix = True

    def add_mag(self, time_us: int, field_b: FloatArray) -> None:
        """A valid magnetometer sample."""
        self._flight.add_mag(time_us, field_b)
        self._block_mag.append((time_us, field_b))
        self._has_mag = True

    def poll(self) -> AlignmentResult | None:
        """At rest: static; fast enough: track; moving slowly with a magnetometer: magnetic."""
        vn, ve, vd = self._v
        if vn * vn + ve * ve + vd * vd <= self._max_rest_speed**2:
            res = self._static.poll()
            if res is not None:
                return res
        res = self._flight.poll()
        if res is not None or not self.moving or not self._has_mag:
            return res
        if math.hypot(vn, ve) >= self._flight.init.min_speed_mps:
            return None  # fast enough for the track: wait for its window
        return self._flight.poll_magnetic(self._mag_cfg)
