"""The simulator's scenario timeline as ``scenario/events`` records.

Two sources, both on simulated time:

* ``--gnss-off START:DUR`` windows (:class:`hil.streamer.GnssWindow`, which the streamer
  applies to fixes by time of validity): ``gnss_off`` when a window begins, ``gnss_on`` when
  it ends; ``detail`` = ``{"start_s", "duration_s"}``.
* the fault injector's boundaries (:attr:`hil.pipeline.SimChain.fault_log`, as they happen):
  ``fault_start`` / ``fault_end``; ``detail`` = ``{"type", "phase", "index", "params"}``
  (``params``: the event's own fields, :mod:`sim.faults.events`).

Payload: :func:`hil.bus.event_payload` (``time_us``, ``event``, ``message``, ``detail``).
"""

from __future__ import annotations

from typing import Any

from hil.pipeline import SimSetup
from sim.faults.injector import FaultLogEntry

__all__ = ["ScenarioTimeline"]

Event = tuple[int, str, str, dict[str, Any]]


class ScenarioTimeline:
    """Scenario events due up to a simulated time (each returned once, in time order).

    Parameters
    ----------
    setup : SimSetup
        The flight's setup (GNSS windows, fault events).
    t0_us : int
        Simulated time of the flight's start, us (GNSS windows count from 0, as the streamer
        applies them; faults carry their own boundary times).
    """

    def __init__(self, setup: SimSetup, t0_us: int) -> None:
        self._setup = setup
        self._faults_seen = 0
        pending: list[Event] = []
        for w in setup.gnss_off:
            start_us, end_us = round(w.start_s * 1e6), round((w.start_s + w.duration_s) * 1e6)
            detail = {"start_s": w.start_s, "duration_s": w.duration_s}
            pending.append((start_us, "gnss_off", f"GNSS off for {w.duration_s:g} s", detail))
            pending.append((end_us, "gnss_on", "GNSS on", detail))
        self._pending = sorted(pending, key=lambda e: e[0])
        self.t0_us = t0_us

    def due(self, time_us: int, fault_log: list[FaultLogEntry]) -> list[Event]:
        """Events at or before ``time_us`` not returned yet; ``fault_log`` is the injector's
        log so far (only its new entries are read)."""
        out: list[Event] = []
        while self._pending and self._pending[0][0] <= time_us:
            out.append(self._pending.pop(0))
        faults = self._setup.faults or ()
        for entry in fault_log[self._faults_seen:]:
            params: dict[str, Any] = {}
            if 0 <= entry.index < len(faults):
                params = faults[entry.index].model_dump(mode="json", exclude={"type"})
            out.append((int(entry.time_us), f"fault_{entry.phase}",
                        f"{entry.type_name} {entry.phase}",
                        {"type": entry.type_name, "phase": entry.phase, "index": entry.index,
                         "params": params}))
        self._faults_seen = len(fault_log)
        return out
