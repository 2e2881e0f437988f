"""Event scoring: how the filter handled each fault of a scenario's timeline.

For every event window (a spoof, a glitch, jamming, or a generic fault): the time the filter
took to detect it (first rejection or mode change of the concerned sensor; for a pitot fault
the first declared blockage), the worst error
while it lasted, whether the filter re-accepted the faulty sensor early, how many bad fixes it
took in, and re-convergence after it; plus the rejections of good data outside every event.
Pure numpy on the collected tracks and health series (:mod:`hil.tracks`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from fusion import earth
from hil.tracks import Fixes, HealthSeries, Track
from scenarios.metrics import Errors, reconverge_time, wrap_pi

FloatArray = NDArray[np.float64]


def fix_errors(fixes: Fixes, truth: Track) -> FloatArray:
    """Horizontal error (m) of each fix against truth at its time of validity, shape (K,).

    NaN for fixes outside the truth's time span. The antenna lever arm is ignored (it is far
    below the errors this is used for: spoofed and glitched fixes).
    """
    t = fixes.time_s
    tp = truth.time_s
    out = np.full(t.shape, np.nan)
    keep = (t >= tp[0]) & (t <= tp[-1])
    lat_t = np.interp(t[keep], tp, truth.lat_rad)
    lon_t = np.interp(t[keep], tp, truth.lon_rad)
    alt_t = np.interp(t[keep], tp, truth.alt_m)
    r_n, r_e = earth.principal_radii(lat_t)
    dn = (fixes.lat_rad[keep] - lat_t) * (r_n + alt_t)
    de = wrap_pi(fixes.lon_rad[keep] - lon_t) * (r_e + alt_t) * np.cos(lat_t)
    out[keep] = np.hypot(dn, de)
    return out


#: Event kinds scored by :func:`event_metrics`.
EVENT_KINDS = ("spoof", "glitch", "jamming", "generic")
#: Sensors an event can concern; ``"any"`` looks at every detector.
EVENT_SENSORS = ("gnss", "baro", "mag", "imu", "airspeed", "any")


def event_kind(type_name: str) -> str:
    """Kind of a fault type name (``"gnss_spoof_hijack"`` -> ``"spoof"``, ...)."""
    for kind in ("spoof", "glitch", "jamming"):
        if kind in type_name:
            return kind
    return "generic"


def event_sensor(type_name: str) -> str:
    """Sensor a fault type name concerns (``"baro_glitch"`` -> ``"baro"``; pressure weather
    acts on the barometer; ``pitot_*`` and ``airspeed_*`` on the airspeed sensor; unknown ->
    ``"any"``)."""
    prefix = type_name.split("_", 1)[0]
    if prefix in ("gnss", "baro", "mag", "imu", "airspeed"):
        return prefix
    if prefix == "pitot":
        return "airspeed"
    if type_name == "weather_front":
        return "baro"
    return "any"


@dataclass(frozen=True)
class EventWindow:
    """A scenario event scored on its own: ``[start_s, end_s]`` of simulated time.

    ``kind`` and ``sensor`` default to what :func:`event_kind` / :func:`event_sensor` read from
    ``type`` (e.g. ``"gnss_spoof_drift"``).
    """

    type: str
    start_s: float
    end_s: float
    kind: str = ""
    sensor: str = ""

    def __post_init__(self) -> None:
        if not math.isfinite(self.start_s):
            raise ValueError(f"event {self.type!r}: start_s must be finite")
        if math.isnan(self.end_s) or self.end_s < self.start_s:
            raise ValueError(f"event {self.type!r}: end_s must be >= start_s")
        if not self.kind:
            object.__setattr__(self, "kind", event_kind(self.type))
        if not self.sensor:
            object.__setattr__(self, "sensor", event_sensor(self.type))
        if self.kind not in EVENT_KINDS:
            raise ValueError(f"event {self.type!r}: kind must be one of {EVENT_KINDS}")
        if self.sensor not in EVENT_SENSORS:
            raise ValueError(f"event {self.type!r}: sensor must be one of {EVENT_SENSORS}")

    @classmethod
    def from_mapping(cls, row: Mapping[str, Any]) -> EventWindow:
        """From ``{"type", "start_s", "end_s"[, "kind", "sensor"]}`` (a ``None`` end = open)."""
        for key in ("type", "start_s"):
            if key not in row:
                raise ValueError(f"event {dict(row)!r} has no {key!r}")
        end = row.get("end_s")
        return cls(
            type=str(row["type"]),
            start_s=float(row["start_s"]),
            end_s=math.inf if end is None else float(end),
            kind=str(row.get("kind") or ""),
            sensor=str(row.get("sensor") or ""),
        )


_DETECTORS: dict[str, tuple[tuple[str, ...], tuple[str, ...]]] = {
    # sensor: (counters whose increase is a rejection, ratios whose fresh value > 1 is one)
    "gnss": (("gnss_rejected", "gnss_resets", "gnss_quality_rejected"),
             ("ratio_gnss_pos", "ratio_gnss_vel")),
    "baro": (("baro_rejected", "baro_resets"), ("ratio_baro",)),
    "mag": (("mag_rejected",), ("ratio_mag",)),
    # a pitot fault is detected when the filter declares the pitot blocked (one rejected
    # batch is not: the monitor needs 5 s of them); an airspeed failure sends no samples, so
    # nothing is refused and it stays undetected here
    "airspeed": (("airspeed_blockages",), ()),
}  # fmt: skip
_DETECTORS["imu"] = _DETECTORS["any"] = (
    tuple(c for v in _DETECTORS.values() for c in v[0]),
    tuple(r for v in _DETECTORS.values() for r in v[1]),
)
#: Counters whose increase means the sensor's data was taken in (fused, or the state reset
#: to it).
_ACCEPT = {
    "gnss": ("gnss_fused", "gnss_resets"),
    "baro": ("baro_fused", "baro_resets"),
    "mag": ("mag_fused",),
}


def _span(time_s: FloatArray, start_s: float, end_s: float) -> NDArray[np.intp]:
    i0 = int(np.searchsorted(time_s, start_s, side="left"))
    i1 = int(np.searchsorted(time_s, end_s, side="right"))
    return np.arange(i0, max(i0, i1))


def _increase(x: NDArray[Any], idx: NDArray[np.intp]) -> NDArray[np.int64]:
    """Increase of a cumulative counter at each index since the sample before (0 at index 0)."""
    prev = np.maximum(idx - 1, 0)
    return np.maximum(np.asarray(x[idx], dtype=np.int64) - np.asarray(x[prev], dtype=np.int64), 0)


def rejection_flags(health: HealthSeries, sensor: str, idx: NDArray[np.intp]) -> NDArray[np.bool_]:
    """True at the samples ``idx`` where the filter refused ``sensor``'s data.

    A refusal is a rejection or reset counter (or, for GNSS, the quality-check counter; for
    the airspeed sensor, the declared pitot blockages) increasing since the previous sample, a
    *fresh* test ratio above 1, or (GNSS, ``"imu"`` and ``"any"``) the mode leaving
    ``"gnss"``: the filter declared GNSS lost.
    """
    if sensor not in _DETECTORS:
        raise ValueError(f"sensor must be one of {tuple(_DETECTORS)}")
    counters, ratios = _DETECTORS[sensor]
    prev = np.maximum(idx - 1, 0)
    hit = np.zeros(idx.size, dtype=bool)
    for name in counters:
        c = getattr(health, name)
        if c is not None:
            hit |= _increase(c, idx) > 0
    for name in ratios:
        r = getattr(health, name)
        if r is not None:
            # a ratio equal to the previous sample's is the same (old) test
            hit |= (r[idx] > 1.0) & (r[idx] != r[prev])
    if health.mode is not None and sensor in ("gnss", "imu", "any"):
        hit |= (health.mode[idx] != "gnss") & (health.mode[prev] == "gnss") & (idx > 0)
    return hit


def detect_time(health: HealthSeries, start_s: float, end_s: float, sensor: str) -> float | None:
    """Time (s, absolute) of the filter's first refusal of ``sensor`` in ``[start_s, end_s]``
    (see :func:`rejection_flags`), ``None`` if it never refused it there."""
    idx = _span(health.time_s, start_s, end_s)
    if idx.size == 0:
        return None
    hit = rejection_flags(health, sensor, idx)
    if not np.any(hit):
        return None
    return float(health.time_s[idx[int(np.argmax(hit))]])


def _bad_fixes_fused(
    health: HealthSeries, idx: NDArray[np.intp], fix_err_m: FloatArray, bad_fix_m: float
) -> int:
    """Fixes taken in (fused or reset to) while the latest fix was ``bad_fix_m`` off truth.

    Each increase of ``gnss_fused`` / ``gnss_resets`` at an estimate is attributed to the
    latest fix with a time of validity at or before that estimate (fixes are fused when the
    INS reaches their time of validity, between two estimates).
    """
    fixes = health.fixes
    if fixes is None or fixes.time_s.size == 0 or idx.size == 0:
        return 0
    taken = np.zeros(idx.size, dtype=np.int64)
    for name in _ACCEPT["gnss"]:
        c = getattr(health, name)
        if c is not None:
            taken += _increase(c, idx)
    at = np.flatnonzero(taken > 0)
    if at.size == 0:
        return 0
    j = np.searchsorted(fixes.time_s, health.time_s[idx[at]], side="right") - 1
    ok = j >= 0
    bad = np.zeros(at.size, dtype=bool)
    e = fix_err_m[j[ok]]
    bad[ok] = np.isfinite(e) & (e > bad_fix_m)
    return int(np.sum(taken[at][bad]))


@dataclass
class EventMetrics:
    """The scorecard of one scenario event (see :func:`event_metrics`)."""

    type: str
    kind: str
    sensor: str
    start_s: float
    end_s: float
    detect_s: float | None
    max_horizontal_m: float
    max_vertical_m: float
    reaccepted_early: bool | None
    reaccept_count: int | None
    bad_fixes_fused: int | None
    reconverge_s: float | None = None

    def as_dict(self) -> dict[str, object]:
        return {
            "type": self.type,
            "kind": self.kind,
            "sensor": self.sensor,
            "start_s": self.start_s,
            "end_s": self.end_s,
            "detect_s": self.detect_s,
            "detected": self.detect_s is not None,
            "max_horizontal_m": self.max_horizontal_m,
            "max_vertical_m": self.max_vertical_m,
            "reaccepted_early": self.reaccepted_early,
            "reaccept_count": self.reaccept_count,
            "bad_fixes_fused": self.bad_fixes_fused,
            "reconverge_s": self.reconverge_s,
        }


def event_metrics(
    err: Errors,
    event: EventWindow,
    *,
    health: HealthSeries | None = None,
    fix_err_m: FloatArray | None = None,
    bad_fix_m: float | None = None,
    reconverge_threshold_m: float | None = None,
    hold_s: float = 10.0,
    until_s: float = math.inf,
) -> EventMetrics:
    """Score one scenario event.

    Parameters
    ----------
    err : Errors
    event : EventWindow
        An open end (``inf``) stops at the last estimate.
    health : HealthSeries, optional
        Without it ``detect_s`` and the re-accept fields are ``None``.
    fix_err_m : ndarray, shape (K,), optional
        Horizontal error of each of ``health.fixes`` vs truth (:func:`fix_errors`).
    bad_fix_m : float, optional
        A fix further than this from truth must not be fused (needs ``fix_err_m``).
    reconverge_threshold_m : float, optional
        For GNSS events: :func:`reconverge_time` after the event's end with this threshold.
    hold_s : float
        Hold time of the re-convergence test, s.
    until_s : float
        The next outage or event start: re-convergence is looked for before it.

    Returns
    -------
    EventMetrics
        ``detect_s``: seconds from the start to the first refusal of the event's sensor
        (:func:`detect_time`), ``None`` if never. ``max_horizontal_m`` / ``max_vertical_m``:
        largest error during the event (NaN without estimates in it). ``reaccept_count``: for
        spoof and glitch events, the sensor's data taken in (fused or reset to) after the
        detection and before the end, plus (GNSS) fixes taken in that were further than
        ``bad_fix_m`` from truth at any time in the event; ``bad_fixes_fused`` the latter
        alone. ``reaccepted_early`` is ``reaccept_count > 0`` (for jamming and generic GNSS
        events only the bad-fix part counts: the real signal may legitimately return).
    """
    end = min(event.end_s, float(err.time_s[-1])) if err.time_s.size else event.end_s
    m = (err.time_s >= event.start_s) & (err.time_s <= end)
    max_h = float(np.max(err.horizontal_m[m])) if np.any(m) else float("nan")
    max_v = float(np.max(err.vertical_m[m])) if np.any(m) else float("nan")
    detect_abs: float | None = None
    reaccepted: bool | None = None
    count: int | None = None
    bad: int | None = None
    if health is not None:
        t_end = min(event.end_s, float(health.time_s[-1])) if health.time_s.size else end
        detect_abs = detect_time(health, event.start_s, t_end, event.sensor)
        if event.sensor == "gnss" and fix_err_m is not None and bad_fix_m is not None:
            bad = _bad_fixes_fused(
                health, _span(health.time_s, event.start_s, t_end), fix_err_m, bad_fix_m)
        after = 0
        if event.kind in ("spoof", "glitch") and detect_abs is not None:
            idx = _span(health.time_s, detect_abs, t_end)
            idx = idx[health.time_s[idx] > detect_abs]
            for name in _ACCEPT.get(event.sensor, ()):
                c = getattr(health, name)
                if c is not None and idx.size:
                    after += int(np.sum(_increase(c, idx)))
        if event.kind in ("spoof", "glitch") or bad is not None:
            count = after + (bad or 0)
            reaccepted = count > 0
    reconv = None
    if (reconverge_threshold_m is not None and event.sensor == "gnss"
            and math.isfinite(event.end_s)):
        reconv = reconverge_time(err, event.end_s, threshold_m=reconverge_threshold_m,
                                 hold_s=hold_s, until_s=until_s)
    return EventMetrics(
        type=event.type, kind=event.kind, sensor=event.sensor, start_s=event.start_s,
        end_s=end, detect_s=None if detect_abs is None else detect_abs - event.start_s,
        max_horizontal_m=max_h, max_vertical_m=max_v, reaccepted_early=reaccepted,
        reaccept_count=count, bad_fixes_fused=bad, reconverge_s=reconv,
    )


def detect_s_by_sensor(rows: Sequence[Mapping[str, Any]]) -> dict[str, list[float | None]]:
    """``detect_s`` of the scored events (:meth:`EventMetrics.as_dict` rows) grouped by the
    sensor they concern, in timeline order (``None`` = never detected), so that a criterion can
    gate one sensor's detections without the others' (e.g. a pitot blockage inside a GNSS
    outage: ``detect_s_by_sensor.airspeed``). Every sensor of :data:`EVENT_SENSORS` has a
    list, empty without events (a criterion on it then fails: there was nothing to detect)."""
    out: dict[str, list[float | None]] = {s: [] for s in EVENT_SENSORS}
    for row in rows:
        d = row.get("detect_s")
        out[str(row["sensor"])].append(None if d is None else float(d))
    return out


def rejections_outside(
    health: HealthSeries, windows: list[tuple[float, float]], *, after_s: float
) -> dict[str, int]:
    """Rejections (counter increases) outside the given windows, from ``after_s`` on: the
    false-alarm side of detection. Keys ``gnss_rejected``, ``baro_rejected``, ``mag_rejected``
    (those collected)."""
    t = health.time_s
    keep = t >= after_s
    for a, b in windows:
        keep &= ~((t >= a) & (t <= b))
    idx = np.flatnonzero(keep)
    out: dict[str, int] = {}
    for name in ("gnss_rejected", "baro_rejected", "mag_rejected"):
        c = getattr(health, name)
        if c is not None:
            out[name] = int(np.sum(_increase(c, idx))) if idx.size else 0
    return out
