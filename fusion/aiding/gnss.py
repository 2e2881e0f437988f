"""GNSS position and velocity aiding (loosely coupled).

*How* — :func:`position_model`, :func:`velocity_model`: the INS state at the fix's time of
validity, moved to the antenna by the lever arm, minus the fix::

    z_pos = [dN, dE, dD](INS - fix) + C_nb l_b                        (metres NED)
    z_vel = v_n + C_nb (omega_ib_b × l_b) - omega_in_n × (C_nb l_b) - v_fix   (m/s NED)

``eph_m`` is used as the 1-sigma of *each* horizontal axis (as PX4's ekf2 does), ``epv_m`` for
down, ``speed_accuracy_mps`` for each velocity axis, each floored by the configuration.

Time-correlated receiver error (layouts ``ins16+gnss`` / ``ins22+gnss``): the fix is
``p_fix = p + b + w`` with ``b`` a Gauss-Markov position bias (N, E, D; tau ~ minutes) and ``w``
white. The filter carries the bias estimate ``b^`` and its error ``db = b^ - b`` (layout block
``gnss``), and the position observation becomes::

    z_pos = [dN, dE, dD](INS - fix) + C_nb l_b + b^ = dr + db - w,    H_gnss = I

with ``R`` the white part only, ``eph^2 - sigma_b^2`` (:func:`white_position_sigmas`). Fused as
white noise at ``eph`` instead, 5 fixes/s of an error that changes over 120 s are taken as
independent, and the position sigma shrinks far below the actual error.

Latency: the fix is compared with the INS state buffered at its time of validity (corrected for
every feedback applied since, see :mod:`fusion.history`), while the error state lives at the
current time. Over the delay ``d`` (<= ``max_delay_s``) ``dr(t_fix) ≈ dr(now) - dv d``; that
term is in ``H``; the other couplings over a fraction of a second (attitude into velocity,
~g phi d) are neglected, which keeps the update a plain one-epoch update.

*When* — :func:`fix_quality` (3-D fix, finite, in range: latitude, longitude, altitude,
speed; accuracy) and :class:`GnssControl`: outage detection (no fused fix for
``outage_timeout_s``), re-acquisition after ``reacquire_fixes`` consecutive good fixes, and
reset requests (re-acquisition after a real outage that the gate rejects, or good-quality
fixes rejected for ``reset_after_rejected_s``).

*Bounded reset* — a requested reset goes to the fix only if the INS does not contradict it
(every innovation axis within ``reset_sigma`` times the INS's sigma plus the fix's claimed
accuracy), or if ``reset_confirm_fixes`` consecutive rejected fixes follow from each other
and, in a continuous stream, from the last fused fix (positions moving as their velocities
say). A fix stream that jumped away from the fused track is therefore not reset to until the
INS's own uncertainty covers the jump; refusals are counted (``gnss_resets_refused``).

*Fusion step* — :class:`GnssAiding`: a fix through the quality checks and the control, its
position update (then a bounded reset when the control asks for one), its velocity update,
counted.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from fusion import earth, kalman
from fusion.aiding import Observation, Update
from fusion.config import GnssTuning
from fusion.estimate import AidSource, HealthCounters
from fusion.rotations import dcm_from_quat
from fusion.samples import GnssFix
from fusion.state_layout import StateLayout
from fusion.strapdown import InsState

FloatArray = NDArray[np.float64]
Reset = Callable[[FloatArray, FloatArray], None]
"""``reset(z, variances)``: set a block of the INS to the measurement."""


def _cross(a: tuple[float, ...], b: tuple[float, ...]) -> tuple[float, float, float]:
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def _rotate(c: tuple[float, ...], v: tuple[float, ...]) -> tuple[float, float, float]:
    return (
        c[0] * v[0] + c[1] * v[1] + c[2] * v[2],
        c[3] * v[0] + c[4] * v[1] + c[5] * v[2],
        c[6] * v[0] + c[7] * v[1] + c[8] * v[2],
    )


def position_model(
    layout: StateLayout,
    ins: InsState,
    fix_lat_rad: float,
    fix_lon_rad: float,
    fix_alt_m: float,
    sigma_h_m: float,
    sigma_v_m: float,
    lever_arm_b_m: tuple[float, float, float] = (0.0, 0.0, 0.0),
    delay_s: float = 0.0,
    bias_ned_m: tuple[float, float, float] | None = None,
) -> Observation | None:
    """GNSS position observation (antenna position, metres NED).

    Parameters
    ----------
    layout : StateLayout
    ins : InsState
        INS state at the fix's time of validity.
    fix_lat_rad, fix_lon_rad, fix_alt_m : float
        Fix position.
    sigma_h_m, sigma_v_m : float
        1-sigma per horizontal axis and vertical, m.
    lever_arm_b_m : 3 floats
        Antenna w.r.t. IMU in body FRD, m.
    delay_s : float
        Current time minus the fix's time of validity, s (>= 0).
    bias_ned_m : 3 floats, optional
        Current estimate of the receiver's correlated position error ``b^``, m NED. Given
        (the layout must have the ``gnss`` block): it is added to ``z`` and ``H`` gets an
        identity on the bias block. ``None``: the fix is not a receiver fix with a modelled
        bias (e.g. a bridging pseudo-fix); the bias block of ``H`` stays zero.

    Returns
    -------
    Observation or None
        ``None`` when the inputs are not finite or the sigmas not positive.

    Raises
    ------
    ValueError
        ``bias_ned_m`` given for a layout without the GNSS bias block.
    """
    vals = (fix_lat_rad, fix_lon_rad, fix_alt_m, sigma_h_m, sigma_v_m)
    if not all(math.isfinite(v) for v in vals) or sigma_h_m <= 0.0 or sigma_v_m <= 0.0:
        return None
    c_nb = dcm_from_quat(ins.q_nb)
    arm_n = _rotate(c_nb, lever_arm_b_m)
    d = earth.ned_offset_m(
        ins.lat_rad, ins.lon_rad, ins.alt_msl_m, fix_lat_rad, fix_lon_rad, fix_alt_m
    )
    z = np.array([d[0] + arm_n[0], d[1] + arm_n[1], d[2] + arm_n[2]])
    H = np.zeros((3, layout.n))
    p, v, a = layout.POS, layout.VEL, layout.ATT
    for i in range(3):
        H[i, p + i] = 1.0
        # dr(t_fix) = dr(now) - dv * delay
        H[i, v + i] = -delay_s
    if bias_ned_m is not None:
        g = layout.GNSS  # ValueError when the layout has no bias block
        # z = p_ins - (p_fix - b^) = dr + (b^ - b) - w; the bias changes little over the delay
        # (tau ~ minutes vs <= 0.5 s), so b^(now) and db(now) stand for their values at t_fix
        for i in range(3):
            z[i] += bias_ned_m[i]
            H[i, g + i] = 1.0
    # d(C l) = [phi×] C l = -[(C l)×] phi
    H[0, a + 1], H[0, a + 2] = arm_n[2], -arm_n[1]
    H[1, a], H[1, a + 2] = -arm_n[2], arm_n[0]
    H[2, a], H[2, a + 1] = arm_n[1], -arm_n[0]
    sh2, sv2 = sigma_h_m * sigma_h_m, sigma_v_m * sigma_v_m
    R = np.array([[sh2, 0.0, 0.0], [0.0, sh2, 0.0], [0.0, 0.0, sv2]])
    return Observation(z, H, R)


def velocity_model(
    layout: StateLayout,
    ins: InsState,
    omega_ib_b_rps: tuple[float, float, float],
    fix_v_ned_mps: np.ndarray,
    sigma_mps: float,
    lever_arm_b_m: tuple[float, float, float] = (0.0, 0.0, 0.0),
) -> Observation | None:
    """GNSS velocity observation (antenna velocity, NED).

    Parameters
    ----------
    layout : StateLayout
    ins : InsState
        INS state at the fix's time of validity.
    omega_ib_b_rps : 3 floats
        Bias-corrected body rate, rad/s (for the lever-arm velocity).
    fix_v_ned_mps : ndarray, shape (3,)
        Fix velocity, m/s.
    sigma_mps : float
        1-sigma per axis, m/s.
    lever_arm_b_m : 3 floats
        Antenna w.r.t. IMU in body FRD, m.

    Returns
    -------
    Observation or None
    """
    v_fix = np.asarray(fix_v_ned_mps, dtype=float)
    if v_fix.shape != (3,) or not np.all(np.isfinite(v_fix[:2])) or not sigma_mps > 0.0:
        return None
    c_nb = dcm_from_quat(ins.q_nb)
    arm_b = lever_arm_b_m
    arm_n = _rotate(c_nb, arm_b)
    t = earth.local_terms(ins.lat_rad, ins.alt_msl_m)
    vn, ve, vd = ins.v_ned_mps
    w_in = (
        earth.RATE * t.cos_lat + ve / t.rho_e_m,
        -vn / t.rho_n_m,
        -earth.RATE * t.sin_lat - ve * t.sin_lat / t.cos_lat / t.rho_e_m,
    )
    rot_n = _rotate(c_nb, _cross(omega_ib_b_rps, arm_b))
    w_arm = _cross(w_in, arm_n)
    fv = v_fix.tolist()
    z = np.array([
        vn + rot_n[0] - w_arm[0] - fv[0],
        ve + rot_n[1] - w_arm[1] - fv[1],
        vd + rot_n[2] - w_arm[2] - fv[2],
    ])  # fmt: skip
    H = np.zeros((3, layout.n))
    v, a, g = layout.VEL, layout.ATT, layout.BG
    for i in range(3):
        H[i, v + i] = 1.0
    if any(arm_b):
        # attitude: -[(C (w × l))×] + [w_in×][(C l)×] = -[r×] + (C l) w_in^T - (w_in . C l) I
        dot = w_in[0] * arm_n[0] + w_in[1] * arm_n[1] + w_in[2] * arm_n[2]
        m = [[arm_n[i] * w_in[j] - (dot if i == j else 0.0) for j in range(3)] for i in range(3)]
        r = rot_n
        m[0][1] += r[2]
        m[0][2] -= r[1]
        m[1][0] -= r[2]
        m[1][2] += r[0]
        m[2][0] += r[1]
        m[2][1] -= r[0]
        H[:, a : a + 3] = m
        # gyro bias: omega^ = omega - dbg, C (-dbg × l) = C [l×] dbg
        lx, ly, lz = arm_b
        c = c_nb
        H[:, g : g + 3] = [
            [c[3 * i + 1] * lz - c[3 * i + 2] * ly,
             -c[3 * i] * lz + c[3 * i + 2] * lx,
             c[3 * i] * ly - c[3 * i + 1] * lx]
            for i in range(3)
        ]  # fmt: skip
    s2 = sigma_mps * sigma_mps
    if not math.isfinite(fv[2]):  # vertical velocity not reported: horizontal rows only
        return Observation(z[:2], H[:2], np.array([[s2, 0.0], [0.0, s2]]))
    R = np.array([[s2, 0.0, 0.0], [0.0, s2, 0.0], [0.0, 0.0, s2]])
    return Observation(z, H, R)


def fix_quality(fix: GnssFix, cfg: GnssTuning) -> str | None:
    """Why a fix cannot be used (``"no_fix"``, ``"invalid"``, ``"inaccurate"``), or ``None``."""
    if fix.fix_type < 3:
        return "no_fix"
    scalars = (
        fix.lat_rad,
        fix.lon_rad,
        fix.alt_msl_m,
    )
    if not all(math.isfinite(float(v)) for v in scalars):
        return "invalid"
    v = np.asarray(fix.v_ned_mps, dtype=float)
    # a NaN vertical velocity means "not reported" (GPS_RAW_INT has none): only the
    # horizontal velocity is fused then
    if v.shape != (3,) or not np.all(np.isfinite(v[:2])) or np.isinf(v[2]):
        return "invalid"
    # NaN accuracies mean "not reported" (HIL_GPS has no speed accuracy; 65535 = unknown):
    # the configured defaults stand in for them in fix_sigmas.
    if (
        abs(fix.lat_rad) > 0.5 * math.pi or abs(fix.lon_rad) > math.pi
        or not cfg.min_alt_m <= fix.alt_msl_m <= cfg.max_alt_m
        or math.hypot(v[0], v[1]) > cfg.max_speed_mps or abs(v[2]) > cfg.max_speed_mps
        or fix.eph_m < 0.0 or fix.epv_m < 0.0
    ):  # fmt: skip
        return "invalid"
    if fix.eph_m > cfg.max_eph_m:
        return "inaccurate"
    return None


def white_position_sigmas(
    sigma_h_m: float, sigma_v_m: float, cfg: GnssTuning, layout: StateLayout
) -> tuple[float, float]:
    """The white part of the reported position sigmas when the bias states take the rest.

    The receiver's ``eph`` / ``epv`` describe its *total* error; with the Gauss-Markov bias
    states (a ``+gnss`` layout) only ``sqrt(sigma^2 - sigma_b^2)`` is left for ``R``, floored by
    ``pos_noise_floor_m`` (a receiver reporting less than the configured bias sigma). Without
    bias states the sigmas are returned unchanged.

    Parameters
    ----------
    sigma_h_m, sigma_v_m : float
        Per-axis horizontal and vertical sigmas (:func:`fix_sigmas`), m.
    cfg : GnssTuning
    layout : StateLayout
        The filter's layout (:attr:`~fusion.state_layout.StateLayout.has_gnss_bias`).

    Returns
    -------
    (float, float)
        Horizontal and vertical white sigmas, m.
    """
    if not layout.has_gnss_bias:
        return sigma_h_m, sigma_v_m
    floor2 = cfg.pos_noise_floor_m**2
    h2 = sigma_h_m * sigma_h_m - cfg.bias_sigma_h_m * cfg.bias_sigma_h_m
    v2 = sigma_v_m * sigma_v_m - cfg.bias_sigma_v_m * cfg.bias_sigma_v_m
    return math.sqrt(max(h2, floor2)), math.sqrt(max(v2, floor2))


def fix_sigmas(fix: GnssFix, cfg: GnssTuning) -> tuple[float, float, float]:
    """Per-axis sigmas ``(horizontal m, vertical m, velocity m/s)`` with the configured floors.

    An accuracy the receiver did not report (NaN) takes the configured default.
    """
    eph, epv, sacc = float(fix.eph_m), float(fix.epv_m), float(fix.speed_accuracy_mps)
    return (
        max(eph if math.isfinite(eph) else cfg.default_eph_m, cfg.pos_noise_floor_m),
        max(epv if math.isfinite(epv) else cfg.default_epv_m, cfg.pos_noise_floor_m),
        max(sacc if math.isfinite(sacc) else cfg.default_speed_accuracy_mps,
            cfg.vel_noise_floor_mps),
    )


class _FixPoint(NamedTuple):
    time_us: int
    lat_rad: float
    lon_rad: float
    alt_m: float
    v_ned_mps: tuple[float, float, float]
    sigma_h_m: float
    sigma_v_m: float
    sigma_vel_mps: float


def _consistent(a: _FixPoint, b: _FixPoint, max_accel_mps2: float) -> bool:
    """Fix ``b`` follows from fix ``a``: its position moved as the two velocities say
    (trapezoid) and its velocity changed by no more than ``max_accel_mps2`` allows, within
    three times their claimed accuracies (a NaN vertical velocity counts as zero)."""
    dt = (b.time_us - a.time_us) * 1e-6
    if not dt > 0.0:
        return False
    d = earth.ned_offset_m(b.lat_rad, b.lon_rad, b.alt_m, a.lat_rad, a.lon_rad, a.alt_m)
    slack = 0.5 * max_accel_mps2 * dt * dt
    for i in range(3):
        va = a.v_ned_mps[i] if math.isfinite(a.v_ned_mps[i]) else 0.0
        vb = b.v_ned_mps[i] if math.isfinite(b.v_ned_mps[i]) else 0.0
        sig = a.sigma_v_m + b.sigma_v_m if i == 2 else a.sigma_h_m + b.sigma_h_m
        if abs(d[i] - 0.5 * (va + vb) * dt) > 3.0 * sig + slack:
            return False
        if abs(vb - va) > 3.0 * (a.sigma_vel_mps + b.sigma_vel_mps) + max_accel_mps2 * dt:
            return False
    return True


class GnssControl:
    """When to fuse GNSS: outage detection, re-acquisition and reset logic.

    Parameters
    ----------
    cfg : GnssTuning
    """

    def __init__(self, cfg: GnssTuning) -> None:
        self.cfg = cfg
        self._timeout_us = round(cfg.outage_timeout_s * 1e6)
        self._reset_us = round(cfg.reset_after_rejected_s * 1e6)
        self.last_fused_us: int | None = None
        self.last_good_us: int | None = None
        self.good_streak = 0
        self.reacquiring = False
        self._after_true_outage = False
        self._rejected_since_us: dict[str, int | None] = {"pos": None, "vel": None}
        # bounded resets: the last fused fix, and the run of rejected fixes since it
        self._anchor: _FixPoint | None = None
        self._run_last: _FixPoint | None = None
        self._run_n = 0
        self._run_broken = False

    def is_active(self, now_us: int) -> bool:
        """GNSS is aiding: a fix was fused within ``outage_timeout_s``."""
        return self.last_fused_us is not None and now_us - self.last_fused_us <= self._timeout_us

    def time_since_fused_s(self, now_us: int) -> float:
        """Seconds since the last fused fix (``inf`` before the first)."""
        if self.last_fused_us is None:
            return math.inf
        return (now_us - self.last_fused_us) * 1e-6

    def start(self, time_us: int) -> None:
        """The filter was initialised from GNSS at ``time_us``: aiding is active."""
        self.last_fused_us = time_us
        self.last_good_us = time_us
        self.good_streak = self.cfg.reacquire_fixes
        self.reacquiring = self._after_true_outage = False

    def on_bad_fix(self) -> None:
        """A fix failed the quality checks: the consecutive-good count restarts."""
        self.good_streak = 0

    def on_good_fix(self, time_us: int, now_us: int) -> bool:
        """A fix passed the quality checks. Returns True if it should be fused now."""
        real_gap = self.last_good_us is None or time_us - self.last_good_us > self._timeout_us
        self.good_streak = 1 if real_gap else self.good_streak + 1
        self.last_good_us = time_us
        if self.is_active(now_us):
            return True
        if real_gap:
            # An outage without usable fixes: when fixes come back, a gate rejection means the
            # INS drifted, not that the fix is bad.
            self._after_true_outage = True
        if self.good_streak >= self.cfg.reacquire_fixes:
            self.reacquiring = self._after_true_outage
            return True
        return False

    def on_result(self, part: str, time_us: int, accepted: bool) -> bool:
        """Record the gate's verdict for ``part`` (``"pos"`` or ``"vel"``).

        Returns
        -------
        bool
            True when that part should be reset to the fix instead.
        """
        if accepted:
            self.last_fused_us = (
                time_us if self.last_fused_us is None else max(self.last_fused_us, time_us)
            )
            self._rejected_since_us[part] = None
            if part == "pos":
                self.reacquiring = self._after_true_outage = False
            return False
        since = self._rejected_since_us[part]
        if since is None:
            self._rejected_since_us[part] = since = time_us
        if self.reacquiring or time_us - since >= self._reset_us:
            return True
        return False

    def on_position_result(self, fix: GnssFix, sigmas: tuple[float, float, float],
                           accepted: bool) -> None:
        """Track the run of rejected fixes that a reset the INS contradicts needs.

        An accepted fix is the anchor. Each rejected fix must follow from the previous one
        (:func:`_consistent`); the first of a run must follow from the anchor when the stream
        is continuous (within ``outage_timeout_s``). A jump away from the fused track breaks
        the run for good (until a fix is fused again or a real outage starts a new run);
        a fix that does not follow from the previous rejected one restarts the count.
        """
        vd = float(fix.v_ned_mps[2])
        p = _FixPoint(int(fix.time_us), float(fix.lat_rad), float(fix.lon_rad),
                      float(fix.alt_msl_m),
                      (float(fix.v_ned_mps[0]), float(fix.v_ned_mps[1]), vd), *sigmas)  # fmt: skip
        if accepted:
            self._anchor, self._run_last, self._run_n, self._run_broken = p, None, 0, False
            return
        amax = self.cfg.max_accel_mps2
        prev = self._run_last
        if prev is not None and p.time_us - prev.time_us > self._timeout_us:
            prev = None  # a real gap: a new run, not anchored
            self._run_n, self._run_broken = 0, False
        if prev is None:
            anchor = self._anchor
            if anchor is not None and p.time_us - anchor.time_us <= self._timeout_us:
                self._run_broken = self._run_broken or not _consistent(anchor, p, amax)
            self._run_n = 1
        elif _consistent(prev, p, amax):
            self._run_n += 1
        else:
            self._run_n = 1
        self._run_last = p

    def contradicted_reset_allowed(self) -> bool:
        """A reset to a fix the INS contradicts: only after ``reset_confirm_fixes``
        consecutive rejected fixes that agree with each other and with the fused track."""
        return not self._run_broken and self._run_n >= self.cfg.reset_confirm_fixes

    def on_reset(self, part: str, time_us: int) -> None:
        """The filter reset ``part`` to the fix."""
        self._rejected_since_us[part] = None
        self.last_fused_us = time_us
        if part == "pos":
            self.reacquiring = self._after_true_outage = False


class FixUpdate(NamedTuple):
    """The outcome of one GNSS position or velocity update."""

    accepted: bool
    """The gate accepted it (it was fused)."""
    innovation: list[float]
    """INS minus the fix as received, NED (position m without the bias estimate; velocity m/s,
    NaN down when the receiver reports no vertical velocity)."""


class GnssAiding:
    """GNSS aiding of :class:`fusion.filter.NavFilter`: quality checks, control and the
    position and velocity updates of a fix.

    Parameters
    ----------
    cfg : GnssTuning
    layout : StateLayout
    counters : HealthCounters
        Where fixes are counted (``gnss_*``).
    update : Update
        The filter's shared measurement update.
    """

    def __init__(
        self, cfg: GnssTuning, layout: StateLayout, counters: HealthCounters, update: Update
    ) -> None:
        self.cfg = cfg
        self.layout = layout
        self.control = GnssControl(cfg)
        self.gate = kalman.chi2_gate(3, cfg.gate_probability)
        self._c = counters
        self._update = update
        self._max_delay_us = round(cfg.max_delay_s * 1e6)

    def usable(self, fix: GnssFix) -> bool:
        """Quality checks (:func:`fix_quality`); a failing fix is counted and restarts the
        control's count of consecutive good fixes."""
        try:
            reason = fix_quality(fix, self.cfg)
        except (TypeError, ValueError, AttributeError):
            reason = "invalid"
        if reason is None:
            return True
        c = self._c
        if reason == "no_fix":
            c.gnss_no_fix += 1
        elif reason == "invalid":
            c.gnss_invalid += 1
        else:
            c.gnss_inaccurate += 1
        self.control.on_bad_fix()
        return False

    def admit(self, time_us: int, now_us: int, past: InsState | None) -> InsState | None:
        """Whether a good fix of ``time_us`` is fused now (at INS time ``now_us``).

        Parameters
        ----------
        time_us, now_us : int
        past : InsState or None
            The INS at the fix's time of validity (``None``: older than the history).

        Returns
        -------
        InsState or None
            ``past`` when the fix is to be fused; ``None`` when it is too old (counted) or
            the control holds it back (re-acquisition).
        """
        if past is None or now_us - time_us > self._max_delay_us:
            self._c.gnss_too_old += 1
            return None
        if not self.control.on_good_fix(time_us, now_us):
            return None
        return past

    def fuse_position(
        self,
        fix: GnssFix,
        sigmas: tuple[float, float, float],
        past: InsState,
        delay_s: float,
        bias_ned_m: Sequence[float] | None,
        step_us: int,
        reset: Reset,
    ) -> FixUpdate | None:
        """The position update of a fix, or a reset to it when the control asks for one.

        Parameters
        ----------
        fix : GnssFix
        sigmas : 3 floats
            :func:`fix_sigmas` of the fix.
        past : InsState
            The INS at the fix's time of validity.
        delay_s : float
            Current time minus the fix's time of validity, s.
        bias_ned_m : 3 floats or None
            The GNSS position-bias estimate at the current time (layouts with the bias block).
        step_us : int
            Time of the stepped sample (labels the update).
        reset : callable ``(z, variances) -> None``
            Resets the INS position to the fix.

        Returns
        -------
        FixUpdate or None
            ``None`` when the fix makes no valid observation (counted as invalid).
        """
        cfg, lay, ctl = self.cfg, self.layout, self.control
        t = int(fix.time_us)
        sig_h, sig_v, _ = sigmas
        lat, lon, alt = float(fix.lat_rad), float(fix.lon_rad), float(fix.alt_msl_m)
        w_h, w_v = white_position_sigmas(sig_h, sig_v, cfg, lay)
        obs = position_model(
            lay, past, lat, lon, alt, w_h, w_v, cfg.lever_arm_b_m, delay_s,
            None if bias_ned_m is None else (bias_ned_m[0], bias_ned_m[1], bias_ned_m[2]),
        )  # fmt: skip
        if obs is None:
            self._c.gnss_invalid += 1
            return None
        res = self._update(obs, self.gate, AidSource.GNSS_POS, step_us)
        ok = res.test_ratio <= 1.0
        ctl.on_position_result(fix, sigmas, ok)
        # the bridge learns the INS minus the fix as received (without the bias estimate)
        z_pos = obs.z if bias_ned_m is None else obs.z - np.array(bias_ned_m)
        if not ok and ctl.on_result("pos", t, False):
            if self._reset_bounded(obs, res):
                reset(obs.z, np.diag(obs.R))
                ctl.on_reset("pos", t)
                self._c.gnss_resets += 1
        elif ok:
            ctl.on_result("pos", t, True)
        return FixUpdate(ok, z_pos.tolist())

    def _reset_bounded(self, obs: Observation, res: kalman.Correction) -> bool:
        """A reset to this fix is allowed: the INS does not contradict it (every axis of the
        innovation within ``reset_sigma`` times the INS's sigma plus the fix's), or a run of
        consistent fixes confirms it (:meth:`GnssControl.contradicted_reset_allowed`);
        refused resets are counted in ``gnss_resets_refused``."""
        r = np.diag(obs.R)
        hph = np.maximum(np.diag(res.S) - r, 0.0)
        bound = self.cfg.reset_sigma * np.sqrt(hph) + np.sqrt(r)
        z = np.asarray(res.innovation)
        finite = np.isfinite(z)
        if np.all(np.abs(z[finite]) <= bound[finite]) or self.control.contradicted_reset_allowed():
            return True
        self._c.gnss_resets_refused += 1
        return False

    def fuse_velocity(
        self,
        fix: GnssFix,
        sigmas: tuple[float, float, float],
        past: InsState,
        omega_ib_b_rps: tuple[float, float, float],
        position: FixUpdate,
        step_us: int,
        reset: Reset,
    ) -> FixUpdate | None:
        """The velocity update of a fix (after its position update), or a reset to it when
        the control asks for one; counts the fix as fused (both accepted) or rejected.

        Parameters
        ----------
        fix : GnssFix
        sigmas : 3 floats
            :func:`fix_sigmas` of the fix.
        past : InsState
            The INS at the fix's time of validity (after the position update).
        omega_ib_b_rps : 3 floats
            Bias-corrected body rate, rad/s (for the lever-arm velocity).
        position : FixUpdate
            The fix's position update.
        step_us : int
            Time of the stepped sample.
        reset : callable ``(z, variances) -> None``
            Resets the INS velocity to the fix.

        Returns
        -------
        FixUpdate or None
            ``None`` when the fix makes no valid observation (counted as invalid).
        """
        cfg, ctl, c = self.cfg, self.control, self._c
        t = int(fix.time_us)
        v_fix = np.asarray(fix.v_ned_mps, dtype=float)
        obs = velocity_model(self.layout, past, omega_ib_b_rps, v_fix, sigmas[2], cfg.lever_arm_b_m)
        if obs is None:
            c.gnss_invalid += 1
            return None
        res = self._update(obs, self.gate, AidSource.GNSS_VEL, step_us)
        ok = res.test_ratio <= 1.0
        if not ok and ctl.on_result("vel", t, False):
            if self._reset_bounded(obs, res):
                reset(obs.z, np.diag(obs.R))
                ctl.on_reset("vel", t)
                c.gnss_resets += 1
        elif ok:
            ctl.on_result("vel", t, True)
        if position.accepted and ok:
            c.gnss_fused += 1
        else:
            c.gnss_rejected += 1
        zv = obs.z.tolist()
        if len(zv) == 2:  # vertical velocity not reported by the receiver
            zv.append(math.nan)
        return FixUpdate(ok, zv)
