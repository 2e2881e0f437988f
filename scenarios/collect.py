"""Run the fusion on a stream of decoded samples and collect estimate and truth tracks.

Shared by ``hilnav replay`` (a recorded log) and the lockstep runners (samples straight from
the simulator through the in-memory MAVLink path).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field

import numpy as np

from fusion import rotations
from fusion.filter import NavEstimate, NavFilter
from scenarios.metrics import Track
from sim.samples import GnssFix, Sample, Truth


@dataclass
class Collector:
    """Accumulates estimates, truth and GNSS fix times as the filter runs."""

    estimates: list[NavEstimate] = field(default_factory=list)
    truths: list[Truth] = field(default_factory=list)
    fix_times_us: list[int] = field(default_factory=list)
    last_time_us: int = 0

    def feed(self, nav: NavFilter, items: Iterable[Sample | Truth]) -> None:
        for item in items:
            self.last_time_us = max(self.last_time_us, item.time_us)
            if isinstance(item, Truth):
                self.truths.append(item)
                continue
            if isinstance(item, GnssFix) and item.fix_type >= 3:
                self.fix_times_us.append(item.time_us)
            self.estimates.extend(nav.step(item))

    def estimate_track(self) -> Track:
        est = [e for e in self.estimates if e.mode != "initializing"]
        if not est:
            raise ValueError("the filter produced no navigation estimate (no valid GNSS fix?)")
        sig = np.array([np.sqrt(np.maximum(e.P_diag[:9], 0.0)) for e in est])
        return Track(
            time_s=np.array([e.time_us for e in est], dtype=float) * 1e-6,
            lat_rad=np.array([e.lat_rad for e in est]),
            lon_rad=np.array([e.lon_rad for e in est]),
            alt_m=np.array([e.alt_msl_m for e in est]),
            v_ned_mps=np.array([e.v_ned_mps for e in est]),
            euler_rad=np.array([e.euler_rad for e in est]),
            sigma=sig,
        )

    def truth_track(self) -> Track:
        if len(self.truths) < 2:
            raise ValueError("the log holds no truth (HIL_STATE_QUATERNION) to score against")
        tr = sorted(self.truths, key=lambda s: s.time_us)
        return Track(
            time_s=np.array([s.time_us for s in tr], dtype=float) * 1e-6,
            lat_rad=np.array([s.lat_rad for s in tr]),
            lon_rad=np.array([s.lon_rad for s in tr]),
            alt_m=np.array([s.alt_msl_m for s in tr]),
            v_ned_mps=np.array([s.v_ned_mps for s in tr]),
            euler_rad=np.array([rotations.quat_to_euler(s.q_nb) for s in tr]),
        )

    def modes(self) -> list[str]:
        return [e.mode for e in self.estimates]
