"""Navigation error metrics: estimate vs truth, per GNSS outage and while GNSS is on.

Everything here is pure numpy on aligned arrays; the runners collect the arrays. Errors are
estimate − truth. Horizontal errors are metres on the local tangent plane (meridian and
transverse radii at the truth position), which is exact to well below a millimetre for the
errors of interest here.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from fusion import earth, rotations
from hil.tracks import Track

FloatArray = NDArray[np.float64]

#: Seconds into an outage at which the horizontal error is reported (300 and 900: the long
#: denials where air-data dead reckoning is judged; ``None`` in shorter outages).
ERROR_AT_S: tuple[int, ...] = (10, 30, 60, 120, 300, 900)


@dataclass(frozen=True)
class Errors:
    """Estimate − truth at the estimate times (truth interpolated).

    Attitude is given twice: ``att_rad``, the Euler-angle differences the accuracy metrics
    report (roll, pitch, yaw, wrapped to ±pi), and ``tilt_rad``, the error as the filter
    defines and reports its covariance (the small rotation about North / East / Down that takes
    the true attitude to the estimate). Consistency compares ``tilt_rad`` with ``sigma`` /
    ``cov``; a plot of ``att_rad`` uses ``att_sigma_rad``, the filter's attitude covariance
    mapped onto the Euler angles.
    """

    time_s: FloatArray
    pos_ned_m: FloatArray  # (N, 3)
    vel_ned_mps: FloatArray  # (N, 3)
    att_rad: FloatArray  # (N, 3) roll, pitch, yaw (wrapped to ±pi)
    lat_deg: FloatArray
    lon_deg: FloatArray
    sigma: FloatArray | None = None
    """(N, 9) 1-sigma of position, velocity and tilt, as the filter reports them."""
    tilt_rad: FloatArray | None = None
    """(N, 3) attitude error about North / East / Down, rad (None: not computed)."""
    cov: FloatArray | None = None
    """(N, 9, 9) the filter's covariance of position, velocity and tilt errors (None: not
    reported; consistency then uses the diagonal ``sigma``)."""
    att_sigma_rad: FloatArray | None = None
    """(N, 3) 1-sigma of the roll / pitch / yaw errors (``sigma`` / ``cov`` mapped)."""

    def select(self, mask: NDArray[np.bool_]) -> Errors:
        """The samples where ``mask`` holds."""

        def part(a: FloatArray | None) -> FloatArray | None:
            return None if a is None else a[mask]

        return Errors(
            self.time_s[mask], self.pos_ned_m[mask], self.vel_ned_mps[mask], self.att_rad[mask],
            self.lat_deg[mask], self.lon_deg[mask], part(self.sigma), part(self.tilt_rad),
            part(self.cov), part(self.att_sigma_rad),
        )  # fmt: skip

    def nav9(self) -> FloatArray:
        """(N, 9) position, velocity and attitude errors as the filter defines them (tilt
        when computed, the Euler differences otherwise)."""
        att = self.tilt_rad if self.tilt_rad is not None else self.att_rad
        return np.column_stack([self.pos_ned_m, self.vel_ned_mps, att])

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


def euler_jacobian(euler_rad: FloatArray) -> FloatArray:
    """(N, 3, 3) ``d(roll, pitch, yaw) / d(tilt)`` at the attitudes ``euler_rad`` (N, 3).

    A small rotation ``phi`` about the NED axes, ``C^ = (I + [phi×]) C``, changes the Euler
    angles by ``A^-1 phi`` where the columns of ``A`` are the rotation axes of roll (the body
    x axis), pitch (yaw-rotated East) and yaw (Down) in NED.
    """
    _, th, ps = euler_rad[:, 0], euler_rad[:, 1], euler_rad[:, 2]
    a = np.zeros((euler_rad.shape[0], 3, 3))
    a[:, 0, 0] = np.cos(ps) * np.cos(th)
    a[:, 1, 0] = np.sin(ps) * np.cos(th)
    a[:, 2, 0] = -np.sin(th)
    a[:, 0, 1] = -np.sin(ps)
    a[:, 1, 1] = np.cos(ps)
    a[:, 2, 2] = 1.0
    return np.asarray(np.linalg.inv(a), dtype=np.float64)


#: Samples per block of :func:`errors`: its per-sample temporaries (interpolated truth, the
#: 3x3 rotation matrices of the tilt, the Euler Jacobians; ~1 kB a sample) stay near 4 MB
#: however long the run, instead of ~150 MB for an hour at 50 Hz.
ERRORS_BLOCK_ROWS = 4096


def errors(estimate: Track, truth: Track, *, block_rows: int = ERRORS_BLOCK_ROWS) -> Errors:
    """Estimate − truth, truth linearly interpolated to the estimate times.

    Estimates outside the truth's time span are dropped (never extrapolated). Computed
    ``block_rows`` estimates at a time: every output sample depends only on its own estimate
    and on the truth (whose attitude is unwrapped once, whole), so the result is the same,
    bit for bit, whatever the block size, and only the outputs are full length.
    """
    if block_rows < 1:
        raise ValueError("block_rows must be >= 1")
    t_all = estimate.time_s
    kept = np.flatnonzero((t_all >= truth.time_s[0]) & (t_all <= truth.time_s[-1]))
    # the usual case, estimates in time order, keeps one run of them: slices (views), no copy
    # of an hour's 9x9 covariances; otherwise the kept rows are gathered
    run = kept.size == 0 or int(kept[-1]) - int(kept[0]) + 1 == kept.size
    keep: slice | NDArray[np.intp] = (
        slice(int(kept[0]), int(kept[-1]) + 1) if kept.size and run
        else slice(0, 0) if run else kept)  # fmt: skip
    t = t_all[keep]
    n = t.shape[0]
    att_unwrapped = [np.unwrap(truth.euler_rad[:, k]) for k in range(3)]
    sigma = None if estimate.sigma is None else estimate.sigma[keep]
    cov = None if estimate.cov is None else estimate.cov[keep]
    pos = np.empty((n, 3))
    vel = np.empty((n, 3))
    att = np.empty((n, 3))
    tilt = np.empty((n, 3))
    lat_deg = np.empty(n)
    lon_deg = np.empty(n)
    att_sigma = None if sigma is None else np.empty((n, 3))
    for a in range(0, n, block_rows):
        b = min(a + block_rows, n)
        sel = slice(keep.start + a, keep.start + b) if isinstance(keep, slice) else kept[a:b]
        _errors_block(estimate, truth, att_unwrapped, t[a:b], sel,
                      None if sigma is None else sigma[a:b], None if cov is None else cov[a:b],
                      (pos[a:b], vel[a:b], att[a:b], tilt[a:b], lat_deg[a:b], lon_deg[a:b],
                       None if att_sigma is None else att_sigma[a:b]))  # fmt: skip
    return Errors(time_s=t, pos_ned_m=pos, vel_ned_mps=vel, att_rad=att, lat_deg=lat_deg,
                  lon_deg=lon_deg, sigma=sigma, tilt_rad=tilt, cov=cov,
                  att_sigma_rad=att_sigma)


def _errors_block(
    estimate: Track, truth: Track, att_unwrapped: list[FloatArray], t: FloatArray,
    sel: slice | NDArray[np.intp], sigma: FloatArray | None, cov: FloatArray | None,
    out: tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray, FloatArray,
               FloatArray | None],
) -> None:
    """One block of :func:`errors`: estimates ``sel`` at times ``t``, written into ``out``
    (position, velocity, Euler and tilt errors, lat / lon in degrees, Euler 1-sigma)."""
    pos, vel, att, tilt, lat_deg, lon_deg, att_sigma = out
    tp = truth.time_s
    lat_t = np.interp(t, tp, truth.lat_rad)
    lon_t = np.interp(t, tp, truth.lon_rad)
    alt_t = np.interp(t, tp, truth.alt_m)
    v_t = np.column_stack([np.interp(t, tp, truth.v_ned_mps[:, k]) for k in range(3)])
    att_t = np.column_stack([wrap_pi(np.interp(t, tp, u)) for u in att_unwrapped])
    r_n, r_e = earth.principal_radii(lat_t)
    dlat = estimate.lat_rad[sel] - lat_t
    dlon = wrap_pi(estimate.lon_rad[sel] - lon_t)
    pos[:, 0] = dlat * (r_n + alt_t)
    pos[:, 1] = dlon * (r_e + alt_t) * np.cos(lat_t)
    pos[:, 2] = -(estimate.alt_m[sel] - alt_t)
    vel[:] = estimate.v_ned_mps[sel] - v_t
    euler_est = estimate.euler_rad[sel]
    att[:] = wrap_pi(euler_est - att_t)
    lat_deg[:] = np.degrees(dlat)
    lon_deg[:] = np.degrees(dlon)
    c_est = rotations.euler_to_dcm(euler_est)
    c_true = rotations.euler_to_dcm(att_t)
    tilt[:] = rotations.dcm_to_rotvec(c_est @ np.swapaxes(c_true, -1, -2))
    if sigma is not None and att_sigma is not None:
        jac = euler_jacobian(euler_est)
        p_att = (cov[:, 6:9, 6:9] if cov is not None
                 else sigma[:, 6:9, None] ** 2 * np.eye(3))  # fmt: skip
        p_eul = jac @ p_att @ np.swapaxes(jac, -1, -2)
        att_sigma[:] = np.sqrt(np.maximum(np.diagonal(p_eul, axis1=-2, axis2=-1), 0.0))


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


GNSS_DENIAL_EVENTS = frozenset({"gnss_outage", "gnss_jamming"})
"""Scripted events during which GNSS is denied: the fix gaps inside one are one outage."""


@dataclass(frozen=True)
class Outage(Window):
    """A GNSS outage as a user counts it: one scripted denial, or gaps in quick succession,
    with the fix gaps it is made of (``gaps``; one gap for a plain outage)."""

    gaps: tuple[Window, ...] = ()


def merge_gaps(gaps: Sequence[Window], *, denied: Sequence[Window] = (),
               merge_s: float = 0.0) -> list[Outage]:
    """Outages from fix gaps: gaps that overlap the same scripted denial window (a jammer
    that lets a fix through now and then), or that are less than ``merge_s`` apart, form one
    outage from the first gap's start to the last one's end.

    Parameters
    ----------
    gaps : sequence of Window
        Fix gaps (:func:`outages_from_fix_times`).
    denied : sequence of Window
        Scripted GNSS-denial windows (events of :data:`GNSS_DENIAL_EVENTS`).
    merge_s : float
        Gaps closer than this (end of one to start of the next) merge, s.
    """
    def within(g: Window, d: Window) -> bool:
        return g.start_s <= d.end_s and g.end_s >= d.start_s

    out: list[Outage] = []
    for g in sorted(gaps, key=lambda w: w.start_s):
        if out:
            last = out[-1]
            same_event = any(within(last.gaps[-1], d) and within(g, d) for d in denied)
            if same_event or g.start_s - last.end_s < merge_s:
                out[-1] = Outage(last.start_s, max(last.end_s, g.end_s), (*last.gaps, g))
                continue
        out.append(Outage(g.start_s, g.end_s, (Window(g.start_s, g.end_s),)))
    return out


def cep(horizontal_m: FloatArray, q: float) -> float:
    """Circular error probable at quantile ``q`` (0.5 = CEP50) of horizontal errors."""
    h = np.asarray(horizontal_m, dtype=float)
    return float(np.quantile(h, q)) if h.size else float("nan")


def _error_at(err: Errors, t_s: float, values: FloatArray | None = None) -> float | None:
    if t_s < err.time_s[0] or t_s > err.time_s[-1]:
        return None
    v = err.horizontal_m if values is None else values
    return float(np.interp(t_s, err.time_s, v))


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
    vertical_max_m: float = float("nan")
    vertical_error_m_at: dict[str, float | None] = field(default_factory=dict)
    containment_3sigma: dict[str, float] = field(default_factory=dict)
    nees_mean: float = float("nan")
    reconverge_s: float | None = None
    """Seconds after the outage until the horizontal error settles (set by the summary, which
    knows the threshold and the next outage)."""
    drift_step_s: float = 1.0
    drift_m: list[float] = field(default_factory=list)
    """Horizontal error at ``0, drift_step_s, ...`` s into the outage (for drift plots)."""

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
            "vertical_max_m": self.vertical_max_m,
            "vertical_error_m_at": self.vertical_error_m_at,
            "containment_3sigma": self.containment_3sigma,
            "nees_mean": self.nees_mean,
            "reconverge_s": self.reconverge_s,
            "drift": {"step_s": self.drift_step_s, "horizontal_m": self.drift_m},
            **self.extra,
        }


def outage_metrics(
    err: Errors, window: Window, *, drift_step_s: float = 1.0
) -> OutageMetrics | None:
    """Metrics of one outage; ``None`` when no estimate falls inside it.

    Horizontal and vertical (absolute) error at :data:`ERROR_AT_S` s into the outage (``None``
    past its end), RMSE, max, CEP50/95, component RMSEs, 3-sigma containment, mean NEES and the
    drift curve sampled every ``drift_step_s``.
    """
    m = window.mask(err.time_s)
    if not np.any(m):
        return None
    sub = err.select(m)
    h = sub.horizontal_m
    v = sub.vertical_m
    at: dict[str, float | None] = {}
    at_v: dict[str, float | None] = {}
    for s in ERROR_AT_S:
        t = window.start_s + s
        at[str(s)] = _error_at(sub, t) if t <= window.end_s else None
        at_v[str(s)] = _error_at(sub, t, v) if t <= window.end_s else None
    tau, h_tau = drift_curve(sub, window)
    nees = consistency(sub).get("nees_mean", float("nan"))
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
        vertical_max_m=float(np.max(v)),
        vertical_error_m_at=at_v,
        containment_3sigma=containment_3sigma(sub),
        nees_mean=nees,
        drift_step_s=drift_step_s,
        drift_m=[float(x) for x in resample_curve(tau, h_tau, drift_step_s)],
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
    """Filter consistency: the errors against the covariance the filter reports for them.

    Returns the mean NEES of the 9 position / velocity / attitude (tilt) errors,
    ``e^T P^-1 e`` with the full 9x9 covariance when the filter reported it (``err.cov``; the
    diagonal otherwise), expected value 9 for a consistent filter; ``rms(error/sigma)`` per
    group (expected 1) and the fraction of samples inside the 3-sigma bound per group.
    """
    if err.sigma is None:
        return {}
    # only the errors and their sigmas are selected (copied), not every field; the
    # covariances are read by nees() a block at a time, the rows it needs
    if mask is None:
        e, s = err.nav9(), err.sigma.copy()
    else:
        att = err.tilt_rad if err.tilt_rad is not None else err.att_rad
        e = np.column_stack([err.pos_ned_m[mask], err.vel_ned_mps[mask], att[mask]])
        s = err.sigma[mask]
    if e.shape[0] == 0:
        return {}
    rows = None if mask is None else np.flatnonzero(mask)
    per_sample = nees(e, err.cov, rows) if err.cov is not None else None
    z = np.divide(e, np.maximum(s, 1e-12, out=s), out=e)  # e is not needed past here
    if per_sample is None:
        per_sample = np.sum(z * z, axis=1)
    out = {"nees_mean": float(np.mean(per_sample)), "nees_dof": 9.0}
    for name, sl in (("pos", slice(0, 3)), ("vel", slice(3, 6)), ("att", slice(6, 9))):
        out[f"rms_z_{name}"] = rms(z[:, sl])
        out[f"within_3sigma_{name}"] = float(np.mean(np.all(np.abs(z[:, sl]) <= 3.0, axis=1)))
    return out


#: Samples per block of :func:`nees`: its temporaries (about five copies of the block's
#: covariances) stay near 13 MB for 9x9 however long the run.
NEES_BLOCK_ROWS = 4096


def nees(e: FloatArray, cov: FloatArray, rows: NDArray[np.intp] | None = None) -> FloatArray:
    """``e_k^T P_k^-1 e_k`` per sample: ``e`` (N, m), ``cov`` (N, m, m), or with ``rows``
    (N,) ``cov`` (M, m, m) of which row ``rows[k]`` belongs to ``e[k]``.

    Computed :data:`NEES_BLOCK_ROWS` samples at a time (each sample's value does not depend
    on the others, so the result is the same as in one piece, at a fraction of the memory).
    A singular ``P_k`` (a state the filter holds exactly) gets the pseudo-inverse's value
    through a tiny relative ridge; a non-finite one yields NaN.
    """
    n = e.shape[0]
    if rows is not None and rows.shape != (n,):
        raise ValueError(f"rows must have shape ({n},), got {rows.shape}")
    if rows is None and cov.shape[0] != n:
        raise ValueError(f"cov has {cov.shape[0]} rows, e has {n}")
    out = np.full(n, np.nan)
    for a in range(0, n, NEES_BLOCK_ROWS):
        b = min(a + NEES_BLOCK_ROWS, n)
        block = cov[a:b] if rows is None else cov[rows[a:b]]
        out[a:b] = _nees_block(e[a:b], block)
    return out


def _nees_block(e: FloatArray, cov: FloatArray) -> FloatArray:
    ok = np.all(np.isfinite(cov), axis=(1, 2)) & np.all(np.isfinite(e), axis=1)
    out = np.full(e.shape[0], np.nan)
    if not np.any(ok):
        return out
    c, x = cov[ok], e[ok]
    # scale to unit diagonal: the solve is then as well conditioned as the correlations allow
    d = np.sqrt(np.maximum(np.diagonal(c, axis1=1, axis2=2), 1e-300))
    r = c / (d[:, :, None] * d[:, None, :]) + 1e-12 * np.eye(c.shape[1])
    y = x / d
    out[ok] = np.einsum("ni,ni->n", y, np.linalg.solve(r, y[:, :, None])[:, :, 0])
    return out


# ---------------------------------------------------------------------------------------------
# 3-sigma containment, drift curves, re-convergence
# ---------------------------------------------------------------------------------------------

#: Probability inside +-3 sigma of a 1-D Gaussian.
P_3SIGMA = 0.9973002039367398
#: Chi-square (2 dof) quantile at :data:`P_3SIGMA`: the horizontal "3-sigma" ellipse holds the
#: same probability as the 1-D +-3 sigma interval (a plain 3-sigma circle would hold only 98.9 %).
CHI2_2DOF_3SIGMA = 11.829158081900795


def containment_3sigma(err: Errors, mask: NDArray[np.bool_] | None = None) -> dict[str, float]:
    """Fraction of samples inside the filter's 3-sigma bound, horizontally and vertically.

    Horizontal: ``(e_N/s_N)^2 + (e_E/s_E)^2 <= CHI2_2DOF_3SIGMA`` (the 99.73 % ellipse of the
    reported diagonal covariance); vertical: ``|e_D| <= 3 s_D``. A consistent filter scores
    about 0.997 on both.

    Parameters
    ----------
    err : Errors
        With ``sigma`` (N, 9); without it both values are NaN.
    mask : ndarray of bool, shape (N,), optional
        Samples to count (all by default).

    Returns
    -------
    dict
        ``{"horizontal": fraction, "vertical": fraction}`` (NaN when no sample counts).
    """
    nan = {"horizontal": float("nan"), "vertical": float("nan")}
    if err.sigma is None:
        return nan
    e, s = err.pos_ned_m, err.sigma[:, 0:3]
    if mask is not None:
        e, s = e[mask], s[mask]
    if e.shape[0] == 0:
        return nan
    z = e / np.maximum(s, 1e-12)
    d2_h = z[:, 0] ** 2 + z[:, 1] ** 2
    return {
        "horizontal": float(np.mean(d2_h <= CHI2_2DOF_3SIGMA)),
        "vertical": float(np.mean(np.abs(z[:, 2]) <= 3.0)),
    }


def horizontal_bound_3sigma(sigma: FloatArray) -> FloatArray:
    """Radius (m) of the horizontal 99.73 % bound for plotting, shape (N,) from sigma (N, >=2).

    ``sqrt(CHI2_2DOF_3SIGMA * (s_N^2 + s_E^2) / 2)``: exact when ``s_N == s_E``, the circle
    of the mean variance otherwise (:func:`containment_3sigma` uses the ellipse itself).
    """
    s = np.asarray(sigma, dtype=float)
    return np.sqrt(CHI2_2DOF_3SIGMA * 0.5 * (s[:, 0] ** 2 + s[:, 1] ** 2))


def drift_curve(err: Errors, window: Window) -> tuple[FloatArray, FloatArray]:
    """Horizontal error against time into an outage.

    Returns
    -------
    tau_s : ndarray, shape (M,)
        Seconds since ``window.start_s`` of the estimates inside the window.
    horizontal_m : ndarray, shape (M,)
    """
    m = window.mask(err.time_s)
    return err.time_s[m] - window.start_s, err.horizontal_m[m]


def resample_curve(tau_s: FloatArray, values: FloatArray, step_s: float) -> FloatArray:
    """A curve sampled at ``0, step_s, 2 step_s, ...`` up to its last time (linear
    interpolation, held at its first value before its first sample: estimates come at the
    output rate, so that is at most one output period). Shape (floor(tau_s[-1] / step_s) + 1,).
    """
    if step_s <= 0.0:
        raise ValueError("step_s must be positive")
    tau = np.asarray(tau_s, dtype=float)
    v = np.asarray(values, dtype=float)
    if tau.size == 0:
        return np.zeros(0)
    grid = np.arange(0.0, tau[-1] + 1e-9, step_s)
    return np.interp(grid, tau, v)


def mean_drift_curve(
    curves: list[tuple[FloatArray, FloatArray]], *, step_s: float = 1.0
) -> tuple[FloatArray, FloatArray, NDArray[np.int64]]:
    """Mean of several drift curves (outages, seeds) on a common time-into-outage grid.

    Parameters
    ----------
    curves : list of (tau_s (M_i,), horizontal_m (M_i,))
    step_s : float
        Grid step, s.

    Returns
    -------
    grid_s : ndarray, shape (G,)
        ``0, step_s, ...`` up to the longest curve.
    mean_m : ndarray, shape (G,)
        Mean over the curves that reach each grid time.
    count : ndarray of int, shape (G,)
        How many curves each mean is over (it drops where short outages end).
    """
    rows = [resample_curve(t, h, step_s) for t, h in curves]
    n = max((r.size for r in rows), default=0)
    grid = np.arange(n, dtype=np.float64) * step_s
    if n == 0:
        return grid, np.zeros(0), np.zeros(0, dtype=np.int64)
    stack = np.full((len(rows), n), np.nan)
    for i, r in enumerate(rows):
        stack[i, : r.size] = r
    count = np.sum(np.isfinite(stack), axis=0).astype(np.int64)
    total = np.nansum(stack, axis=0)
    mean = np.where(count > 0, total / np.maximum(count, 1), np.nan).astype(np.float64)
    return grid, mean, count


def reconverge_time(
    err: Errors,
    after_s: float,
    *,
    threshold_m: float,
    hold_s: float,
    until_s: float = math.inf,
) -> float | None:
    """Seconds from ``after_s`` (GNSS back) until the horizontal error stays below a threshold.

    The answer is ``t - after_s`` for the first estimate time ``t >= after_s`` from which every
    estimate in ``[t, t + hold_s]`` has a horizontal error below ``threshold_m``. Only
    estimates before ``until_s`` (the next outage or event) are looked at: a run cut short by
    ``until_s`` counts (the error stayed below until GNSS was lost again), a run cut by the end
    of the data must itself last ``hold_s``.

    Returns
    -------
    float or None
        ``None`` when the error never settles (or there is no estimate after ``after_s``).
    """
    if not math.isfinite(threshold_m) or hold_s < 0.0:
        return None
    t = err.time_s
    m = (t >= after_s) & (t < until_s)
    ts = t[m]
    if ts.size == 0:
        return None
    below = err.horizontal_m[m] < threshold_m
    edges = np.diff(np.r_[0, below.astype(np.int8), 0])
    starts = np.flatnonzero(edges == 1)
    ends = np.flatnonzero(edges == -1) - 1  # inclusive
    cut_by_until = math.isfinite(until_s) and until_s <= t[-1]
    for s, e in zip(starts.tolist(), ends.tolist(), strict=True):
        if e + 1 < ts.size:
            ok = ts[e + 1] - ts[s] > hold_s  # the first sample above comes after the hold
        else:
            ok = cut_by_until or ts[e] - ts[s] >= hold_s
        if ok:
            return float(ts[s] - after_s)
    return None


# ---------------------------------------------------------------------------------------------
# Health series, GNSS fixes, scenario events
# ---------------------------------------------------------------------------------------------
