"""Navigation error metrics: estimate vs truth, per GNSS outage and while GNSS is on.

Everything here is pure numpy on aligned arrays; the runners collect the arrays. Errors are
estimate − truth. Horizontal errors are metres on the local tangent plane (meridian and
transverse radii at the truth position), which is exact to well below a millimetre for the
errors of interest here.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from fusion import earth

FloatArray = NDArray[np.float64]

#: Seconds into an outage at which the horizontal error is reported.
ERROR_AT_S: tuple[int, ...] = (10, 30, 60, 120)


@dataclass(frozen=True)
class Track:
    """A navigation solution or truth sampled at ``time_s``.

    Shapes: ``time_s`` (N,), ``lat_rad``/``lon_rad``/``alt_m`` (N,), ``v_ned_mps`` (N, 3),
    ``euler_rad`` (N, 3) roll/pitch/yaw. ``sigma`` (N, 9) is optional: 1-sigma of N/E/D position
    (m), N/E/D velocity (m/s) and roll/pitch/yaw error (rad) as reported by the filter.
    """

    time_s: FloatArray
    lat_rad: FloatArray
    lon_rad: FloatArray
    alt_m: FloatArray
    v_ned_mps: FloatArray
    euler_rad: FloatArray
    sigma: FloatArray | None = None


@dataclass(frozen=True)
class Errors:
    """Estimate − truth at the estimate times (truth interpolated)."""

    time_s: FloatArray
    pos_ned_m: FloatArray  # (N, 3)
    vel_ned_mps: FloatArray  # (N, 3)
    att_rad: FloatArray  # (N, 3) roll, pitch, yaw (wrapped to ±pi)
    lat_deg: FloatArray
    lon_deg: FloatArray
    sigma: FloatArray | None = None

    @property
    def horizontal_m(self) -> FloatArray:
        return np.hypot(self.pos_ned_m[:, 0], self.pos_ned_m[:, 1])

    @property
    def vertical_m(self) -> FloatArray:
        return np.abs(self.pos_ned_m[:, 2])


@dataclass(frozen=True)
class Window:
    """A GNSS outage [start_s, end_s)."""

    start_s: float
    end_s: float

    def mask(self, time_s: FloatArray) -> NDArray[np.bool_]:
        return (time_s >= self.start_s) & (time_s < self.end_s)


def wrap_pi(angle: FloatArray) -> FloatArray:
    """Wrap angles to [-pi, pi)."""
    return (np.asarray(angle) + np.pi) % (2.0 * np.pi) - np.pi


def _interp_angle(t: FloatArray, tp: FloatArray, ang: FloatArray) -> FloatArray:
    return wrap_pi(np.interp(t, tp, np.unwrap(ang)))


def errors(estimate: Track, truth: Track) -> Errors:
    """Estimate − truth, truth linearly interpolated to the estimate times.

    Estimates outside the truth's time span are dropped (never extrapolated).
    """
    t = estimate.time_s
    keep = (t >= truth.time_s[0]) & (t <= truth.time_s[-1])
    t = t[keep]
    tp = truth.time_s
    lat_t = np.interp(t, tp, truth.lat_rad)
    lon_t = np.interp(t, tp, truth.lon_rad)
    alt_t = np.interp(t, tp, truth.alt_m)
    v_t = np.column_stack([np.interp(t, tp, truth.v_ned_mps[:, k]) for k in range(3)])
    att_t = np.column_stack([_interp_angle(t, tp, truth.euler_rad[:, k]) for k in range(3)])
    r_n, r_e = earth.principal_radii(lat_t)
    dlat = estimate.lat_rad[keep] - lat_t
    dlon = wrap_pi(estimate.lon_rad[keep] - lon_t)
    pos = np.column_stack(
        [
            dlat * (r_n + alt_t),
            dlon * (r_e + alt_t) * np.cos(lat_t),
            -(estimate.alt_m[keep] - alt_t),
        ]
    )
    return Errors(
        time_s=t,
        pos_ned_m=pos,
        vel_ned_mps=estimate.v_ned_mps[keep] - v_t,
        att_rad=wrap_pi(estimate.euler_rad[keep] - att_t),
        lat_deg=np.degrees(dlat),
        lon_deg=np.degrees(dlon),
        sigma=None if estimate.sigma is None else estimate.sigma[keep],
    )


def rms(x: FloatArray) -> float:
    x = np.asarray(x, dtype=float)
    return float(np.sqrt(np.mean(x * x))) if x.size else float("nan")


def outages_from_fix_times(
    fix_time_s: FloatArray, *, end_s: float, gap_s: float = 1.0
) -> list[Window]:
    """Outage windows from gaps between consecutive GNSS fixes longer than ``gap_s``.

    An outage starts at the last fix before the gap and ends at the first fix after it. A
    missing tail (no fix after ``fix_time_s[-1] + gap_s`` until ``end_s``) is an outage to
    ``end_s``.
    """
    ft = np.sort(np.asarray(fix_time_s, dtype=float))
    if ft.size == 0:
        return [Window(0.0, end_s)]
    gaps = np.flatnonzero(np.diff(ft) > gap_s)
    windows = [Window(float(ft[i]), float(ft[i + 1])) for i in gaps]
    if end_s - ft[-1] > gap_s:
        windows.append(Window(float(ft[-1]), float(end_s)))
    return windows


def cep(horizontal_m: FloatArray, q: float) -> float:
    """Circular error probable at quantile ``q`` (0.5 = CEP50) of horizontal errors."""
    h = np.asarray(horizontal_m, dtype=float)
    return float(np.quantile(h, q)) if h.size else float("nan")


def _error_at(err: Errors, t_s: float) -> float | None:
    if t_s < err.time_s[0] or t_s > err.time_s[-1]:
        return None
    return float(np.interp(t_s, err.time_s, err.horizontal_m))


@dataclass
class OutageMetrics:
    start_s: float
    end_s: float
    horizontal_rmse_m: float
    horizontal_max_m: float
    horizontal_error_m_at: dict[str, float | None]
    vertical_rmse_m: float
    cep50_m: float
    cep95_m: float
    rmse: dict[str, float]
    extra: dict[str, float] = field(default_factory=dict)

    def as_dict(self) -> dict[str, object]:
        return {
            "start_s": self.start_s,
            "end_s": self.end_s,
            "duration_s": self.end_s - self.start_s,
            "horizontal_rmse_m": self.horizontal_rmse_m,
            "horizontal_max_m": self.horizontal_max_m,
            "horizontal_error_m_at": self.horizontal_error_m_at,
            "vertical_rmse_m": self.vertical_rmse_m,
            "cep50_m": self.cep50_m,
            "cep95_m": self.cep95_m,
            "rmse": self.rmse,
            **self.extra,
        }


def outage_metrics(err: Errors, window: Window) -> OutageMetrics | None:
    """Metrics of one outage; ``None`` when no estimate falls inside it."""
    m = window.mask(err.time_s)
    if not np.any(m):
        return None
    sub = Errors(
        err.time_s[m], err.pos_ned_m[m], err.vel_ned_mps[m], err.att_rad[m],
        err.lat_deg[m], err.lon_deg[m], None if err.sigma is None else err.sigma[m],
    )
    h = sub.horizontal_m
    at: dict[str, float | None] = {}
    for s in ERROR_AT_S:
        t = window.start_s + s
        at[str(s)] = _error_at(sub, t) if t <= window.end_s else None
    return OutageMetrics(
        start_s=window.start_s,
        end_s=window.end_s,
        horizontal_rmse_m=rms(h),
        horizontal_max_m=float(np.max(h)),
        horizontal_error_m_at=at,
        vertical_rmse_m=rms(sub.pos_ned_m[:, 2]),
        cep50_m=cep(h, 0.5),
        cep95_m=cep(h, 0.95),
        rmse=component_rmse(sub),
    )


def component_rmse(err: Errors) -> dict[str, float]:
    """The papers' component RMSEs: lat/lon (deg), h (m), vN/vE/vD (m/s), horizontal (m)."""
    return {
        "lat_deg": rms(err.lat_deg),
        "lon_deg": rms(err.lon_deg),
        "h_m": rms(err.pos_ned_m[:, 2]),
        "vn_mps": rms(err.vel_ned_mps[:, 0]),
        "ve_mps": rms(err.vel_ned_mps[:, 1]),
        "vd_mps": rms(err.vel_ned_mps[:, 2]),
        "horizontal_m": rms(err.horizontal_m),
    }


def gnss_on_mask(
    time_s: FloatArray, outages: list[Window], *, settle_s: float
) -> NDArray[np.bool_]:
    """Samples with GNSS available, after ``settle_s`` from the start and from each outage end."""
    m = time_s >= time_s[0] + settle_s if time_s.size else np.zeros(0, bool)
    for w in outages:
        m &= ~((time_s >= w.start_s) & (time_s < w.end_s + settle_s))
    return m


def gnss_on_metrics(err: Errors, mask: NDArray[np.bool_]) -> dict[str, float]:
    """Accuracy while GNSS is aided (after convergence)."""
    if not np.any(mask):
        nan = float("nan")
        return dict.fromkeys(
            ("horizontal_rmse_m", "vertical_rmse_m", "roll_rmse_deg", "pitch_rmse_deg",
             "yaw_rmse_deg"), nan)
    att = np.degrees(err.att_rad[mask])
    return {
        "horizontal_rmse_m": rms(err.horizontal_m[mask]),
        "vertical_rmse_m": rms(err.pos_ned_m[mask, 2]),
        "roll_rmse_deg": rms(att[:, 0]),
        "pitch_rmse_deg": rms(att[:, 1]),
        "yaw_rmse_deg": rms(att[:, 2]),
    }


def consistency(err: Errors, mask: NDArray[np.bool_] | None = None) -> dict[str, float]:
    """Filter consistency from the reported 1-sigma (diagonal approximation of P).

    Returns the mean NEES of the 9 position/velocity/attitude errors (expected value 9 for a
    consistent filter with uncorrelated errors), ``rms(error/sigma)`` per group (expected 1)
    and the fraction of samples inside the 3-sigma bound per group.
    """
    if err.sigma is None:
        return {}
    e = np.column_stack([err.pos_ned_m, err.vel_ned_mps, err.att_rad])
    s = err.sigma
    if mask is not None:
        e, s = e[mask], s[mask]
    if e.shape[0] == 0:
        return {}
    z = e / np.maximum(s, 1e-12)
    out = {"nees_mean": float(np.mean(np.sum(z * z, axis=1))), "nees_dof": 9.0}
    for name, sl in (("pos", slice(0, 3)), ("vel", slice(3, 6)), ("att", slice(6, 9))):
        out[f"rms_z_{name}"] = rms(z[:, sl])
        out[f"within_3sigma_{name}"] = float(np.mean(np.all(np.abs(z[:, sl]) <= 3.0, axis=1)))
    return out
