"""Plots of a run: ground track estimate vs truth with the outage segments marked, errors vs
time with outage (and event) windows shaded and the filter's 3-sigma envelopes, and drift vs
time into each outage; plus the drift comparison of several methods for ``hilnav compare``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

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
    fig, ax = _subplots(figsize=(7, 7))
    ax.plot(e_t, n_t, color="k", lw=1.2, label=reference_label)
    ax.plot(e_e, n_e, color="tab:blue", lw=0.9, label="estimate")
    for i, w in enumerate(outages):
        m = w.mask(estimate.time_s)
        ax.plot(e_e[m], n_e[m], color="tab:red", lw=1.6,
                label="estimate during outage" if i == 0 else None)
        mt = w.mask(truth.time_s)
        if np.any(mt):
            ax.plot(e_t[mt], n_t[mt], color="tab:orange", lw=2.4, alpha=0.5,
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
    fig.tight_layout()
    fig.savefig(path, dpi=110)


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
    for row, (title, data, names, sig, col0, scale) in enumerate(groups):
        for k in range(3):
            ax = axes[row, k]
            ax.plot(t, data[:, k] * scale, lw=0.8, color="tab:blue", label="error")
            _shade(ax, outages, evs)
            if sig is not None:
                s3 = 3.0 * sig[:, col0 + k] * scale
                ax.fill_between(t, -s3, s3, color="tab:gray", alpha=0.25, label="±3σ")
            ax.set_title(f"{names[k]} {title}", fontsize=9)
            ax.grid(alpha=0.3)
    axes[0, 0].legend(loc="upper left", fontsize=8)
    for ax in axes[-1]:
        ax.set_xlabel("time (s)")
    fig.suptitle(f"estimate minus {reference_label}", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=100)


def plot_horizontal_vertical(err: Errors, outages: list[Window], path: Path, *,
                             events: Sequence[EventLike] = ()) -> None:
    """Horizontal error and height error vs time, outages (and events) shaded, with the
    filter's 99.73 % ("3-sigma") bounds: the horizontal one is the radius of
    :func:`scenarios.metrics.horizontal_bound_3sigma`, the vertical one ±3 s_D."""
    evs = _events(events)
    fig, (a1, a2) = _subplots(2, 1, figsize=(11, 6), sharex=True)
    a1.plot(err.time_s, err.horizontal_m, lw=0.9, label="horizontal error")
    if err.sigma is not None:
        a1.fill_between(err.time_s, 0.0, metrics.horizontal_bound_3sigma(err.sigma),
                        color="tab:gray", alpha=0.25, lw=0.0, label="3σ bound (99.73 %)")
    _shade(a1, outages, evs)
    a1.set_ylabel("horizontal error (m)")
    a1.set_ylim(bottom=0.0)
    a1.legend(loc="upper left", fontsize=8)
    a1.grid(alpha=0.3)
    a2.plot(err.time_s, -err.pos_ned_m[:, 2], lw=0.9, label="height error")
    if err.sigma is not None:
        s3 = 3.0 * err.sigma[:, 2]
        a2.fill_between(err.time_s, -s3, s3, color="tab:gray", alpha=0.25, lw=0.0, label="±3σ")
    _shade(a2, outages, evs)
    a2.set_ylabel("height error (m)")
    a2.set_xlabel("time (s)")
    a2.legend(loc="upper left", fontsize=8)
    a2.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=100)


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
    fig.tight_layout()
    fig.savefig(path, dpi=100)


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
    fig.tight_layout()
    fig.savefig(path, dpi=100)


def plot_side_by_side(truth: Track, hilnav: Track, hilnav_err: Errors, autopilot_track: Track,
                      autopilot_err: Errors, outages: list[Window], path: Path, *,
                      autopilot: str = "autopilot") -> None:
    """Truth, hilnav's estimate and the autopilot's through the same denial: the ground
    tracks (left), horizontal and height errors of both estimates vs time with the outages
    shaded (right)."""
    fig = Figure(figsize=(15, 7))
    grid = fig.add_gridspec(2, 2, width_ratios=(1.0, 1.4))
    ax_t = fig.add_subplot(grid[:, 0])
    lat0, lon0, h0 = truth.lat_rad[0], truth.lon_rad[0], truth.alt_m[0]
    for track, label, color, lw in ((truth, "truth", "k", 1.4), (hilnav, "hilnav", "tab:blue",
                                     0.9), (autopilot_track, autopilot, "tab:green", 0.9)):
        n, e = _local_ne(track, lat0, lon0, h0)
        ax_t.plot(e, n, color=color, lw=lw, label=label)
    ax_t.set_xlabel("east (m)")
    ax_t.set_ylabel("north (m)")
    ax_t.set_aspect("equal", adjustable="datalim")
    ax_t.grid(alpha=0.3)
    ax_t.legend(loc="best")
    ax_t.set_title("Ground track")
    a1 = fig.add_subplot(grid[0, 1])
    a2 = fig.add_subplot(grid[1, 1], sharex=a1)
    for err, label, color in ((hilnav_err, "hilnav", "tab:blue"),
                              (autopilot_err, autopilot, "tab:green")):
        a1.plot(err.time_s, err.horizontal_m, lw=0.9, color=color, label=label)
        a2.plot(err.time_s, -err.pos_ned_m[:, 2], lw=0.9, color=color, label=label)
    for ax, label in ((a1, "horizontal error (m)"), (a2, "height error (m)")):
        _shade(ax, outages)
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
        ax.legend(loc="upper left", fontsize=8)
    a1.set_ylim(bottom=0.0)
    a2.set_xlabel("time (s)")
    fig.suptitle(f"truth, hilnav and {autopilot} through the same GNSS denial", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=100)


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
