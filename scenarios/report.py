"""Plots of a run: ground track estimate vs truth with the outage segments marked, errors vs
time with outage (and event) windows shaded and the filter's 3-sigma envelopes, and drift vs
time into each outage; plus the drift comparison of several methods for ``hilnav compare``.

Long runs are drawn from a subset of their samples that gives the same picture
(:func:`envelope_indices` for curves against time, :func:`path_indices` for ground tracks):
an hour at 50 Hz is 180,000 samples, a plot is ~1,000 pixels wide, and matplotlib would
otherwise hold every sample several times over while it draws.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, Protocol

import matplotlib as mpl
import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from fusion import earth
from hil.tracks import Track
from scenarios import metrics
from scenarios.event_metrics import EventWindow
from scenarios.metrics import Errors, Window

EventLike = EventWindow | Mapping[str, Any]


class UnaidedTracks(Protocol):
    """An autopilot's unaided flight (:class:`scenarios.unaided_baseline.UnaidedFlight`): its
    truth, and its estimate and errors when they were scored."""

    @property
    def truth(self) -> Track: ...

    @property
    def track(self) -> Track | None: ...

    @property
    def errors(self) -> Errors | None: ...


#: Time bins per pixel column of the figure in :func:`envelope_indices` (at least one bin per
#: pixel column of any axes in it).
BINS_PER_PIXEL = 2
#: Ground-track cells per pixel (:func:`path_indices`): a dropped sample is within half a pixel
#: of the drawn path.
CELLS_PER_PIXEL = 2


def envelope_indices(time_s: np.ndarray, *series: np.ndarray, bins: int) -> np.ndarray:
    """Indices of the samples that draw the same curves as all samples at ``bins`` columns.

    The time span is cut into ``bins`` equal bins; in each, the first and the last sample and
    the minimum and the maximum of every one of ``series`` are kept (the "M4" aggregation of
    Jugel et al., VLDB 2014), so no spike and no extreme is lost and every line drawn between
    neighbouring bins is there; non-finite samples are all kept (a gap stays a gap). With at
    least one bin per pixel column the picture is the same as the full curve's.

    Parameters
    ----------
    time_s : ndarray, shape (N,)
        Non-decreasing times (otherwise every index is returned).
    *series : ndarray, shape (N,)
        The values plotted against ``time_s`` (a curve, or both edges of a band).
    bins : int

    Returns
    -------
    ndarray of int, shape (M,)
        Increasing indices; ``arange(N)`` when ``N <= 4 * bins`` (nothing to gain).
    """
    if bins < 1:
        raise ValueError("bins must be >= 1")
    t = np.asarray(time_s, dtype=float)
    n = t.size
    span = float(t[-1] - t[0]) if n else 0.0
    if n <= 4 * bins or not (np.isfinite(span) and span > 0.0) or np.any(np.diff(t) < 0.0):
        return np.arange(n)
    b = np.minimum(((t - t[0]) * (bins / span)).astype(np.int64), bins - 1)
    starts = np.flatnonzero(np.r_[True, b[1:] != b[:-1]])
    counts = np.diff(np.r_[starts, n])
    keep = [starts, starts + counts - 1]
    for v in series:
        v = np.asarray(v, dtype=float)
        finite = np.isfinite(v)
        keep.append(np.flatnonzero(~finite))
        for reduce, fill in ((np.minimum, np.inf), (np.maximum, -np.inf)):
            w = np.where(finite, v, fill)
            extreme = np.repeat(reduce.reduceat(w, starts), counts)
            hits = np.flatnonzero(w == extreme)
            keep.append(hits[np.searchsorted(hits, starts)])  # the first extreme of each bin
    return np.unique(np.concatenate(keep))


def path_indices(x: np.ndarray, y: np.ndarray, cell: float) -> np.ndarray:
    """Indices of the samples that draw the same path ``(x, y)`` to within ``cell``.

    The plane is cut into square cells of side ``cell``; of every run of consecutive samples
    in the same cell the first and the last are kept (and the path's ends), so each dropped
    sample lies in the cell of a kept neighbour: the drawn path is within one cell of the
    full one. Non-finite samples are all kept.

    Returns
    -------
    ndarray of int, shape (M,)
        Increasing indices (all of them when ``cell`` is not positive and finite).
    """
    n = np.size(x)
    if (n < 3 or not (np.isfinite(cell) and cell > 0.0)
            or not (np.isfinite(x).any() and np.isfinite(y).any())):
        return np.arange(n)
    with np.errstate(invalid="ignore"):
        cx = np.floor((np.asarray(x) - np.nanmin(x)) / cell)
        cy = np.floor((np.asarray(y) - np.nanmin(y)) / cell)
    same = (cx[1:] == cx[:-1]) & (cy[1:] == cy[:-1])  # False where either is NaN
    moved = np.r_[True, ~same] | np.r_[~same, True]  # first or last of its run
    return np.flatnonzero(moved)


def _path_cell(fig: Figure, dpi: float, *xy: np.ndarray) -> float:
    """Data units of a :func:`path_indices` cell for an equal-aspect plot of ``xy`` arrays."""
    width_px = min(fig.get_figwidth(), fig.get_figheight()) * dpi
    extent = max((float(np.nanmax(a) - np.nanmin(a)) for a in xy if np.isfinite(a).any()),
                 default=0.0)  # (an all-NaN track, e.g. a log without positions: no extent)
    return extent / (CELLS_PER_PIXEL * width_px)


def _bins(fig: Figure, dpi: float) -> int:
    return int(BINS_PER_PIXEL * fig.get_figwidth() * dpi)


def _local_ne(track: Track, lat0: float, lon0: float, h0: float) -> tuple[np.ndarray, np.ndarray]:
    r_n, r_e = (float(r) for r in earth.principal_radii(lat0))
    north = (track.lat_rad - lat0) * (r_n + h0)
    east = (track.lon_rad - lon0) * (r_e + h0) * np.cos(lat0)
    return north, east


def _subplots(nrows: int = 1, ncols: int = 1, *, figsize: tuple[float, float],
              **kwargs: Any) -> tuple[Figure, Any]:
    """A figure and its axes made without pyplot: no global backend choice and no figure
    registry to close (``Figure.savefig`` renders PNG through the Agg canvas by file type)."""
    fig = Figure(figsize=figsize)
    return fig, fig.subplots(nrows, ncols, **kwargs)


def _save(fig: Figure, path: Path, *, dpi: float) -> None:
    """Lay ``fig`` out tightly once and write it to ``path``.

    ``Figure.tight_layout`` leaves a placeholder layout engine behind, and with any engine set
    ``savefig`` draws the whole figure once more, invisibly, before the draw that renders the
    file. The layout is already done, so the engine is removed first: the same pixels (the
    PNG bytes are identical) with one full draw of the figure fewer.
    """
    fig.tight_layout()
    fig.set_layout_engine(None)
    fig.savefig(path, dpi=dpi)


def _events(events: Sequence[EventLike]) -> list[EventWindow]:
    return [e if isinstance(e, EventWindow) else EventWindow.from_mapping(e) for e in events]


def _shade(ax: Axes, outages: list[Window], events: Sequence[EventWindow] = ()) -> None:
    for i, w in enumerate(outages):
        ax.axvspan(w.start_s, w.end_s, color="tab:red", alpha=0.12,
                   label="GNSS outage" if i == 0 else None)
    t_max = ax.dataLim.x1 if np.isfinite(ax.dataLim.x1) else None
    for i, e in enumerate(events):
        end = e.end_s if np.isfinite(e.end_s) or t_max is None else t_max
        ax.axvspan(e.start_s, end, facecolor="none", edgecolor="tab:orange", hatch="//",
                   alpha=0.5, lw=0.0, label="scenario event" if i == 0 else None)


def plot_ground_track(estimate: Track, truth: Track, outages: list[Window], path: Path, *,
                      reference_label: str = "truth") -> None:
    """Ground track of the estimate and of the reference (``reference_label``: "truth" for a
    simulation, the autopilot's estimate for a flight log)."""
    lat0, lon0, h0 = truth.lat_rad[0], truth.lon_rad[0], truth.alt_m[0]
    n_t, e_t = _local_ne(truth, lat0, lon0, h0)
    n_e, e_e = _local_ne(estimate, lat0, lon0, h0)
    dpi = 110
    fig, ax = _subplots(figsize=(7, 7))
    cell = _path_cell(fig, dpi, e_t, n_t, e_e, n_e)

    def draw(east: np.ndarray, north: np.ndarray, **kwargs: Any) -> None:
        k = path_indices(east, north, cell)
        ax.plot(east[k], north[k], **kwargs)

    draw(e_t, n_t, color="k", lw=1.2, label=reference_label)
    draw(e_e, n_e, color="tab:blue", lw=0.9, label="estimate")
    for i, w in enumerate(outages):
        m = w.mask(estimate.time_s)
        draw(e_e[m], n_e[m], color="tab:red", lw=1.6,
             label="estimate during outage" if i == 0 else None)
        mt = w.mask(truth.time_s)
        if np.any(mt):
            draw(e_t[mt], n_t[mt], color="tab:orange", lw=2.4, alpha=0.5,
                 label=f"{reference_label} during outage" if i == 0 else None)
            k0, k1 = np.flatnonzero(mt)[[0, -1]]
            ax.plot(e_t[k0], n_t[k0], "o", color="tab:red", ms=5,
                    label="outage start" if i == 0 else None)
            ax.plot(e_t[k1], n_t[k1], "s", mfc="none", color="tab:red", ms=6,
                    label="outage end" if i == 0 else None)
            ax.annotate(f"{i + 1}", (e_t[k0], n_t[k0]), textcoords="offset points",
                        xytext=(4, 4), fontsize=8, color="tab:red")
    ax.plot(e_t[0], n_t[0], "^", color="k", ms=6, label="start")
    ax.set_xlabel("east (m)")
    ax.set_ylabel("north (m)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(alpha=0.3)
    ax.legend(loc="best")
    ax.set_title("Ground track")
    _save(fig, path, dpi=dpi)


def plot_errors(err: Errors, outages: list[Window], path: Path, *,
                events: Sequence[EventLike] = (), reference_label: str = "truth") -> None:
    """Position, velocity and attitude errors (estimate minus ``reference_label``) per axis
    with the filter's ±3-sigma envelope."""
    evs = _events(events)
    fig, axes = _subplots(3, 3, figsize=(14, 9), sharex=True)
    # (title, errors, axis names, their 1-sigma (N, >=3) or None, first column, scale)
    pv = err.sigma
    groups = (
        ("position error (m)", err.pos_ned_m, ("north", "east", "down"), pv, 0, 1.0),
        ("velocity error (m/s)", err.vel_ned_mps, ("north", "east", "down"), pv, 3, 1.0),
        ("attitude error (deg)", err.att_rad, ("roll", "pitch", "yaw"), err.att_sigma_rad, 0,
         np.degrees(1.0)),
    )
    t = err.time_s
    bins = _bins(fig, 100)
    for row, (title, data, names, sig, col0, scale) in enumerate(groups):
        for k in range(3):
            ax = axes[row, k]
            y = data[:, k] * scale
            s3 = None if sig is None else 3.0 * sig[:, col0 + k] * scale
            i = envelope_indices(t, y, bins=bins) if s3 is None else envelope_indices(
                t, y, s3, -s3, bins=bins)
            ax.plot(t[i], y[i], lw=0.8, color="tab:blue", label="error")
            _shade(ax, outages, evs)
            if s3 is not None:
                ax.fill_between(t[i], -s3[i], s3[i], color="tab:gray", alpha=0.25,
                                label="±3σ")
            ax.set_title(f"{names[k]} {title}", fontsize=9)
            ax.grid(alpha=0.3)
    axes[0, 0].legend(loc="upper left", fontsize=8)
    for ax in axes[-1]:
        ax.set_xlabel("time (s)")
    fig.suptitle(f"estimate minus {reference_label}", fontsize=10)
    _save(fig, path, dpi=100)


def plot_horizontal_vertical(err: Errors, outages: list[Window], path: Path, *,
                             events: Sequence[EventLike] = ()) -> None:
    """Horizontal error and height error vs time, outages (and events) shaded, with the
    filter's 99.73 % ("3-sigma") bounds: the horizontal one is the radius of
    :func:`scenarios.metrics.horizontal_bound_3sigma`, the vertical one ±3 s_D."""
    evs = _events(events)
    fig, (a1, a2) = _subplots(2, 1, figsize=(11, 6), sharex=True)
    bins = _bins(fig, 100)
    t, h = err.time_s, err.horizontal_m
    bound = None if err.sigma is None else metrics.horizontal_bound_3sigma(err.sigma)
    i = envelope_indices(t, h, bins=bins) if bound is None else envelope_indices(
        t, h, bound, bins=bins)
    a1.plot(t[i], h[i], lw=0.9, label="horizontal error")
    if bound is not None:
        a1.fill_between(t[i], 0.0, bound[i], color="tab:gray", alpha=0.25, lw=0.0,
                        label="3σ bound (99.73 %)")
    _shade(a1, outages, evs)
    a1.set_ylabel("horizontal error (m)")
    a1.set_ylim(bottom=0.0)
    a1.legend(loc="upper left", fontsize=8)
    a1.grid(alpha=0.3)
    up = -err.pos_ned_m[:, 2]
    s3 = None if err.sigma is None else 3.0 * err.sigma[:, 2]
    i = envelope_indices(t, up, bins=bins) if s3 is None else envelope_indices(
        t, up, s3, -s3, bins=bins)
    a2.plot(t[i], up[i], lw=0.9, label="height error")
    if s3 is not None:
        a2.fill_between(t[i], -s3[i], s3[i], color="tab:gray", alpha=0.25, lw=0.0,
                        label="±3σ")
    _shade(a2, outages, evs)
    a2.set_ylabel("height error (m)")
    a2.set_xlabel("time (s)")
    a2.legend(loc="upper left", fontsize=8)
    a2.grid(alpha=0.3)
    _save(fig, path, dpi=100)


def plot_drift(err: Errors, outages: list[Window], path: Path) -> None:
    """Horizontal error vs time into each outage (one line per outage, its 3σ bound dashed)."""
    fig, ax = _subplots(figsize=(8, 5))
    colors = mpl.rcParams["axes.prop_cycle"].by_key()["color"]
    for i, w in enumerate(outages):
        m = w.mask(err.time_s)
        if not np.any(m):
            continue
        c = colors[i % len(colors)]
        tau = err.time_s[m] - w.start_s
        ax.plot(tau, err.horizontal_m[m], color=c, lw=1.1,
                label=f"outage {i + 1} ({w.start_s:.0f}-{w.end_s:.0f} s)")
        if err.sigma is not None:
            ax.plot(tau, metrics.horizontal_bound_3sigma(err.sigma[m]), "--", color=c, lw=0.7)
    if err.sigma is not None and outages:
        ax.plot([], [], "--", color="tab:gray", lw=0.7, label="3σ bound (99.73 %)")
    longest = max((w.end_s - w.start_s for w in outages), default=0.0)
    for s in metrics.ERROR_AT_S:
        if s <= longest:  # the scorecard's error-at times
            ax.axvline(s, color="k", lw=0.4, alpha=0.3)
    ax.set_xlabel("time into outage (s)")
    ax.set_ylabel("horizontal error (m)")
    ax.set_ylim(bottom=0.0)
    ax.set_xlim(left=0.0)
    ax.grid(alpha=0.3)
    ax.legend(loc="upper left", fontsize=8)
    ax.set_title("Drift during GNSS outages")
    _save(fig, path, dpi=100)


Curve = tuple[np.ndarray, np.ndarray]


def drift_curves(summary: Mapping[str, Any]) -> list[Curve]:
    """The outages' drift curves stored in a summary (``outages[i].drift``) as
    ``(tau_s, horizontal_m)`` arrays (null samples dropped)."""
    curves: list[Curve] = []
    for o in summary.get("outages") or []:
        d = o.get("drift") or {}
        vals = d.get("horizontal_m") or []
        step = float(d.get("step_s") or 1.0)
        h = np.array([np.nan if v is None else float(v) for v in vals], dtype=float)
        tau = np.arange(h.size, dtype=float) * step
        ok = np.isfinite(h)
        if np.any(ok):
            curves.append((tau[ok], h[ok]))
    return curves


def plot_drift_compare(
    curves: Mapping[str, Sequence[Curve]], path: Path, *, step_s: float = 1.0,
    title: str = "Drift during GNSS outages by method",
) -> None:
    """Several methods' drift: each outage (and seed) thin, the method's mean bold.

    Parameters
    ----------
    curves : mapping of method name to a list of (tau_s (M,), horizontal_m (M,))
        E.g. ``{m: [c for s in summaries[m] for c in drift_curves(s)]}``.
    path : Path
    step_s : float
        Grid of the mean curve, s.
    """
    fig, ax = _subplots(figsize=(8, 5))
    colors = mpl.rcParams["axes.prop_cycle"].by_key()["color"]
    for i, (name, rows) in enumerate(curves.items()):
        c = colors[i % len(colors)]
        rows = list(rows)
        for tau, h in rows:
            ax.plot(tau, h, color=c, lw=0.5, alpha=0.3)
        grid, mean, count = metrics.mean_drift_curve(rows, step_s=step_s)
        if grid.size:
            ax.plot(grid, mean, color=c, lw=2.0, label=f"{name} (mean of {int(count.max())})")
    ax.set_xlabel("time into outage (s)")
    ax.set_ylabel("horizontal error (m)")
    ax.set_ylim(bottom=0.0)
    ax.set_xlim(left=0.0)
    ax.grid(alpha=0.3)
    if curves:
        ax.legend(loc="upper left", fontsize=8)
    ax.set_title(title)
    _save(fig, path, dpi=100)


def plot_side_by_side(truth: Track, hilnav: Track, hilnav_err: Errors, autopilot_track: Track,
                      autopilot_err: Errors, outages: list[Window], path: Path, *,
                      autopilot: str = "autopilot", unaided: UnaidedTracks | None = None,
                      ) -> None:
    """Truth, hilnav's estimate and the autopilot's through the same denial: the ground
    tracks (left), horizontal and height errors of both estimates vs time with the outages
    shaded (right).

    ``unaided``: the autopilot's unaided flight of the same seed
    (:class:`scenarios.unaided_baseline.UnaidedFlight`: its truth, and its estimate and
    errors when scored); drawn as a fourth estimate (its errors against its own truth) and
    its truth dashed, the autopilot's estimate above then being the one aided by hilnav.
    """
    fig = Figure(figsize=(15, 7))
    grid = fig.add_gridspec(2, 2, width_ratios=(1.0, 1.4))
    ax_t = fig.add_subplot(grid[:, 0])
    lat0, lon0, h0 = truth.lat_rad[0], truth.lon_rad[0], truth.alt_m[0]
    other = unaided is not None and unaided.track is not None and unaided.errors is not None
    aided = f"{autopilot} aided by hilnav" if other else autopilot
    tracks: list[tuple[Track, str, str, float, str]] = [
        (truth, "truth", "k", 1.4, "-"), (hilnav, "hilnav", "tab:blue", 0.9, "-"),
        (autopilot_track, aided, "tab:green", 0.9, "-")]
    curves = [(hilnav_err, "hilnav", "tab:blue", 3.0), (autopilot_err, aided, "tab:green", 3.0)]
    if unaided is not None and unaided.track is not None and unaided.errors is not None:
        tracks += [(unaided.truth, "truth, unaided flight", "tab:gray", 1.0, "--"),
                   (unaided.track, f"{autopilot} unaided", "tab:red", 0.9, "-")]
        # beneath the others: its GNSS-on stretch often lies right on the aided one's
        curves.append((unaided.errors, f"{autopilot} unaided (its own flight)", "tab:red",
                       2.0))
    ne = [_local_ne(track, lat0, lon0, h0) for track, *_ in tracks]
    # the track panel is ~6.2 x 7 in, close to the 7 in _path_cell takes: cells ~half a pixel
    cell = _path_cell(fig, 100, *(a for n_e in ne for a in n_e))
    for (n, e), (_track, label, color, lw, style) in zip(ne, tracks, strict=True):
        k = path_indices(e, n, cell)
        ax_t.plot(e[k], n[k], style, color=color, lw=lw, label=label)
    ax_t.set_xlabel("east (m)")
    ax_t.set_ylabel("north (m)")
    ax_t.set_aspect("equal", adjustable="datalim")
    ax_t.grid(alpha=0.3)
    ax_t.legend(loc="best")
    ax_t.set_title("Ground track")
    a1 = fig.add_subplot(grid[0, 1])
    a2 = fig.add_subplot(grid[1, 1], sharex=a1)
    for err, label, color, z in curves:
        t, h, up = err.time_s, err.horizontal_m, -err.pos_ned_m[:, 2]
        i = envelope_indices(t, h, up, bins=_bins(fig, 100))
        a1.plot(t[i], h[i], lw=0.9, color=color, label=label, zorder=z)
        a2.plot(t[i], up[i], lw=0.9, color=color, label=label, zorder=z)
    for ax, label in ((a1, "horizontal error (m)"), (a2, "height error (m)")):
        _shade(ax, outages)
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
        ax.legend(loc="upper left", fontsize=8)
    a1.set_ylim(bottom=0.0)
    a2.set_xlabel("time (s)")
    title = (f"truth, hilnav, {autopilot} aided by hilnav and {autopilot} unaided (a second "
             "flight of the same seed)" if other else
             f"truth, hilnav and {autopilot} through the same GNSS denial")
    fig.suptitle(title, fontsize=10)
    _save(fig, path, dpi=100)


def write_plots(estimate: Track, truth: Track, err: Errors, outages: list[Window],
                out_dir: Path, *, events: Sequence[EventLike] = (),
                reference_label: str = "truth") -> list[Path]:
    """Write the run's plots into ``out_dir``; returns their paths. ``truth`` is the reference
    the errors are taken against, named ``reference_label`` in the plots.

    ``ground_track.png``, ``errors.png``, ``horizontal_vertical.png`` and, when there are
    outages, ``drift.png``.
    """
    paths = [out_dir / "ground_track.png", out_dir / "errors.png",
             out_dir / "horizontal_vertical.png"]
    plot_ground_track(estimate, truth, outages, paths[0], reference_label=reference_label)
    plot_errors(err, outages, paths[1], events=events, reference_label=reference_label)
    plot_horizontal_vertical(err, outages, paths[2], events=events)
    if outages:
        paths.append(out_dir / "drift.png")
        plot_drift(err, outages, paths[3])
    return paths
