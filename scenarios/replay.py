"""``hilnav replay``: run the fusion on a recorded MAVLink log and score it against truth.

Any log that follows the message definitions works: HIL_SENSOR and HIL_GPS for the sensors,
truth as HIL_STATE_QUATERNION from a component other than the sensors'. GNSS outages are found
from gaps in the GNSS frames longer than one second. What was read goes into the scorecard's
``input`` section (records, frames, damaged frames, a truncated last record, bytes skipped to
resynchronise), so a damaged or cut log is scored and says so.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from fusion.config import ALTITUDE_METHODS, FilterConfig
from hil.pipeline import FusionRun
from hil.tlog import TlogReader
from scenarios.report import write_plots
from scenarios.summary import RunInfo, score_run, write_summary


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
    progress: Callable[[int, int], None] | None = None,
) -> ReplayResult:
    """Run the filter over ``log`` and write ``summary.json`` and plots into ``out_dir``.

    ``altitude`` selects the altitude method (``fusion.config.ALTITUDE_METHODS``), replacing
    ``config.altitude.method``; an unknown name raises ``ValueError`` listing the valid ones.
    """
    if altitude not in ALTITUDE_METHODS:
        raise ValueError(
            f"unknown altitude method {altitude!r}; valid methods: {', '.join(ALTITUDE_METHODS)}"
        )
    base = config if config is not None else FilterConfig()
    config = base.model_copy(
        update={"altitude": base.altitude.model_copy(update={"method": altitude})}
    )
    if log.is_dir():
        raise ValueError(f"{log} is a folder; give a .tlog file")
    if not log.is_file():
        raise ValueError(f"no such log file: {log}")
    if log.stat().st_size == 0:
        raise ValueError(f"{log} is empty")
    out_dir.mkdir(parents=True, exist_ok=True)
    size = log.stat().st_size
    run = FusionRun(config, bridge)
    t0 = time.perf_counter()
    done = 0
    with TlogReader(log) as reader:
        for _ts, frame in reader:
            done += len(frame) + 8
            run.feed_frame(frame)
            if progress is not None and done % 65536 < len(frame) + 8:
                progress(done, size)
    wall = time.perf_counter() - t0
    _check_content(log, run)
    assert run.collector is not None
    info = RunInfo(scenario=log.stem, seed=None, sim_duration_s=run.collector.last_time_us * 1e-6,
                   wall_s=wall, bridge=bridge, altitude=altitude)
    scored = score_run(run, info, settle_s=settle_s)
    c = run.decoder.counters
    scored.summary["input"] = {
        "records": reader.stats.records, "frames": c.frames_ok,
        "bad_frames": c.bad_crc + c.bad_frames + c.bad_signature,
        "truncated": reader.stats.truncated_records > 0,
        "skipped_bytes": reader.stats.skipped_bytes,
    }
    summary_path = out_dir / "summary.json"
    write_summary(scored.summary, summary_path)
    plots = write_plots(scored.estimate, scored.truth, scored.errors, scored.outages, out_dir)
    return ReplayResult(scored.summary, summary_path, plots)


def _check_content(log: Path, run: FusionRun) -> None:
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
