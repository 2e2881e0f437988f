"""What a fused run collected: the estimate, truth and GNSS-fix tracks, and the collector.

The pipeline (:mod:`hil.pipeline`) feeds every decoded sample through the filter and a
:class:`Collector`; the scorer (``scenarios``) turns its tracks into metrics. These are the data
types that cross that boundary. Shared by ``hilnav replay``, ``run``, ``compare``, the live
service's scorecard and the benches.
"""

from __future__ import annotations

import io
import tempfile
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

import numpy as np
from numpy.typing import NDArray

from fusion import rotations
from fusion.estimate import Mode, NavEstimate
from fusion.filter import NavFilter
from hil.sample_clock import SampleClock
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


#: Objects held before they are compacted into one chunk of column arrays (~8 MB of
#: estimate objects at most; a chunk is ~2 MB of columns).
CHUNK_ROWS = 2048

_MODES = tuple(Mode)
_MODE_CODE = {m: i for i, m in enumerate(_MODES)}
_INITIALIZING = _MODE_CODE[Mode.INITIALIZING]


class ColumnChunks:
    """Named column arrays, appended a chunk at a time, kept in memory or spilled to a file.

    A chunk is a dict of arrays with the same first dimension (rows) and the same keys, in the
    same order, every time. In memory, every chunk is copied at once into one array per column
    that grows by doubling its capacity (the capacity not yet filled is never touched, so it
    takes no resident memory), and :meth:`columns` returns read-only views of the rows filled:
    the columns are held once, never as chunks *and* columns (an hour's ~160 MB would
    otherwise be twice that while the scorer reads them). With ``spill_dir`` every chunk is
    written at once to an anonymous temporary file in that folder (unlinked at creation:
    nothing is left behind, even after a crash), so what stays in memory is constant however
    long the run.

    Parameters
    ----------
    spill_dir : Path, optional
    """

    def __init__(self, spill_dir: Path | None = None) -> None:
        self.spill_dir = spill_dir
        self._keys: tuple[str, ...] | None = None
        self._held: dict[str, NDArray[Any]] = {}
        self._file: IO[bytes] | None = None
        self._n_chunks = 0
        self.rows = 0
        self.nbytes = 0
        """Bytes of the column arrays appended (in memory or on disk)."""

    def append(self, chunk: dict[str, NDArray[Any]]) -> None:
        keys = tuple(chunk)
        if self._keys is None:
            self._keys = keys
        elif keys != self._keys:
            raise ValueError(f"chunk columns {keys} differ from the first chunk's {self._keys}")
        n = len(chunk[keys[0]])
        self.nbytes += sum(a.nbytes for a in chunk.values())
        self._n_chunks += 1
        if self.spill_dir is None:
            self._hold(chunk, n)
            self.rows += n
            return
        self.rows += n
        if self._file is None:
            self.spill_dir.mkdir(parents=True, exist_ok=True)
            self._file = tempfile.TemporaryFile(dir=self.spill_dir, prefix=".hilnav-tracks-")
        for key in keys:
            np.save(self._file, chunk[key], allow_pickle=False)

    def _hold(self, chunk: dict[str, NDArray[Any]], n: int) -> None:
        """Copy ``chunk`` behind the rows held, doubling the capacity when it is full (views
        handed out before keep the old arrays, unchanged)."""
        end = self.rows + n
        for k, a in chunk.items():
            held = self._held.get(k)
            if held is None or held.shape[0] < end:
                grown = np.empty((max(end, 2 * (0 if held is None else held.shape[0])),
                                  *a.shape[1:]), dtype=a.dtype)
                if held is not None:
                    grown[:self.rows] = held[:self.rows]
                self._held[k] = held = grown
            held[self.rows:end] = a

    def _chunks(self) -> Iterator[dict[str, NDArray[Any]]]:
        assert self._keys is not None and self._file is not None
        self._file.flush()
        self._file.seek(0)
        try:
            for _ in range(self._n_chunks):
                yield {k: np.load(self._file, allow_pickle=False) for k in self._keys}
        finally:
            self._file.seek(0, io.SEEK_END)

    def columns(self) -> dict[str, NDArray[Any]]:
        """Every column, the chunks in order; empty dict when there is nothing. In memory:
        read-only views of the columns held (no copy). Spilled: each column is allocated once
        at its full length and filled chunk by chunk from the file, so reading back a spilled
        hour needs the columns' size, not twice that."""
        if self._keys is None:
            return {}
        if self._file is None:
            out = {k: a[:self.rows] for k, a in self._held.items()}
            for a in out.values():
                a.flags.writeable = False  # shared with the store
            return out
        out = {}
        start = 0
        for chunk in self._chunks():
            n = len(next(iter(chunk.values())))
            for k, a in chunk.items():
                if k not in out:
                    out[k] = np.empty((self.rows, *a.shape[1:]), dtype=a.dtype)
                out[k][start:start + n] = a
            start += n
        return out

    def close(self) -> None:
        if self._file is not None:
            self._file.close()
            self._file = None


def _estimate_columns(est: list[NavEstimate]) -> dict[str, NDArray[Any]]:
    """The compact form of estimates: what the tracks and the health series are built from."""
    ratios = [e.test_ratios for e in est]
    counts = [(h.gnss_fused, h.gnss_rejected, h.gnss_resets,
               h.gnss_no_fix + h.gnss_invalid + h.gnss_inaccurate,
               h.baro_fused, h.baro_rejected, h.baro_resets, h.mag_fused, h.mag_rejected,
               h.airspeed_blockages) for h in (e.health for e in est)]  # fmt: skip
    nan9 = np.full((9, 9), np.nan)
    return {
        "time_us": np.array([e.time_us for e in est], dtype=np.int64),
        "mode": np.array([_MODE_CODE[e.mode] for e in est], dtype=np.uint8),
        "lat_rad": np.array([e.lat_rad for e in est], dtype=float),
        "lon_rad": np.array([e.lon_rad for e in est], dtype=float),
        "alt_m": np.array([e.alt_msl_m for e in est], dtype=float),
        "v_ned_mps": np.array([e.v_ned_mps for e in est], dtype=float).reshape(-1, 3),
        "euler_rad": np.array([e.euler_rad for e in est], dtype=float).reshape(-1, 3),
        "sigma": np.sqrt(np.maximum(
            np.array([e.P_diag[:9] for e in est], dtype=float).reshape(-1, 9), 0.0)),
        "has_cov": np.array([e.P_nav is not None for e in est], dtype=bool),
        "cov": np.array([nan9 if e.P_nav is None else e.P_nav for e in est],
                        dtype=float).reshape(-1, 9, 9),
        "ratios": np.array([(r.gnss_pos, r.gnss_vel, r.baro_hgt, r.mag_hdg) for r in ratios],
                           dtype=float).reshape(-1, 4),
        "counts": np.array(counts, dtype=np.int64).reshape(-1, len(_COUNTERS)),
    }


def _truth_columns(truths: list[Truth]) -> dict[str, NDArray[Any]]:
    return {
        "time_us": np.array([s.time_us for s in truths], dtype=np.int64),
        "lat_rad": np.array([s.lat_rad for s in truths], dtype=float),
        "lon_rad": np.array([s.lon_rad for s in truths], dtype=float),
        "alt_m": np.array([s.alt_msl_m for s in truths], dtype=float),
        "v_ned_mps": np.array([s.v_ned_mps for s in truths], dtype=float).reshape(-1, 3),
        "q_nb": np.array([s.q_nb for s in truths], dtype=float).reshape(-1, 4),
    }


def _track(c: dict[str, NDArray[Any]], euler_rad: FloatArray, **optional: Any) -> Track:
    """A Track of compact columns (``time_us``, ``lat_rad``, ``lon_rad``, ``alt_m``,
    ``v_ned_mps``) with ``euler_rad`` and the optional ``sigma`` / ``cov``."""
    return Track(time_s=c["time_us"].astype(float) * 1e-6, lat_rad=c["lat_rad"],
                 lon_rad=c["lon_rad"], alt_m=c["alt_m"], v_ned_mps=c["v_ned_mps"],
                 euler_rad=euler_rad, **optional)


def _truth_track(c: dict[str, NDArray[Any]]) -> Track:
    # one vectorised call: per-sample calls cost ~0.1 ms each
    return _track(c, rotations.quat_to_euler(c["q_nb"]))


def truth_track(truths: list[Truth]) -> Track:
    """Truth samples (in time order) as a :class:`Track`."""
    return _truth_track(_truth_columns(truths))


def _fix_columns(fixes: list[GnssFix]) -> dict[str, NDArray[Any]]:
    return {
        "time_us": np.array([f.time_us for f in fixes], dtype=np.int64),
        "lat_rad": np.array([f.lat_rad for f in fixes], dtype=float),
        "lon_rad": np.array([f.lon_rad for f in fixes], dtype=float),
        "alt_m": np.array([f.alt_msl_m for f in fixes], dtype=float),
    }


class _Stream:
    """One kind of collected object: held as objects until a chunk is full, then compacted."""

    def __init__(self, compact: Callable[[list[Any]], dict[str, NDArray[Any]]],
                 spill_dir: Path | None, chunk_rows: int) -> None:
        self._compact = compact
        self._chunk_rows = chunk_rows
        self.chunks = ColumnChunks(spill_dir)
        self.pending: list[Any] = []
        self._cache: tuple[int, dict[str, NDArray[Any]]] | None = None

    def __len__(self) -> int:
        return self.chunks.rows + len(self.pending)

    def add(self, obj: object) -> None:
        self.pending.append(obj)
        self.settle()

    def settle(self) -> None:
        """Compact the objects pending into one chunk once there are ``chunk_rows`` of them
        (the collector appends to :attr:`pending` directly and settles once per feed)."""
        if len(self.pending) >= self._chunk_rows:
            self.chunks.append(self._compact(self.pending))
            self.pending = []

    def columns(self) -> dict[str, NDArray[Any]]:
        """Every column (cached until the next object arrives); {} when empty. The objects
        pending are compacted into the store first (a short chunk)."""
        n = len(self)
        if self._cache is None or self._cache[0] != n:
            if self.pending:
                self.chunks.append(self._compact(self.pending))
                self.pending = []
            cols = self.chunks.columns()
            for a in cols.values():
                a.flags.writeable = False  # shared by every track built from them
            self._cache = (n, cols)
        return self._cache[1]


@dataclass
class Collector:
    """Accumulates estimates, truth and GNSS fixes as the filter runs, in compact form.

    Feeding only appends each new object to a list (it runs at the sensor rates); at the end
    of a :meth:`feed` that brought a list to ``chunk_rows`` objects, the list is turned into
    column arrays at once (:class:`ColumnChunks`: per estimate its time, mode, position,
    velocity, attitude, the 1-sigma and full 9x9 covariance of the navigation errors, test
    ratios and counters, ~0.9 kB; per truth sample 88 bytes; per fix 32 bytes) and the objects
    are dropped. With ``spill_dir`` those chunks go to an anonymous file there, so a live run of
    any length holds at most one chunk of objects (plus those of the feed in progress: one
    frame's live, one lockstep batch's in :func:`hil.pipeline.fly`) in memory.
    ``keep_objects`` also keeps every object (:attr:`estimates`, :attr:`truths`,
    :attr:`fixes`) for tests and tools that want them.
    """

    keep_objects: bool = False
    spill_dir: Path | None = None
    chunk_rows: int = CHUNK_ROWS
    _est: _Stream = field(init=False, repr=False)
    _tru: _Stream = field(init=False, repr=False)
    _fix: _Stream = field(init=False, repr=False)
    _kept: tuple[list[NavEstimate], list[Truth], list[GnssFix]] = field(
        init=False, repr=False, default_factory=lambda: ([], [], []))
    _clock: SampleClock | None = field(init=False, repr=False, default=None)

    def __post_init__(self) -> None:
        if self.chunk_rows < 1:
            raise ValueError("chunk_rows must be >= 1")
        self._est = _Stream(_estimate_columns, self.spill_dir, self.chunk_rows)
        self._tru = _Stream(_truth_columns, self.spill_dir, self.chunk_rows)
        self._fix = _Stream(_fix_columns, self.spill_dir, self.chunk_rows)

    def feed(self, nav: NavFilter, items: Iterable[Sample | Truth]) -> list[NavEstimate]:
        """Step ``nav`` with the samples (truth is only collected); the new estimates.

        The objects are appended to their streams' pending lists in the loop and compacted
        once per call (:meth:`_Stream.settle`), also when the filter raises."""
        out: list[NavEstimate] = []
        clock = self._clock
        if clock is None:
            clock = self._clock = SampleClock(round(nav.config.imu.time_jump_s * 1e6))
        truths, fixes = self._tru.pending, self._fix.pending
        n_truths, n_fixes = len(truths), len(fixes)
        # bound once per call: this loop runs for every sample of a run
        offer, step, add_truth, add_fix = clock.offer, nav.step, truths.append, fixes.append
        try:
            for item in items:
                if isinstance(item, Truth):
                    offer(item.time_us, nav.time_us)
                    add_truth(item)
                    continue
                if isinstance(item, GnssFix) and item.fix_type >= 3:
                    add_fix(item)
                estimates = step(item)
                if estimates:
                    out += estimates
                offer(item.time_us, nav.time_us)
        finally:
            self._est.pending += out
            if self.keep_objects:
                kept_est, kept_truths, kept_fixes = self._kept
                kept_est += out
                kept_truths += truths[n_truths:]
                kept_fixes += fixes[n_fixes:]
            for stream in (self._est, self._tru, self._fix):
                stream.settle()
        return out

    def _objects(self, which: int) -> list[Any]:
        if not self.keep_objects:
            raise ValueError("this collector keeps only the compact tracks; build it with "
                             "keep_objects=True to keep the objects")
        return self._kept[which]

    @property
    def estimates(self) -> list[NavEstimate]:
        """Every estimate (needs ``keep_objects``)."""
        return self._objects(0)

    @property
    def truths(self) -> list[Truth]:
        """Every truth sample, in arrival order (needs ``keep_objects``)."""
        return self._objects(1)

    @property
    def fixes(self) -> list[GnssFix]:
        """The 3-D fixes received, in arrival order (needs ``keep_objects``)."""
        return self._objects(2)

    @property
    def last_time_us(self) -> int:
        """The newest sample time of the run, us, not counting stamps the filter's clock
        refused (:class:`hil.sample_clock.SampleClock`); 0 before any sample."""
        return max(0, self._clock.latest_us) if self._clock is not None else 0

    @property
    def n_estimates(self) -> int:
        """Estimates collected (initialising ones included)."""
        return len(self._est)

    @property
    def n_truths(self) -> int:
        return len(self._tru)

    @property
    def n_fixes(self) -> int:
        """3-D fixes received."""
        return len(self._fix)

    @property
    def compact_nbytes(self) -> int:
        """Bytes of the compacted columns (in memory, or on disk with ``spill_dir``)."""
        return sum(s.chunks.nbytes for s in (self._est, self._tru, self._fix))

    @property
    def fix_times_us(self) -> NDArray[np.int64]:
        """Times of validity of the 3-D fixes received, in arrival order, us."""
        c = self._fix.columns()
        return c["time_us"] if c else np.zeros(0, dtype=np.int64)

    def close(self) -> None:
        """Close the spill files (their space is freed; the collector is empty afterwards)."""
        for s in (self._est, self._tru, self._fix):
            s.chunks.close()

    def _navigating(self) -> dict[str, NDArray[Any]]:
        c = self._est.columns()
        keep = c["mode"] != _INITIALIZING if c else np.zeros(0, dtype=bool)
        if not np.any(keep):
            raise ValueError("the filter produced no navigation estimate (no valid GNSS fix?)")
        if np.all(keep):
            return c  # the usual case: no copy of an hour's columns
        return {k: v[keep] for k, v in c.items()}

    def _truth_sorted(self) -> dict[str, NDArray[Any]]:
        if self.n_truths < 2:
            raise ValueError("the log holds no truth (HIL_STATE_QUATERNION) to score against")
        c = self._tru.columns()
        t = c["time_us"]
        if t.size < 2 or bool(np.all(t[1:] >= t[:-1])):
            return c  # the usual case: already in order, no copy of an hour's truth
        order = np.argsort(t, kind="stable")  # as sorted(): ties keep arrival order
        return {k: v[order] for k, v in c.items()}

    def end_s(self) -> float:
        """Where scoring ends: the earlier of the last navigation estimate and the last truth
        sample, s (the last times of :meth:`estimate_track` and :meth:`truth_track`)."""
        est = self._navigating()
        if self.n_truths < 2:
            raise ValueError("the log holds no truth (HIL_STATE_QUATERNION) to score against")
        last_truth_us = int(self._tru.columns()["time_us"].max())
        return min(float(est["time_us"][-1]) * 1e-6, float(last_truth_us) * 1e-6)

    def estimate_track(self) -> Track:
        c = self._navigating()
        return _track(c, c["euler_rad"], sigma=c["sigma"],
                      cov=c["cov"] if bool(np.all(c["has_cov"])) else None)

    def truth_track(self) -> Track:
        return _truth_track(self._truth_sorted())

    def modes(self) -> list[str]:
        """The mode of every estimate (initialising ones included), in order."""
        c = self._est.columns()
        return [] if not c else [str(_MODES[k]) for k in c["mode"]]

    def fix_track(self) -> Fixes:
        """The received 3-D fixes as arrays (time of validity, position)."""
        c = self._fix.columns()
        if not c:
            c = _fix_columns([])
        return Fixes(
            time_s=c["time_us"].astype(float) * 1e-6,
            lat_rad=c["lat_rad"],
            lon_rad=c["lon_rad"],
            alt_m=c["alt_m"],
        )

    def series(self) -> HealthSeries:
        """Mode, test ratios and counters at the times of :meth:`estimate_track`, with the fixes.

        Raises
        ------
        ValueError
            When the filter produced no navigation estimate.
        """
        c = self._navigating()
        ratios, counts = c["ratios"], c["counts"]
        fixes = self.fix_track()
        order = np.argsort(fixes.time_s, kind="stable")  # fixes arrive in time order, mostly
        return HealthSeries(
            time_s=c["time_us"].astype(float) * 1e-6,
            mode=np.array([str(_MODES[k]) for k in c["mode"]], dtype=np.str_),
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
