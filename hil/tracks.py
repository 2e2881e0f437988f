"""What a fused run collected: the estimate, truth and GNSS-fix tracks, and the collector.

The pipeline (:mod:`hil.pipeline`) feeds every decoded sample through the filter and a
:class:`Collector`; the scorer (``scenarios``) turns its tracks into metrics. These are the data
types that cross that boundary. Shared by ``hilnav replay``, ``run``, ``compare``, the live
service's scorecard and the benches.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any

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


#: Mode codes of the compact estimate rows (index into this tuple).
_MODES = ("initializing", "gnss", "free-inertial", "dead-reckoning", "bridging")
_MODE_CODE = {m: i for i, m in enumerate(_MODES)}

# Column layout of the compact rows (named once, as the error-state layout is).
_E_LAT, _E_LON, _E_ALT = 0, 1, 2
_E_V = slice(3, 6)
_E_EUL = slice(6, 9)
_E_SIG = slice(9, 18)
_E_COV = slice(18, 99)
_E_RAT = slice(99, 103)
EST_FLOAT_WIDTH = 103
"""float64 columns of one estimate row: lat, lon, alt, v_ned (3), euler (3), sigma (9),
cov (81, NaN when not reported), test ratios (4)."""
_I_TIME, _I_MODE, _I_HASCOV = 0, 1, 2
_I_CNT = slice(3, 3 + len(_COUNTERS))
EST_INT_WIDTH = 3 + len(_COUNTERS)
"""int64 columns of one estimate row: time_us, mode code, has-cov flag, counters (10)."""
TRUTH_WIDTH = 10
"""float64 columns of one truth row: lat, lon, alt, v_ned (3), q_nb (4)."""
FIX_WIDTH = 3
"""float64 columns of one fix row: lat, lon, alt."""


class RowStore:
    """A growing 2-D array of fixed-size rows, kept in preallocated chunks.

    Appending never copies what is stored (a full chunk is kept as is and a new one
    allocated), so memory grows by ``width * itemsize`` bytes per row plus at most one
    chunk of slack: the compact form of a recorded track, not one Python object per sample.

    Parameters
    ----------
    width : int
        Columns per row.
    dtype : numpy dtype
    chunk_rows : int
        Rows per chunk.
    """

    def __init__(self, width: int, dtype: type[np.generic], chunk_rows: int = 4096) -> None:
        if width < 1 or chunk_rows < 1:
            raise ValueError("width and chunk_rows must be >= 1")
        self.width = width
        self.dtype = np.dtype(dtype)
        self.chunk_rows = chunk_rows
        self._full: list[NDArray[Any]] = []
        self._cur: NDArray[Any] = np.empty((chunk_rows, width), dtype=self.dtype)
        self._n = 0

    def __len__(self) -> int:
        return len(self._full) * self.chunk_rows + self._n

    def next_row(self) -> NDArray[Any]:
        """A view of the next row, to be filled in place by the caller."""
        if self._n == self.chunk_rows:
            self._full.append(self._cur)
            self._cur = np.empty((self.chunk_rows, self.width), dtype=self.dtype)
            self._n = 0
        row = self._cur[self._n]
        self._n += 1
        return row

    def array(self) -> NDArray[Any]:
        """Every row, shape (len, width) (a copy)."""
        return np.concatenate([*self._full, self._cur[: self._n]], axis=0)

    @property
    def nbytes(self) -> int:
        """Bytes allocated for rows (stored and preallocated)."""
        return (len(self._full) + 1) * self.chunk_rows * self.width * self.dtype.itemsize


@dataclass
class Collector:
    """Accumulates estimates, truth and GNSS fixes as the filter runs, in compact form.

    Each estimate, truth sample and 3-D fix becomes one fixed-size row of numpy chunks
    (:class:`RowStore`: ``EST_FLOAT_WIDTH`` float64 + ``EST_INT_WIDTH`` int64 columns per
    estimate, ``TRUTH_WIDTH`` float64 + one int64 per truth sample, ``FIX_WIDTH`` float64 + one
    int64 per fix) holding exactly what the tracks and :meth:`series` are built from, so a
    long live run grows by those bytes per sample, not by Python objects. ``keep_objects``
    also keeps the objects themselves (:attr:`estimates`, :attr:`truths`, :attr:`fixes`) for
    tests and tools that want them.
    """

    keep_objects: bool = False
    estimates: list[NavEstimate] = field(default_factory=list)
    """The estimates (only with ``keep_objects``)."""
    truths: list[Truth] = field(default_factory=list)
    """The truth samples (only with ``keep_objects``)."""
    fixes: list[GnssFix] = field(default_factory=list)
    """The 3-D fixes received (only with ``keep_objects``)."""
    last_time_us: int = 0
    chunk_rows: int = 4096
    _est_f: RowStore = field(init=False, repr=False)
    _est_i: RowStore = field(init=False, repr=False)
    _tru_f: RowStore = field(init=False, repr=False)
    _tru_t: RowStore = field(init=False, repr=False)
    _fix_f: RowStore = field(init=False, repr=False)
    _fix_t: RowStore = field(init=False, repr=False)

    def __post_init__(self) -> None:
        c = self.chunk_rows
        self._est_f = RowStore(EST_FLOAT_WIDTH, np.float64, c)
        self._est_i = RowStore(EST_INT_WIDTH, np.int64, c)
        self._tru_f = RowStore(TRUTH_WIDTH, np.float64, c)
        self._tru_t = RowStore(1, np.int64, c)
        self._fix_f = RowStore(FIX_WIDTH, np.float64, max(1, c // 16))
        self._fix_t = RowStore(1, np.int64, max(1, c // 16))

    def feed(self, nav: NavFilter, items: Iterable[Sample | Truth]) -> list[NavEstimate]:
        """Step ``nav`` with the samples (truth is only collected); the new estimates."""
        out: list[NavEstimate] = []
        for item in items:
            self.last_time_us = max(self.last_time_us, item.time_us)
            if isinstance(item, Truth):
                self._add_truth(item)
                continue
            if isinstance(item, GnssFix) and item.fix_type >= 3:
                self._fix_t.next_row()[0] = item.time_us
                r = self._fix_f.next_row()
                r[0], r[1], r[2] = item.lat_rad, item.lon_rad, item.alt_msl_m
                if self.keep_objects:
                    self.fixes.append(item)
            new = nav.step(item)
            for e in new:
                self._add_estimate(e)
            out.extend(new)
        if self.keep_objects:
            self.estimates.extend(out)
        return out

    def _add_truth(self, s: Truth) -> None:
        self._tru_t.next_row()[0] = s.time_us
        r = self._tru_f.next_row()
        r[0], r[1], r[2] = s.lat_rad, s.lon_rad, s.alt_msl_m
        r[3:6] = s.v_ned_mps
        r[6:10] = s.q_nb
        if self.keep_objects:
            self.truths.append(s)

    def _add_estimate(self, e: NavEstimate) -> None:
        f = self._est_f.next_row()
        f[_E_LAT], f[_E_LON], f[_E_ALT] = e.lat_rad, e.lon_rad, e.alt_msl_m
        f[_E_V] = e.v_ned_mps
        f[_E_EUL] = e.euler_rad
        f[_E_SIG] = np.sqrt(np.maximum(e.P_diag[:9], 0.0))
        r = e.test_ratios
        f[_E_RAT] = (r.gnss_pos, r.gnss_vel, r.baro_hgt, r.mag_hdg)
        i = self._est_i.next_row()
        i[_I_TIME] = e.time_us
        i[_I_MODE] = _MODE_CODE[e.mode]
        if e.P_nav is None:
            f[_E_COV] = np.nan
            i[_I_HASCOV] = 0
        else:
            f[_E_COV] = np.ravel(e.P_nav)
            i[_I_HASCOV] = 1
        h = e.health
        i[_I_CNT] = (h.gnss_fused, h.gnss_rejected, h.gnss_resets,
                     h.gnss_no_fix + h.gnss_invalid + h.gnss_inaccurate,
                     h.baro_fused, h.baro_rejected, h.baro_resets, h.mag_fused, h.mag_rejected,
                     h.airspeed_blockages)  # fmt: skip

    @property
    def n_estimates(self) -> int:
        """Estimates collected (initialising ones included)."""
        return len(self._est_i)

    @property
    def n_truths(self) -> int:
        return len(self._tru_t)

    @property
    def nbytes(self) -> int:
        """Bytes allocated for the compact rows (the objects of ``keep_objects`` excluded)."""
        return sum(s.nbytes for s in (self._est_f, self._est_i, self._tru_f, self._tru_t,
                                      self._fix_f, self._fix_t))

    @property
    def fix_times_us(self) -> NDArray[np.int64]:
        """Times of validity of the 3-D fixes received, in arrival order, us."""
        return self._fix_t.array()[:, 0]

    def _navigating(self) -> tuple[FloatArray, NDArray[np.int64]]:
        f, i = self._est_f.array(), self._est_i.array()
        keep = i[:, _I_MODE] != _MODE_CODE["initializing"]
        if not np.any(keep):
            raise ValueError("the filter produced no navigation estimate (no valid GNSS fix?)")
        return f[keep], i[keep]

    def _truth_rows(self) -> tuple[FloatArray, NDArray[np.int64]]:
        if self.n_truths < 2:
            raise ValueError("the log holds no truth (HIL_STATE_QUATERNION) to score against")
        t = self._tru_t.array()[:, 0]
        order = np.argsort(t, kind="stable")  # as sorted(): equal times keep arrival order
        return self._tru_f.array()[order], t[order]

    def end_s(self) -> float:
        """Where scoring ends: the earlier of the last navigation estimate and the last truth
        sample, s (the last times of :meth:`estimate_track` and :meth:`truth_track`)."""
        _, i = self._navigating()
        if self.n_truths < 2:
            raise ValueError("the log holds no truth (HIL_STATE_QUATERNION) to score against")
        last_truth_us = int(self._tru_t.array()[:, 0].max())
        return min(float(i[-1, _I_TIME]) * 1e-6, float(last_truth_us) * 1e-6)

    def estimate_track(self) -> Track:
        f, i = self._navigating()
        has_cov = bool(np.all(i[:, _I_HASCOV] == 1))
        return Track(
            time_s=i[:, _I_TIME].astype(float) * 1e-6,
            lat_rad=f[:, _E_LAT].copy(),
            lon_rad=f[:, _E_LON].copy(),
            alt_m=f[:, _E_ALT].copy(),
            v_ned_mps=f[:, _E_V].copy(),
            euler_rad=f[:, _E_EUL].copy(),
            sigma=f[:, _E_SIG].copy(),
            cov=f[:, _E_COV].reshape(-1, 9, 9).copy() if has_cov else None,
        )

    def truth_track(self) -> Track:
        f, t = self._truth_rows()
        return Track(
            time_s=t.astype(float) * 1e-6,
            lat_rad=f[:, 0].copy(),
            lon_rad=f[:, 1].copy(),
            alt_m=f[:, 2].copy(),
            v_ned_mps=f[:, 3:6].copy(),
            # one vectorised call: per-sample calls cost ~0.1 ms each
            euler_rad=rotations.quat_to_euler(np.ascontiguousarray(f[:, 6:10])),
        )

    def modes(self) -> list[str]:
        return [_MODES[c] for c in self._est_i.array()[:, _I_MODE]]

    def fix_track(self) -> Fixes:
        """The received 3-D fixes as arrays (time of validity, position)."""
        f = self._fix_f.array()
        return Fixes(
            time_s=self._fix_t.array()[:, 0].astype(float) * 1e-6,
            lat_rad=f[:, 0].copy(),
            lon_rad=f[:, 1].copy(),
            alt_m=f[:, 2].copy(),
        )

    def series(self) -> HealthSeries:
        """Mode, test ratios and counters at the times of :meth:`estimate_track`, with the fixes.

        Raises
        ------
        ValueError
            When the filter produced no navigation estimate.
        """
        f, i = self._navigating()
        ratios = f[:, _E_RAT]
        counts = i[:, _I_CNT]
        fixes = self.fix_track()
        order = np.argsort(fixes.time_s, kind="stable")  # fixes arrive in time order, mostly
        return HealthSeries(
            time_s=i[:, _I_TIME].astype(float) * 1e-6,
            mode=np.array([_MODES[c] for c in i[:, _I_MODE]], dtype=np.str_),
            ratio_gnss_pos=ratios[:, 0].copy(),
            ratio_gnss_vel=ratios[:, 1].copy(),
            ratio_baro=ratios[:, 2].copy(),
            ratio_mag=ratios[:, 3].copy(),
            gnss_fused=counts[:, 0].copy(),
            gnss_rejected=counts[:, 1].copy(),
            gnss_resets=counts[:, 2].copy(),
            gnss_quality_rejected=counts[:, 3].copy(),
            baro_fused=counts[:, 4].copy(),
            baro_rejected=counts[:, 5].copy(),
            baro_resets=counts[:, 6].copy(),
            mag_fused=counts[:, 7].copy(),
            mag_rejected=counts[:, 8].copy(),
            airspeed_blockages=counts[:, 9].copy(),
            fixes=Fixes(fixes.time_s[order], fixes.lat_rad[order], fixes.lon_rad[order],
                        fixes.alt_m[order]),
        )
