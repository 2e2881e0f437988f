"""The live fusion service wired to the scorer: ``hilnav fusion`` (part of the composition root).

:class:`hil.service.FusionService` runs the filter on a live MAVLink link and keeps what it
fused; at exit its scorecard is built by the same scorer as ``hilnav replay``
(:func:`scenarios.summary.score_run`) plus a ``live`` section with the link counters.
"""

from __future__ import annotations

import contextlib
import threading
import time
from collections.abc import Callable
from typing import Any

from hil.bus.security import BusAccess
from hil.live_sim import stop_on_signals
from hil.service import FusionOptions, FusionService
from scenarios.summary import RunInfo, score_run, write_summary


def live_summary(service: FusionService, wall_s: float) -> dict[str, Any] | None:
    """The live run's scorecard, or None without ``--out`` or without estimate + truth."""
    col = service.fusion.collector
    if col is None:
        return None
    o = service.options
    info = RunInfo(scenario="live", seed=None, sim_duration_s=col.last_time_us * 1e-6,
                   wall_s=wall_s, bridge=o.bridge, altitude=o.altitude)
    try:
        # settled as replay settles: the same frames give the same scorecard
        scored = score_run(service.fusion, info, settle_s=o.settle_s, fit_settle=True)
    except ValueError:
        return None
    summary = scored.summary
    summary["live"] = service.live_section()
    return summary


def serve_fusion(
    options: FusionOptions,
    *,
    signing_key: bytes | None = None,
    bus_access: BusAccess | None = None,
    stop: threading.Event | None = None,
    on_ready: Callable[[FusionService], None] | None = None,
) -> dict[str, Any] | None:
    """Run the fusion service until stopped; write ``summary.json`` into ``options.out``.

    Returns
    -------
    dict or None
        The live run's summary (None without ``out`` or without estimate + truth).
    """
    service = FusionService(options, signing_key=signing_key, bus_access=bus_access)
    with contextlib.ExitStack() as stack:
        if stop is None:
            stop = stack.enter_context(stop_on_signals())
        service.open(stack)
        if on_ready is not None:
            on_ready(service)
        t0 = time.monotonic()
        service.run(stop)
        wall = service.wall_s(time.monotonic() - t0)
    try:
        summary = live_summary(service, wall)
    finally:
        if service.fusion.collector is not None:
            service.fusion.collector.close()  # frees the spilled tracks' disk space
    if summary is not None and options.out is not None:
        options.out.mkdir(parents=True, exist_ok=True)
        write_summary(summary, options.out / "summary.json")
    return summary
