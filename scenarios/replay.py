"""``hilnav replay``: run the fusion on a recorded MAVLink log and score it against truth.

Any log that follows the message definitions works: HIL_SENSOR and HIL_GPS for the sensors,
truth as HIL_STATE_QUATERNION from a component other than the sensors'. GNSS outages are found
from gaps in the GNSS frames longer than one second.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from fusion.bridging.registry import make_bridge
from fusion.config import ALTITUDE_METHODS, FilterConfig
from fusion.filter import NavFilter
from hil.codec import Decoder
from hil.tlog import read_tlog
from scenarios import metrics
from scenarios.collect import Collector
from scenarios.jsonable import plain_dict
from scenarios.report import write_plots
from scenarios.summary import RunInfo, build_summary, write_summary


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
    if not log.is_file():
        raise ValueError(f"no such log file: {log}")
    out_dir.mkdir(parents=True, exist_ok=True)
    size = log.stat().st_size
    nav = NavFilter(config, bridge=make_bridge(bridge, config.bridge))
    decoder = Decoder()
    col = Collector()
    t0 = time.perf_counter()
    done = 0
    for _ts, frame in read_tlog(log):
        done += len(frame) + 8
        col.feed(nav, (d.sample for d in decoder.feed(frame)))
        if progress is not None and done % 65536 < len(frame) + 8:
            progress(done, size)
    wall = time.perf_counter() - t0
    estimate = col.estimate_track()
    truth = col.truth_track()
    end_s = min(estimate.time_s[-1], truth.time_s[-1])
    outages = metrics.outages_from_fix_times(
        np.asarray(col.fix_times_us, dtype=float) * 1e-6, end_s=end_s)
    info = RunInfo(
        scenario=log.stem, seed=None, sim_duration_s=col.last_time_us * 1e-6, wall_s=wall,
        bridge=bridge, altitude=altitude)
    health = nav.health
    summary, err = build_summary(
        info, estimate, truth, outages, settle_s=settle_s,
        health={"filter": plain_dict(health), "decoder": plain_dict(decoder.counters)})
    summary_path = out_dir / "summary.json"
    write_summary(summary, summary_path)
    plots = write_plots(estimate, truth, err, outages, out_dir)
    return ReplayResult(summary, summary_path, plots)


#: Old private name; ``hil.service`` still imports it.
_as_dict = plain_dict
