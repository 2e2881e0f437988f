"""Magnetometer heading aiding: what makes yaw observable in straight flight (paper P3 fuses the
magnetometer in its EKF for the same reason).

*How* — :func:`heading_model`. The body field is rotated into NED with the estimated attitude,
``m^_n = C^_nb m_b`` (tilt compensation with the filter's own roll and pitch), and its heading
``atan2(m^_E, m^_N)`` is compared with the reference field's (the declination)::

    z = wrap(atan2(m^_E, m^_N) - atan2(m_ref_E, m_ref_N))

With ``C^_nb = (I + [phi×]) C_nb``, ``m^_n = (I + [phi×]) m_n`` and to first order
``z = phi_D - m_D (m_N phi_N + m_E phi_E) / (m_N^2 + m_E^2)``: mostly yaw error, plus the tilt
error through the (large, at mid latitudes) vertical field. The noise is a generous heading
sigma from the configuration; soft/hard-iron residuals are not modelled.

*When* — :class:`MagControl`: fuse at most ``fuse_rate_hz``; reference field
(:func:`reference_field_n`) from the configuration, from the World Magnetic Model at the
filter's position and the configured date (the default; re-evaluated every 500 m travelled),
or learned: once the filter's yaw sigma is below ``learn_yaw_sigma_rad`` (GNSS manoeuvres
made heading observable), the mean of ``C^_nb m_b`` over ``LEARN_SAMPLES`` samples (taken at
``learn_rate_hz``, faster than the heading is fused) becomes the reference.
Learning at the in-flight alignment itself would freeze the alignment's heading error (a
crabbing aircraft's track is not its heading) into the reference. With
``hard_iron_calibration`` the body-fixed offset and the Earth field are estimated together
(:class:`HardIronCalibrator`).

*Fusion step* — :class:`MagAiding`: a sample through the checks, the rate limit, the reference
learning and calibration, and the heading update, counted.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from fusion import kalman
from fusion.aiding import Observation, Update
from fusion.config import MagTuning
from fusion.estimate import AidSource, HealthCounters
from fusion.rotations import euler_from_quat, quat_to_dcm, wrap_pi
from fusion.samples import MagSample, as_vec3
from fusion.state_layout import StateLayout
from fusion.strapdown import InsState
from physconst.geomag import REEVALUATE_DISTANCE_M, magnetic_field_ned_t, moved_beyond

LEARN_SAMPLES = 10
#: Forgetting factor per calibration sample (at 5 Hz: a memory of ~10 minutes).
CAL_FORGET = 0.9997
#: Calibration samples between two solutions.
CAL_SOLVE_EVERY = 25
_HEADING_BINS = 12


def heading_model(
    layout: StateLayout,
    c_nb: NDArray[np.float64],
    field_b: NDArray[np.float64],
    reference_field_n: NDArray[np.float64],
    heading_noise_rad: float,
    min_horizontal_field: float = 0.0,
) -> Observation | None:
    """Magnetic heading observation.

    Parameters
    ----------
    layout : StateLayout
    c_nb : ndarray, shape (3, 3)
        Estimated attitude.
    field_b : ndarray, shape (3,)
        Measured field in body FRD (any unit, e.g. T).
    reference_field_n : ndarray, shape (3,)
        Earth field in NED, same unit.
    heading_noise_rad : float
        1-sigma, rad.
    min_horizontal_field : float
        Below this horizontal magnitude (same unit) heading is meaningless: returns ``None``.

    Returns
    -------
    Observation or None
    """
    m = c_nb @ np.asarray(field_b, dtype=float)
    if not np.all(np.isfinite(m)):
        return None
    mn, me, md = float(m[0]), float(m[1]), float(m[2])
    h2 = mn * mn + me * me
    ref = np.asarray(reference_field_n, dtype=float)
    if h2 <= min_horizontal_field**2 or h2 == 0.0 or float(ref[0] ** 2 + ref[1] ** 2) == 0.0:
        return None
    z = np.array([wrap_pi(math.atan2(me, mn) - math.atan2(float(ref[1]), float(ref[0])))])
    H = np.zeros((1, layout.n))
    a = layout.ATT
    H[0, a] = -md * mn / h2
    H[0, a + 1] = -md * me / h2
    H[0, a + 2] = 1.0
    return Observation(z, H, np.array([[heading_noise_rad**2]]))


def reference_field_n(
    cfg: MagTuning, lat_rad: float, lon_rad: float, alt_m: float
) -> NDArray[np.float64] | None:
    """The Earth field (NED, T) heading is measured against at a position: the configured
    field, the World Magnetic Model's at ``cfg.decimal_year`` (``reference="wmm"``), or
    ``None`` when it is to be learned in flight."""
    if cfg.reference_field_n_tesla is not None:
        return np.asarray(cfg.reference_field_n_tesla, dtype=float)
    if cfg.reference == "wmm":
        return np.array(magnetic_field_ned_t(lat_rad, lon_rad, alt_m, cfg.decimal_year).ned_t)
    return None


class MagControl:
    """When to fuse magnetometer heading; owns the (configured or learned) reference field.

    Parameters
    ----------
    cfg : MagTuning
    """

    def __init__(self, cfg: MagTuning) -> None:
        self.cfg = cfg
        self._period_us = round(1e6 / cfg.fuse_rate_hz)
        self._learn_period_us = round(1e6 / cfg.learn_rate_hz)
        self.last_fused_us: int | None = None
        self._last_attempt_us: int | None = None
        self._last_learn_us: int | None = None
        self.reference_n: NDArray[np.float64] | None = (
            None
            if cfg.reference_field_n_tesla is None
            else np.asarray(cfg.reference_field_n_tesla, dtype=float)
        )
        self.follows_model = cfg.reference_field_n_tesla is None and cfg.reference == "wmm"
        """The reference is the WMM's at the filter's position (:meth:`locate`)."""
        self._at = (math.nan, math.nan, math.nan)
        self._learn: list[NDArray[np.float64]] = []
        self.calibrator = (
            HardIronCalibrator(cfg.calibration_min_heading_span_rad,
                               cfg.calibration_hard_iron_sigma_tesla)
            if cfg.hard_iron_calibration else None
        )

    @property
    def calibrated(self) -> bool:
        """The hard-iron calibration has replaced the learned reference."""
        return self.calibrator is not None and self.calibrator.solved

    def offer_calibration(self, c_nb: NDArray[np.float64], field_b: NDArray[np.float64],
                          yaw_rad: float, yaw_sigma_rad: float) -> None:
        """Offer a (good-attitude, body-field) pair to the hard-iron calibration."""
        cal = self.calibrator
        if cal is None or yaw_sigma_rad > self.cfg.learn_yaw_sigma_rad:
            return
        cal.add(c_nb, field_b, yaw_rad)
        if cal.field_n is not None and self._learns_reference:
            self.reference_n = cal.field_n

    def corrected(self, field_b: NDArray[np.float64]) -> NDArray[np.float64]:
        """The body field minus the estimated hard-iron offset (unchanged before calibration)."""
        cal = self.calibrator
        if cal is None or cal.offset_b is None:
            return field_b
        return field_b - cal.offset_b

    def heading_noise_rad(self) -> float:
        """Heading sigma to fuse with: larger until the hard iron is calibrated."""
        if self.calibrator is None or self.calibrated:
            return self.cfg.heading_noise_rad
        return max(self.cfg.heading_noise_rad, self.cfg.uncalibrated_heading_noise_rad)

    @property
    def _learns_reference(self) -> bool:
        return self.cfg.reference_field_n_tesla is None and self.cfg.reference == "learned"

    @property
    def learned(self) -> bool:
        """The reference came from learning (not from the configuration or the WMM)."""
        return self._learns_reference and self.reference_n is not None

    def locate(self, lat_rad: float, lon_rad: float, alt_m: float) -> None:
        """The filter is here: with the WMM reference, the field is (re-)evaluated when the
        position moved more than ``REEVALUATE_DISTANCE_M`` since the last evaluation."""
        here = (lat_rad, lon_rad, alt_m)
        if self.follows_model and moved_beyond(self._at, here, REEVALUATE_DISTANCE_M):
            self._at = here
            self.reference_n = reference_field_n(self.cfg, lat_rad, lon_rad, alt_m)

    def due(self, time_us: int) -> bool:
        """Rate limit of the heading update (``fuse_rate_hz``): True when a sample at
        ``time_us`` should be fused."""
        if self._last_attempt_us is not None and time_us - self._last_attempt_us < self._period_us:
            return False
        self._last_attempt_us = time_us
        return True

    def learning_due(self, time_us: int) -> bool:
        """Rate limit of the reference learning and the hard-iron calibration
        (``learn_rate_hz``): True when a sample at ``time_us`` should feed them."""
        last = self._last_learn_us
        if last is not None and time_us - last < self._learn_period_us:
            return False
        self._last_learn_us = time_us
        return True

    def learn(self, field_n: NDArray[np.float64], yaw_sigma_rad: float) -> None:
        """Offer ``C^_nb m_b`` for the learned reference (used only when heading is good)."""
        if self.reference_n is not None or yaw_sigma_rad > self.cfg.learn_yaw_sigma_rad:
            return
        self._learn.append(np.asarray(field_n, dtype=float))
        if len(self._learn) >= LEARN_SAMPLES:
            self.reference_n = np.mean(self._learn, axis=0)
            self._learn.clear()

    def on_result(self, time_us: int, accepted: bool) -> None:
        """Record the gate's verdict."""
        if accepted:
            self.last_fused_us = time_us


class HardIronCalibrator:
    """Joint least-squares estimate of the Earth field (NED) and the hard-iron offset (body).

    Parameters
    ----------
    min_heading_span_rad : float
        Headings (in 30-degree bins) that must have been flown before :attr:`solved`.
    hard_iron_sigma : float
        Prior sigma of each offset component (same unit as the field).
    noise : float
        Field measurement sigma used to weight the prior (same unit).
    """

    def __init__(self, min_heading_span_rad: float, hard_iron_sigma: float,
                 noise: float = 0.3e-6) -> None:
        self._ata = np.zeros((6, 6))
        self._aty = np.zeros(6)
        self._bins = np.zeros(_HEADING_BINS, dtype=bool)
        self._need_bins = max(2, math.ceil(min_heading_span_rad / (2 * math.pi / _HEADING_BINS)))
        self._prior = (noise / hard_iron_sigma) ** 2
        self._count = 0
        self.field_n: NDArray[np.float64] | None = None
        self.offset_b: NDArray[np.float64] | None = None

    @property
    def solved(self) -> bool:
        return self.offset_b is not None

    def add(self, c_nb: NDArray[np.float64], field_b: NDArray[np.float64], yaw_rad: float) -> None:
        """One pair of a good attitude and the measured body field."""
        c_bn = np.asarray(c_nb, dtype=float).T
        a = np.hstack((c_bn, np.eye(3)))
        self._ata *= CAL_FORGET
        self._aty *= CAL_FORGET
        self._ata += a.T @ a
        self._aty += a.T @ np.asarray(field_b, dtype=float)
        self._bins[int((yaw_rad % (2 * math.pi)) / (2 * math.pi) * _HEADING_BINS)
                   % _HEADING_BINS] = True
        self._count += 1
        if self._count % CAL_SOLVE_EVERY == 0 and int(self._bins.sum()) >= self._need_bins:
            self._solve()

    def _solve(self) -> None:
        ata = self._ata.copy()
        ata[3:, 3:] += self._prior * np.eye(3) * max(1.0, float(np.trace(self._ata[:3, :3])) / 3)
        try:
            x = np.asarray(np.linalg.solve(ata, self._aty), dtype=np.float64)
        except np.linalg.LinAlgError:
            return
        if np.all(np.isfinite(x)):
            self.field_n = x[:3]
            self.offset_b = x[3:]


class MagAiding:
    """Magnetometer aiding of :class:`fusion.filter.NavFilter`: checks, control, reference and
    calibration, and the heading update.

    Parameters
    ----------
    cfg : MagTuning
    layout : StateLayout
    counters : HealthCounters
        Where samples are counted (``mag_*``).
    update : Update
        The filter's shared measurement update.
    """

    def __init__(
        self, cfg: MagTuning, layout: StateLayout, counters: HealthCounters, update: Update
    ) -> None:
        self.cfg = cfg
        self.layout = layout
        self.control = MagControl(cfg)
        self.gate = kalman.chi2_gate(1, cfg.gate_probability)
        self._c = counters
        self._update = update

    def field(self, s: MagSample) -> tuple[float, float, float] | None:
        """The sample's body field, or ``None`` (counted as invalid) when it is not three
        finite numbers."""
        # scalar checks, and the array only for a sample that is used (most are not due):
        # numpy's all(isfinite) on 3 values costs more than the rest of a skipped sample
        try:
            field = as_vec3(s.field_b_tesla)
        except (TypeError, ValueError, AttributeError):
            field = (math.nan, math.nan, math.nan)
        isfinite = math.isfinite
        if not (isfinite(field[0]) and isfinite(field[1]) and isfinite(field[2])):
            self._c.mag_invalid += 1
            return None
        return field

    def fuse(
        self, field: tuple[float, float, float], time_us: int, ins: InsState,
        yaw_sigma: Callable[[], float],
    ) -> None:  # fmt: skip
        """One valid sample at ``time_us``: rate limit, reference learning and hard-iron
        calibration while the heading is good, then the heading update.

        Parameters
        ----------
        field : 3 floats
            Body field, T.
        time_us : int
            The sample's time (also labels the update).
        ins : InsState
            The current INS.
        yaw_sigma : callable ``() -> float``
            The filter's current yaw sigma, rad (asked only when the reference or the
            calibration needs it).
        """
        ctl = self.control
        if ctl.follows_model:
            ctl.locate(ins.lat_rad, ins.lon_rad, ins.alt_msl_m)
        learning = (ctl.reference_n is None or ctl.calibrator is not None) and ctl.learning_due(
            time_us)
        fusing = ctl.reference_n is not None and ctl.due(time_us)
        if not (learning or fusing):
            return
        m = np.array(field)
        c_nb = quat_to_dcm(ins.q_nb)
        if learning:
            sigma = yaw_sigma()
            if ctl.reference_n is None:
                ctl.learn(c_nb @ m, sigma)
            ctl.offer_calibration(c_nb, m, euler_from_quat(ins.q_nb)[2], sigma)
        reference = ctl.reference_n  # the calibration may just have replaced it
        if not fusing or reference is None:
            return
        obs = heading_model(
            self.layout, c_nb, ctl.corrected(m), reference, ctl.heading_noise_rad(),
            self.cfg.min_horizontal_field_tesla,
        )  # fmt: skip
        c = self._c
        if obs is None:
            c.mag_invalid += 1
            return
        res = self._update(obs, self.gate, AidSource.MAG_HDG, time_us)
        ok = res.test_ratio <= 1.0
        ctl.on_result(time_us, ok)
        if ok:
            c.mag_fused += 1
        else:
            c.mag_rejected += 1
