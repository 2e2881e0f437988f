"""``hilnav replay``: run the fusion on a recorded log and score it against the log's reference.

Two formats, told apart by their first bytes:

* a MAVLink ``.tlog`` that follows the message definitions: HIL_SENSOR and HIL_GPS (or a flight
  controller's HIGHRES_IMU / GPS_RAW_INT ...) for the sensors, **truth** as
  HIL_STATE_QUATERNION from a component other than the sensors'. What was read goes into the
  scorecard's ``input`` section (records, frames, damaged frames, a truncated last record,
  bytes skipped to resynchronise), so a damaged or cut log is scored and says so.
* a PX4 ULog ``.ulg`` (:mod:`hil.ulog`): the sensors PX4 logged, and the autopilot's own
  estimate (EKF2) as the **reference** (``summary.json``: ``"reference": {"source": "PX4
  EKF2", ...}``); what the reference lacks (a log whose EKF2 never had a global position) is
  said there, and the metrics it cannot give are null.

GNSS outages are the gaps in the fixes longer than one second; ``gnss_off`` windows cut the
fixes of a real flight (``START:DURATION``, seconds from the log's first sample) so that a
team can rehearse a denial on its own data. The settling time is fitted to the log
(:func:`scenarios.summary.fit_settling`): a log shorter than ``--settle`` is scored over what it
has, with a warning in ``summary.json`` (``settling``) that the CLI prints on stderr. The
filter aligns by itself; the log's date goes to its World Magnetic Model reference
(:func:`_alignment_for_log`).
"""

from __future__ import annotations

import datetime as dt
import math
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Final

import numpy as np

from fusion.alignment import level_from_specific_force
from fusion.config import ALTITUDE_METHODS, FilterConfig
from fusion.rotations import euler_to_dcm
from hil.pipeline import FusionRun
from hil.streamer import GnssWindow
from hil.tlog import TlogReader, iter_decoded
from hil.ulog import REFERENCE_LABEL, UlogLog, read_ulog
from physconst.geomag import decimal_year, magnetic_field_ned_t
from scenarios.report import write_plots
from scenarios.summary import RunInfo, score_run, write_summary
from sim.samples import GnssFix, ImuSample, MagSample, Sample, Truth

_ULOG_MAGIC: Final = b"ULog\x01\x12\x35"
_TRUTH_LABEL: Final = "truth"
_UNIX_2010_US: Final = 1_262_304_000_000_000  # a tlog stamp above this is Unix time


@dataclass(frozen=True)
class ReplayResult:
    summary: dict[str, Any]
    summary_path: Path
    plots: list[Path]


def replay(
    log: Path,
    out_dir: Path,
    *,
    config: FilterConfig | None = None,
    bridge: str = "none",
    altitude: str = "ekf",
    settle_s: float = 60.0,
    gnss_off: Sequence[str] = (),
    progress: Callable[[int, int], None] | None = None,
    setup: Mapping[str, Any] | None = None,
) -> ReplayResult:
    """Run the filter over ``log`` (``.tlog`` or ``.ulg``) and write ``summary.json`` and plots
    into ``out_dir``.

    ``altitude`` selects the altitude method (``fusion.config.ALTITUDE_METHODS``), replacing
    ``config.altitude.method``; ``gnss_off`` holds ``START:DURATION`` windows (s from the log's
    first sample) whose fixes are removed; ``setup``: what was flown (aircraft, plan, sensor
    presets, air), for the scorecard, when the caller knows it. Bad input raises
    ``ValueError`` with one line that names the cause.
    """
    if altitude not in ALTITUDE_METHODS:
        raise ValueError(
            f"unknown altitude method {altitude!r}; valid methods: {', '.join(ALTITUDE_METHODS)}"
        )
    windows = tuple(GnssWindow.parse(w) for w in gnss_off)
    base = config if config is not None else FilterConfig()
    config = base.model_copy(
        update={"altitude": base.altitude.model_copy(update={"method": altitude})}
    )
    if log.is_dir():
        raise ValueError(f"{log} is a folder; give a .tlog or .ulg file")
    if not log.is_file():
        raise ValueError(f"no such log file: {log}")
    if log.stat().st_size == 0:
        raise ValueError(f"{log} is empty")
    with open(log, "rb") as f:
        head = f.read(len(_ULOG_MAGIC))
    if head == _ULOG_MAGIC:
        return _replay_ulog(log, out_dir, config, bridge, altitude, settle_s, windows, setup)
    if log.suffix.lower() == ".ulg":
        raise ValueError(f"{log}: not a PX4 ULog file (its header is not 'ULog'); a damaged "
                         "or renamed file?")
    return _replay_tlog(log, out_dir, config, bridge, altitude, settle_s, windows, progress,
                        setup)


# -------------------------------------------------------------------------------- tlog
def _replay_tlog(
    log: Path, out_dir: Path, config: FilterConfig, bridge: str, altitude: str,
    settle_s: float, windows: tuple[GnssWindow, ...],
    progress: Callable[[int, int], None] | None, setup: Mapping[str, Any] | None = None,
) -> ReplayResult:
    head, year = _tlog_start(log)
    try:
        config, alignment = _alignment_for_log(config, head, year, whole_log=False)
    except ValueError as exc:
        raise ValueError(f"{log}: {exc}") from None
    out_dir.mkdir(parents=True, exist_ok=True)
    size = log.stat().st_size
    run = FusionRun(config, bridge)
    cut = _GnssCut(windows)
    t0 = time.perf_counter()
    done = 0
    with TlogReader(log) as reader:
        for _ts, frame in reader:
            done += len(frame) + 8
            decoded = run.decoder.feed(frame)
            run.samples += len(decoded)
            run.feed(cut.filter(d.sample for d in decoded))
            if progress is not None and done % 65536 < len(frame) + 8:
                progress(done, size)
    wall = time.perf_counter() - t0
    _check_tlog_content(log, run)
    c = run.decoder.counters
    inp = {
        "format": "tlog", "records": reader.stats.records, "frames": c.frames_ok,
        "bad_frames": c.bad_crc + c.bad_frames + c.bad_signature,
        "truncated": reader.stats.truncated_records > 0,
        "skipped_bytes": reader.stats.skipped_bytes,
    }
    reference = {"source": _TRUTH_LABEL, "topics": ["HIL_STATE_QUATERNION"], "position": True,
                 "height": True, "velocity": True, "attitude": True}
    return _score(log, out_dir, run, bridge, altitude, settle_s, wall, cut, alignment,
                  reference, inp, setup)


def _tlog_start(log: Path) -> tuple[list[Sample], float | None]:
    """The samples up to the first 3-D fix (all of them if there is none), and the log's date
    when its record stamps are Unix time (a ground station's recording)."""
    head: list[Sample] = []
    year = None
    for stamp_us, d in iter_decoded(log):
        s = d.sample
        if year is None and stamp_us > _UNIX_2010_US:
            year = decimal_year(dt.datetime.fromtimestamp(stamp_us * 1e-6, tz=dt.UTC))
        if isinstance(s, Truth):
            continue
        head.append(s)
        if isinstance(s, GnssFix) and s.fix_type >= 3:
            break
    return head, year


def _check_tlog_content(log: Path, run: FusionRun) -> None:
    """Name what a log lacks before scoring it (ValueError, one line)."""
    counters = run.decoder.counters
    if counters.frames_ok == 0:
        raise ValueError(f"{log}: no MAVLink frame with a valid checksum (not a .tlog of "
                         "MAVLink frames?)")
    h = run.nav.health
    if h.imu_ok + h.imu_nan + h.imu_out_of_range == 0:
        raise ValueError(f"{log}: no IMU messages (HIL_SENSOR, HIGHRES_IMU, SCALED_IMU or "
                         "RAW_IMU)")
    col = run.collector
    if col is not None and col.n_fixes == 0:
        raise ValueError(f"{log}: no GNSS fix with a 3-D fix type (HIL_GPS or GPS_RAW_INT): "
                         "nothing to align the filter with")


# -------------------------------------------------------------------------------- ULog
def _replay_ulog(
    log: Path, out_dir: Path, config: FilterConfig, bridge: str, altitude: str,
    settle_s: float, windows: tuple[GnssWindow, ...], setup: Mapping[str, Any] | None = None,
) -> ReplayResult:
    t0 = time.perf_counter()
    ulog = read_ulog(log)
    _check_ulog_content(log, ulog)
    year = (None if ulog.first_fix_utc_us is None else decimal_year(
        dt.datetime.fromtimestamp(ulog.first_fix_utc_us * 1e-6, tz=dt.UTC)))
    try:
        config, alignment = _alignment_for_log(config, ulog.samples, year, whole_log=True)
    except ValueError as exc:
        raise ValueError(f"{log}: {exc}") from None
    out_dir.mkdir(parents=True, exist_ok=True)
    run = FusionRun(config, bridge)
    cut = _GnssCut(windows)
    run.samples = len(ulog.samples)
    run.feed(cut.filter(ulog.samples))
    run.feed(ulog.reference)
    wall = time.perf_counter() - t0
    inp = {
        "format": "ulog", "topics": ulog.topics, "ignored_topics": ulog.ignored_topics,
        "dropped": ulog.dropped, "corrupt": ulog.corrupt, "notes": ulog.notes,
        "logger_dropouts": ulog.dropouts, "logger_dropout_ms": ulog.dropout_ms,
        "gnss_topic": ulog.gnss_topic,
        "fix_types": {str(k): v for k, v in sorted(ulog.fix_types.items())},
        "log_duration_s": ulog.duration_s,
    }
    reference = {
        "source": REFERENCE_LABEL,
        "topics": list(dict.fromkeys(
            t for t in ("vehicle_attitude", ulog.reference_position, ulog.reference_height,
                        "vehicle_local_position" if ulog.reference_velocity else None)
            if t is not None)),
        "position": ulog.reference_position is not None,
        "height": ulog.reference_height is not None,
        "velocity": ulog.reference_velocity,
        "attitude": True,
    }
    missing = [k for k in ("position", "height", "velocity") if not reference[k]]
    if missing:
        reference["warning"] = (
            f"the autopilot's estimate in the log has no global {', no '.join(missing)}: "
            "those metrics are null (scored: " + ", ".join(
                k for k in ("position", "height", "velocity", "attitude") if reference[k]) + ")")
    return _score(log, out_dir, run, bridge, altitude, settle_s, wall, cut, alignment,
                  reference, inp, setup)


def _check_ulog_content(log: Path, ulog: UlogLog) -> None:
    """Name what a ULog lacks, with what the user can do (ValueError, one line)."""
    if ulog.corrupt and not ulog.samples:
        raise ValueError(f"{log}: a damaged ULog with no readable sensor data (pyulog: "
                         f"{ulog.notes or 'file corruption'})")
    if ulog.count(ImuSample) == 0:
        raise ValueError(f"{log}: no IMU messages (sensor_combined is not logged or empty); "
                         "it is one of PX4's default logger topics: check SDLOG_PROFILE")
    if ulog.gnss_topic is None:
        raise ValueError(f"{log}: no position source (neither vehicle_gps_position nor "
                         "sensor_gps is logged); replay needs GNSS to align the filter")
    if not any(k >= 3 for k in ulog.fix_types):
        seen = ", ".join(f"{n} x fix type {k}" for k, n in sorted(ulog.fix_types.items()))
        raise ValueError(f"{log}: GNSS never valid ({seen or 'no fixes'}; a 3-D fix, fix "
                         "type >= 3, is needed): was the receiver still acquiring?")
    if not ulog.reference:
        raise ValueError(f"{log}: no reference: vehicle_attitude (the autopilot's estimate) is "
                         "not logged, so there is nothing to score against")


# ------------------------------------------------------------------- shared: cut, align
class _GnssCut:
    """Removes the fixes inside ``--gnss-off`` windows, timed from the log's first sample."""

    def __init__(self, windows: tuple[GnssWindow, ...]) -> None:
        self.windows = windows
        self.first_us: int | None = None
        self.removed = 0

    def filter(self, samples: Iterable[Sample | Truth]) -> list[Sample | Truth]:
        out: list[Sample | Truth] = []
        for s in samples:
            if self.first_us is None and not isinstance(s, Truth):
                self.first_us = s.time_us
            if (isinstance(s, GnssFix) and self.first_us is not None
                    and any(w.covers(s.time_us - self.first_us) for w in self.windows)):
                self.removed += 1
                continue
            out.append(s)
        return out

    def as_list(self) -> list[dict[str, Any]]:
        t0 = 0.0 if self.first_us is None else self.first_us * 1e-6
        return [{"start_s": t0 + w.start_s, "end_s": t0 + w.start_s + w.duration_s,
                 "requested": f"{w.start_s:g}:{w.duration_s:g}"} for w in self.windows]


def _alignment_for_log(
    config: FilterConfig, head: Sequence[Sample], year: float | None, *, whole_log: bool
) -> tuple[FilterConfig, dict[str, Any]]:
    """How the filter aligns on a recorded log.

    The filter aligns by itself (``InitConfig.mode="auto"``: static at rest, from the GNSS
    track when moving, from the magnetometer when hovering); a log adds what the filter
    cannot know: its date, which goes to the World Magnetic Model reference
    (``MagTuning.decimal_year``; unknown: :data:`DEFAULT_DECIMAL_YEAR`, the filter's default).
    The WMM field at the first 3-D fix is recorded, with the magnetometer's own dip and
    strength over the first seconds and a warning when they disagree.

    Parameters
    ----------
    config : FilterConfig
    head : sequence of Sample
        The log's samples in time order, at least up to its first 3-D fix.
    year : float or None
        The log's date, decimal year (None: unknown).
    whole_log : bool
        ``head`` is the whole log (else a vehicle at rest without magnetometer may still move
        later).

    Raises
    ------
    ValueError
        The vehicle never moves and the log has no magnetometer: no heading can be found
        (gyrocompassing needs gyros far better than a flight controller's).
    """
    if year is not None:
        config = config.model_copy(update={
            "mag": config.mag.model_copy(update={"decimal_year": year})})
    info: dict[str, Any] = {"mode": config.init.mode, "decimal_year": config.mag.decimal_year,
                            "date_known": year is not None}
    fixes = [s for s in head if isinstance(s, GnssFix) and s.fix_type >= 3]
    if not fixes:
        return config, info
    first = fixes[0]
    speed = math.hypot(float(first.v_ned_mps[0]), float(first.v_ned_mps[1]))
    min_speed = config.init.min_speed_mps
    info["first_fix_speed_mps"] = speed
    has_mag = any(isinstance(s, MagSample) for s in head)
    if speed < min_speed and not has_mag and whole_log and all(
            math.hypot(float(f.v_ned_mps[0]), float(f.v_ned_mps[1])) < min_speed
            for f in fixes):
        raise ValueError(
            f"alignment not reached: the vehicle never moved (GNSS ground speed below "
            f"{min_speed:g} m/s) and the log has no magnetometer, so no heading can be found; "
            "replay a log with magnetometer data (vehicle_magnetometer / HIL_SENSOR mag) or "
            "one that includes flight")
    field = magnetic_field_ned_t(first.lat_rad, first.lon_rad, first.alt_msl_m,
                                 config.mag.decimal_year)
    info.update({
        "magnetic_model": "WMM",
        "declination_deg": math.degrees(field.declination_rad),
        "inclination_deg": math.degrees(field.inclination_rad),
        "intensity_ut": field.intensity_t * 1e6,
    })
    info.update(_mag_check(head, field.inclination_rad, field.intensity_t,
                           config.init.static_duration_s))
    return config, info


_MAX_INCLINATION_DIFF_RAD: Final = math.radians(10.0)
_MAX_INTENSITY_RATIO: Final = 1.3


def _mag_check(head: Sequence[Sample], inclination_rad: float, intensity_t: float,
               window_s: float) -> dict[str, Any]:
    """The magnetometer's mean field over the log's first ``window_s`` (levelled with the
    accelerometer) against the model: a heading from a magnetometer whose dip or strength
    disagrees (uncalibrated, disturbed by the vehicle) is off by an unknown angle, so say so."""
    imu = [s for s in head if isinstance(s, ImuSample)]
    mag = [s for s in head if isinstance(s, MagSample)]
    if not imu or not mag:
        return {}
    t_end = mag[0].time_us + round(window_s * 1e6)
    m_b = np.mean([m.field_b_tesla for m in mag if m.time_us <= t_end], axis=0)
    f_b = np.mean([s.specific_force_b_mps2 for s in imu
                   if mag[0].time_us <= s.time_us <= t_end] or [imu[0].specific_force_b_mps2],
                  axis=0)
    roll, pitch = level_from_specific_force(f_b)
    m_lev = euler_to_dcm(np.array([roll, pitch, 0.0])) @ m_b
    measured_inc = math.atan2(float(m_lev[2]), math.hypot(float(m_lev[0]), float(m_lev[1])))
    measured_int = float(np.linalg.norm(m_b))
    out: dict[str, Any] = {"measured_inclination_deg": math.degrees(measured_inc),
                           "measured_intensity_ut": measured_int * 1e6}
    ratio = measured_int / intensity_t
    if (abs(measured_inc - inclination_rad) > _MAX_INCLINATION_DIFF_RAD
            or not 1.0 / _MAX_INTENSITY_RATIO <= ratio <= _MAX_INTENSITY_RATIO):
        out["warning"] = (
            f"the magnetometer disagrees with the WMM field at the start (dip "
            f"{math.degrees(measured_inc):.0f} vs {math.degrees(inclination_rad):.0f} deg, "
            f"strength {measured_int * 1e6:.0f} vs {intensity_t * 1e6:.0f} uT): uncalibrated or "
            "disturbed, so the heading aligned from it may be off by many degrees")
    return out


# ------------------------------------------------------------------------------- score
def _score(
    log: Path, out_dir: Path, run: FusionRun, bridge: str, altitude: str, settle_s: float,
    wall: float, cut: _GnssCut, alignment: dict[str, Any], reference: dict[str, Any],
    inp: dict[str, Any], setup: Mapping[str, Any] | None = None,
) -> ReplayResult:
    col = run.collector
    assert col is not None
    if all(m == "initializing" for m in col.modes()):
        raise ValueError(_not_aligned(log, run))
    if col.n_truths < 2:
        raise ValueError(f"{log}: the log holds no {reference['source']} "
                         f"({', '.join(reference['topics'])}) to score against")
    est, ref = col.estimate_track(), col.truth_track()
    if min(est.time_s[-1], ref.time_s[-1]) <= max(est.time_s[0], ref.time_s[0]):
        raise ValueError(f"{log}: too short to score: the navigation estimate "
                         f"({est.time_s[0]:.1f}-{est.time_s[-1]:.1f} s) and the "
                         f"{reference['source']} reference ({ref.time_s[0]:.1f}-"
                         f"{ref.time_s[-1]:.1f} s) never overlap")
    info = RunInfo(scenario=log.stem, seed=None, sim_duration_s=col.last_time_us * 1e-6,
                   wall_s=wall, bridge=bridge, altitude=altitude, setup=setup)
    scored = score_run(run, info, settle_s=settle_s, fit_settle=True)
    s = scored.summary
    s["reference"] = reference
    alignment["method"] = run.nav.alignment_method
    s["alignment"] = alignment
    s["gnss_off"] = {"windows": cut.as_list(), "fixes_removed": cut.removed}
    s["input"] = inp
    summary_path = out_dir / "summary.json"
    write_summary(s, summary_path)
    label = str(reference["source"])
    plots = write_plots(scored.estimate, scored.truth, scored.errors, scored.outages, out_dir,
                        reference_label=label if label == _TRUTH_LABEL else f"{label} reference")
    return ReplayResult(s, summary_path, plots)


def _not_aligned(log: Path, run: FusionRun) -> str:
    """Why the filter never navigated, in one line with what the user can do."""
    fixes = (np.asarray(run.collector.fix_times_us) if run.collector is not None
             else np.zeros(0))
    span = (f"3-D fixes from {fixes[0] * 1e-6:.1f} to {fixes[-1] * 1e-6:.1f} s" if fixes.size
            else "no 3-D fix")
    init = run.config.init
    needs = {
        "static": f"the static alignment (--align static) needs {init.static_duration_s:g} s at "
                  "rest after a good fix; try --align auto",
        "in_flight": f"the in-flight alignment (--align in-flight) needs a GNSS ground speed of "
                     f"{init.min_speed_mps:g} m/s; try --align auto",
    }.get(init.mode, f"the log needs {init.static_duration_s:g} s at rest, or a GNSS ground "
                     f"speed of {init.min_speed_mps:g} m/s, or a magnetometer while moving "
                     "slower, after a good fix")
    return (f"{log}: alignment not reached ({span}; at the end of the log the filter was "
            f"{run.nav.alignment_state}): {needs}")
