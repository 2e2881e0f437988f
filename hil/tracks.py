"""What a fused run collected: the estimate, truth and GNSS-fix tracks, and the collector.

The pipeline (:mod:`hil.pipeline`) feeds every decoded sample through the filter and a
:class:`Collector`; the scorer (``scenarios``) turns its tracks into metrics. These are the data
types that cross that boundary. Shared by ``hilnav replay``, ``run``, ``compare``, the live
service's scorecard and the benches.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from fusion import rotations
from fusion.estimate import NavEstimate
from fusion.filter import NavFilter
from sim.samples import GnssFix, Sample, Truth

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class Track:
    """A navigation solution or truth sampled at ``time_s``.

    Shapes: ``time_s`` (N,), ``lat_rad``/``lon_rad``/``alt_m`` (N,), ``v_ned_mps`` (N, 3),
    ``euler_rad`` (N, 3) roll/pitch/yaw. ``sigma`` (N, 9) is optional: 1-sigma of N/E/D position
    (m), N/E/D velocity (m/s) and attitude error (rad) as reported by the filter; its attitude
    error is the small rotation (tilt) about North / East / Down that takes the true attitude to
    the estimate (``fusion.error_model``), not a difference of Euler angles. ``cov``
    (N, 9, 9) is optional: the full covariance of those nine errors.
    """

    time_s: FloatArray
    lat_rad: FloatArray
    lon_rad: FloatArray
    alt_m: FloatArray
    v_ned_mps: FloatArray
    euler_rad: FloatArray
    sigma: FloatArray | None = None
    cov: FloatArray | None = None


@dataclass(frozen=True)
class Fixes:
    """GNSS fixes as received (3-D fixes only), shapes (K,): time of validity, position."""

    time_s: FloatArray
    lat_rad: FloatArray
    lon_rad: FloatArray
    alt_m: FloatArray

    def __post_init__(self) -> None:
        _check_shapes(self, ("lat_rad", "lon_rad", "alt_m"), self.time_s.shape)


#: Sensor counters in :class:`HealthSeries` (cumulative, as in ``fusion.filter.Health``).
_COUNTERS = (
    "gnss_fused", "gnss_rejected", "gnss_resets", "gnss_quality_rejected",
    "baro_fused", "baro_rejected", "baro_resets", "mag_fused", "mag_rejected",
    "airspeed_blockages",
)  # fmt: skip
_RATIOS = ("ratio_gnss_pos", "ratio_gnss_vel", "ratio_baro", "ratio_mag")


@dataclass(frozen=True)
class HealthSeries:
    """The filter's mode, innovation test ratios and counters at each estimate, shapes (N,).

    Every field but ``time_s`` is optional (``None`` = not collected); detection uses what is
    there. Counters are cumulative since the filter started (``fusion.filter.Health``); test
    ratios are the last test's normalised innovation over its gate (> 1 = rejected, NaN before
    the first test), so a ratio is *fresh* at a sample only where it changed.

    Attributes
    ----------
    time_s : ndarray, shape (N,)
    mode : ndarray of str, shape (N,)
        ``"gnss"``, ``"free-inertial"``, ``"dead-reckoning"`` or ``"bridging"``.
    ratio_gnss_pos, ratio_gnss_vel, ratio_baro, ratio_mag : ndarray, shape (N,)
    gnss_fused, gnss_rejected, gnss_resets : ndarray of int, shape (N,)
    gnss_quality_rejected : ndarray of int, shape (N,)
        Fixes refused by the quality checks (no 3-D fix, invalid, inaccurate).
    baro_fused, baro_rejected, baro_resets, mag_fused, mag_rejected : ndarray of int, shape (N,)
    airspeed_blockages : ndarray of int, shape (N,)
        Pitot faults the filter declared (stuck, zero, persistently rejected).
    fixes : Fixes, optional
        The GNSS fixes received, to tell whether a fused fix was far from truth.
    """

    time_s: FloatArray
    mode: NDArray[np.str_] | None = None
    ratio_gnss_pos: FloatArray | None = None
    ratio_gnss_vel: FloatArray | None = None
    ratio_baro: FloatArray | None = None
    ratio_mag: FloatArray | None = None
    gnss_fused: NDArray[np.int64] | None = None
    gnss_rejected: NDArray[np.int64] | None = None
    gnss_resets: NDArray[np.int64] | None = None
    gnss_quality_rejected: NDArray[np.int64] | None = None
    baro_fused: NDArray[np.int64] | None = None
    baro_rejected: NDArray[np.int64] | None = None
    baro_resets: NDArray[np.int64] | None = None
    mag_fused: NDArray[np.int64] | None = None
    mag_rejected: NDArray[np.int64] | None = None
    airspeed_blockages: NDArray[np.int64] | None = None
    fixes: Fixes | None = None

    def __post_init__(self) -> None:
        if self.time_s.ndim != 1:
            raise ValueError("HealthSeries.time_s must be one-dimensional")
        if self.time_s.size > 1 and np.any(np.diff(self.time_s) < 0.0):
            raise ValueError("HealthSeries.time_s must be non-decreasing")
        _check_shapes(self, ("mode", *_RATIOS, *_COUNTERS), self.time_s.shape)


def _check_shapes(obj: object, names: tuple[str, ...], shape: tuple[int, ...]) -> None:
    for name in names:
        a = getattr(obj, name)
        if a is not None and np.shape(a) != shape:
            raise ValueError(
                f"{type(obj).__name__}.{name} has shape {np.shape(a)}, time_s has {shape}")


@dataclass
class Collector:
    """Accumulates estimates, truth and GNSS fixes as the filter runs.

    Nothing is computed while feeding (it runs at the sensor rates): the estimates already
    carry the mode, test ratios and counters, and :meth:`series` turns them into arrays once.
    """

    estimates: list[NavEstimate] = field(default_factory=list)
    truths: list[Truth] = field(default_factory=list)
    fix_times_us: list[int] = field(default_factory=list)
    fixes: list[GnssFix] = field(default_factory=list)
    """The 3-D fixes received (same order as ``fix_times_us``)."""
    last_time_us: int = 0

    def feed(self, nav: NavFilter, items: Iterable[Sample | Truth]) -> None:
        for item in items:
            self.last_time_us = max(self.last_time_us, item.time_us)
            if isinstance(item, Truth):
                self.truths.append(item)
                continue
            if isinstance(item, GnssFix) and item.fix_type >= 3:
                self.fix_times_us.append(item.time_us)
                self.fixes.append(item)
            self.estimates.extend(nav.step(item))

    def _navigating(self) -> list[NavEstimate]:
        est = [e for e in self.estimates if e.mode != "initializing"]
        if not est:
            raise ValueError("the filter produced no navigation estimate (no valid GNSS fix?)")
        return est

    def end_s(self) -> float:
        """Where scoring ends: the earlier of the last navigation estimate and the last truth
        sample, s (the last times of :meth:`estimate_track` and :meth:`truth_track`)."""
        est = self._navigating()
        if len(self.truths) < 2:
            raise ValueError("the log holds no truth (HIL_STATE_QUATERNION) to score against")
        last_truth_us = max(s.time_us for s in self.truths)
        return min(float(est[-1].time_us) * 1e-6, float(last_truth_us) * 1e-6)

    def estimate_track(self) -> Track:
        est = self._navigating()
        sig = np.array([np.sqrt(np.maximum(e.P_diag[:9], 0.0)) for e in est])
        covs = [e.P_nav for e in est]
        cov = None if any(c is None for c in covs) else np.array(covs)
        return Track(
            time_s=np.array([e.time_us for e in est], dtype=float) * 1e-6,
            lat_rad=np.array([e.lat_rad for e in est]),
            lon_rad=np.array([e.lon_rad for e in est]),
            alt_m=np.array([e.alt_msl_m for e in est]),
            v_ned_mps=np.array([e.v_ned_mps for e in est]),
            euler_rad=np.array([e.euler_rad for e in est]),
            sigma=sig,
            cov=cov,
        )

    def truth_track(self) -> Track:
        if len(self.truths) < 2:
            raise ValueError("the log holds no truth (HIL_STATE_QUATERNION) to score against")
        tr = sorted(self.truths, key=lambda s: s.time_us)
        return Track(
            time_s=np.array([s.time_us for s in tr], dtype=float) * 1e-6,
            lat_rad=np.array([s.lat_rad for s in tr]),
            lon_rad=np.array([s.lon_rad for s in tr]),
            alt_m=np.array([s.alt_msl_m for s in tr]),
            v_ned_mps=np.array([s.v_ned_mps for s in tr]),
            # one vectorised call: per-sample calls cost ~0.1 ms each
            euler_rad=rotations.quat_to_euler(np.array([s.q_nb for s in tr], dtype=float)),
        )

    def modes(self) -> list[str]:
        return [e.mode for e in self.estimates]

    def fix_track(self) -> Fixes:
        """The received 3-D fixes as arrays (time of validity, position)."""
        fx = self.fixes
        return Fixes(
            time_s=np.array([f.time_us for f in fx], dtype=float) * 1e-6,
            lat_rad=np.array([f.lat_rad for f in fx], dtype=float),
            lon_rad=np.array([f.lon_rad for f in fx], dtype=float),
            alt_m=np.array([f.alt_msl_m for f in fx], dtype=float),
        )

    def series(self) -> HealthSeries:
        """Mode, test ratios and counters at the times of :meth:`estimate_track`, with the fixes.

        Raises
        ------
        ValueError
            When the filter produced no navigation estimate.
        """
        est = self._navigating()
        ratios = np.array(
            [(r.gnss_pos, r.gnss_vel, r.baro_hgt, r.mag_hdg)
             for r in (e.test_ratios for e in est)], dtype=float)  # fmt: skip
        counts = np.array(
            [(h.gnss_fused, h.gnss_rejected, h.gnss_resets,
              h.gnss_no_fix + h.gnss_invalid + h.gnss_inaccurate,
              h.baro_fused, h.baro_rejected, h.baro_resets, h.mag_fused, h.mag_rejected,
              h.airspeed_blockages)
             for h in (e.health for e in est)], dtype=np.int64)  # fmt: skip
        fixes = self.fix_track()
        order = np.argsort(fixes.time_s, kind="stable")  # fixes arrive in time order, mostly
        return HealthSeries(
            time_s=np.array([e.time_us for e in est], dtype=float) * 1e-6,
            mode=np.array([e.mode for e in est], dtype=np.str_),
            ratio_gnss_pos=ratios[:, 0],
            ratio_gnss_vel=ratios[:, 1],
            ratio_baro=ratios[:, 2],
            ratio_mag=ratios[:, 3],
            gnss_fused=counts[:, 0],
            gnss_rejected=counts[:, 1],
            gnss_resets=counts[:, 2],
            gnss_quality_rejected=counts[:, 3],
            baro_fused=counts[:, 4],
            baro_rejected=counts[:, 5],
            baro_resets=counts[:, 6],
            mag_fused=counts[:, 7],
            mag_rejected=counts[:, 8],
            airspeed_blockages=counts[:, 9],
            fixes=Fixes(fixes.time_s[order], fixes.lat_rad[order], fixes.lon_rad[order],
                        fixes.alt_m[order]),
        )
