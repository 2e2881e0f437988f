"""Plots of a run: ground track estimate vs truth, errors vs time with outages and 3-sigma."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from fusion import earth
from scenarios.metrics import Errors, Track, Window


def _local_ne(track: Track, lat0: float, lon0: float, h0: float) -> tuple[np.ndarray, np.ndarray]:
    r_n, r_e = (float(r) for r in earth.principal_radii(lat0))
    north = (track.lat_rad - lat0) * (r_n + h0)
    east = (track.lon_rad - lon0) * (r_e + h0) * np.cos(lat0)
    return north, east


def _shade(ax: plt.Axes, outages: list[Window]) -> None:
    for i, w in enumerate(outages):
        ax.axvspan(w.start_s, w.end_s, color="tab:red", alpha=0.12,
                   label="GNSS outage" if i == 0 else None)


def plot_ground_track(estimate: Track, truth: Track, outages: list[Window], path: Path) -> None:
    lat0, lon0, h0 = truth.lat_rad[0], truth.lon_rad[0], truth.alt_m[0]
    n_t, e_t = _local_ne(truth, lat0, lon0, h0)
    n_e, e_e = _local_ne(estimate, lat0, lon0, h0)
    fig, ax = plt.subplots(figsize=(7, 7))
    ax.plot(e_t, n_t, color="k", lw=1.2, label="truth")
    ax.plot(e_e, n_e, color="tab:blue", lw=0.9, label="estimate")
    for i, w in enumerate(outages):
        m = w.mask(estimate.time_s)
        ax.plot(e_e[m], n_e[m], color="tab:red", lw=1.6,
                label="estimate during outage" if i == 0 else None)
    ax.set_xlabel("east (m)")
    ax.set_ylabel("north (m)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(alpha=0.3)
    ax.legend(loc="best")
    ax.set_title("Ground track")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_errors(err: Errors, outages: list[Window], path: Path) -> None:
    """Position, velocity and attitude errors per axis with the filter's ±3-sigma envelope."""
    fig, axes = plt.subplots(3, 3, figsize=(14, 9), sharex=True)
    groups = (
        ("position error (m)", err.pos_ned_m, ("north", "east", "down"), 0, 1.0),
        ("velocity error (m/s)", err.vel_ned_mps, ("north", "east", "down"), 3, 1.0),
        ("attitude error (deg)", err.att_rad, ("roll", "pitch", "yaw"), 6, np.degrees(1.0)),
    )
    t = err.time_s
    for row, (title, data, names, col0, scale) in enumerate(groups):
        for k in range(3):
            ax = axes[row, k]
            _shade(ax, outages)
            ax.plot(t, data[:, k] * scale, lw=0.8, color="tab:blue", label="error")
            if err.sigma is not None:
                s3 = 3.0 * err.sigma[:, col0 + k] * scale
                ax.fill_between(t, -s3, s3, color="tab:gray", alpha=0.25, label="±3σ")
            ax.set_title(f"{names[k]} {title}", fontsize=9)
            ax.grid(alpha=0.3)
    axes[0, 0].legend(loc="upper left", fontsize=8)
    for ax in axes[-1]:
        ax.set_xlabel("time (s)")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def plot_horizontal_vertical(err: Errors, outages: list[Window], path: Path) -> None:
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(11, 6), sharex=True)
    _shade(a1, outages)
    a1.plot(err.time_s, err.horizontal_m, lw=0.9, label="horizontal error")
    if err.sigma is not None:
        a1.plot(err.time_s, 3.0 * np.hypot(err.sigma[:, 0], err.sigma[:, 1]), "--",
                color="tab:gray", lw=0.8, label="3σ (horizontal)")
    a1.set_ylabel("m")
    a1.legend(loc="upper left")
    a1.grid(alpha=0.3)
    _shade(a2, outages)
    a2.plot(err.time_s, -err.pos_ned_m[:, 2], lw=0.9, label="height error")
    if err.sigma is not None:
        s3 = 3.0 * err.sigma[:, 2]
        a2.fill_between(err.time_s, -s3, s3, color="tab:gray", alpha=0.25, label="±3σ")
    a2.set_ylabel("m")
    a2.set_xlabel("time (s)")
    a2.legend(loc="upper left")
    a2.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def write_plots(estimate: Track, truth: Track, err: Errors, outages: list[Window],
                out_dir: Path) -> list[Path]:
    paths = [out_dir / "ground_track.png", out_dir / "errors.png",
             out_dir / "horizontal_vertical.png"]
    plot_ground_track(estimate, truth, outages, paths[0])
    plot_errors(err, outages, paths[1])
    plot_horizontal_vertical(err, outages, paths[2])
    return paths
