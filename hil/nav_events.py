"""What the navigation does and detects, as discrete events: mode changes and faults.

:class:`NavEventDetector` watches the stream of :class:`fusion.estimate.NavEstimate` (their
mode and health counters, on the estimate's time) and turns changes into
:class:`NavEvent` records, which the fusion service publishes on ``fusion/events`` and the
shadow vehicle sends as STATUSTEXT. The filter itself stays pure: everything here is derived
from what it already reports.

Events (``event``: severity, when)
    ``mode``              notice/warning: every mode change (``aligned``, ``GNSS lost: ...``,
                          ``GNSS regained``, ``Nav mode: ...``); never rate-limited
    ``gnss_rejected``     debug: a fix rejected by the innovation gate; single rejections
                          come at the gate's own false-alarm rate (0.5 % of fixes at its
                          default probability), so they stay on the bus and never reach a
                          ground station
    ``gnss_rejections_persist`` warning: rejections persist, :attr:`reject_run` fixes in a row
                          without one fused, or :attr:`reject_burst` within
                          :attr:`reject_window_s`; once per episode
    ``gnss_gate_clear``   notice: the episode is over, fixes fused again and none rejected
                          for :attr:`clear_after_s`
    ``spoof_suspected``   critical: fixes keep arriving but every one has been rejected for
                          :attr:`NavEventDetector.spoof_after_s` (a consistency test: it
                          cannot tell a spoofer from a long multipath glitch); once per episode
    ``gnss_reset``        notice: position / velocity reset to GNSS
    ``gnss_reset_refused`` warning: a reset refused because the INS contradicted the fixes
    ``pitot_dropped``     warning: a pitot fault detected (stuck, zero, rejected)
    ``pitot_recovered``   notice: the pitot is trusted again
    ``baro_frozen``       warning: baro readings identical for too long (dropped)
    ``baro_reset``        notice: baro bias re-initialised after a long rejection
    ``imu_invalid``       warning: IMU samples with NaN/Inf or out of range (replaced)
    ``filter_rebase``     error: a new IMU time base; the filter re-initialised

Repeatable events (all but ``mode``, ``spoof_suspected`` and the once-per-episode gate
events) are rate-limited per kind to one per :attr:`NavEventDetector.min_interval_s` of
estimate time; the ones held back are counted in the next one's ``detail["suppressed"]``.

Why the persistence rule's defaults: at 5 fixes a second and a gate that rejects 0.5 % of
good fixes, a run of 3 rejected fixes happens by chance about once in 10^7 fixes (weeks of
flight), and 10 rejections within 20 s (0.5 expected) even less often; a real fault (a glitch,
a spoofer, multipath that lasts) trips either within seconds.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field
from typing import Any, Final

from fusion.estimate import Health, Mode, NavEstimate
from hil.bus.schemas import EVENT_SEVERITIES

__all__ = ["MODE_LABELS", "SEVERITIES", "NavEvent", "NavEventDetector"]

SEVERITIES: Final = EVENT_SEVERITIES
"""Severity names, index = MAVLink ``MAV_SEVERITY`` (0 emergency .. 7 debug)."""

MODE_LABELS: Final = {
    Mode.INITIALIZING: "aligning",
    Mode.GNSS: "GNSS",
    Mode.BRIDGING: "bridging",
    Mode.DEAD_RECKONING: "dead-reckoning",
    Mode.FREE_INERTIAL: "free-inertial",
}
"""Human names of the navigation modes (STATUSTEXT, flight-mode names)."""

_GNSS_LOST_MODES: Final = frozenset({Mode.BRIDGING, Mode.DEAD_RECKONING, Mode.FREE_INERTIAL})

# (counter, event, severity, message) for the counter-driven, rate-limited events
_COUNTER_EVENTS: Final = (
    ("gnss_resets", "gnss_reset", "notice", "GNSS reset: position/velocity reset to GNSS"),
    ("gnss_resets_refused", "gnss_reset_refused", "warning",
     "GNSS reset refused: INS contradicts the fixes"),
    ("airspeed_recoveries", "pitot_recovered", "notice", "Pitot trusted again"),
    ("baro_resets", "baro_reset", "notice", "Baro bias reset after rejections"),
    ("time_rebases", "filter_rebase", "error", "Filter reset: new IMU time base"),
)


@dataclass(frozen=True, slots=True)
class NavEvent:
    """One navigation event (see the module docstring).

    Attributes
    ----------
    time_us : int
        Estimate time of the detection, us.
    event : str
        Kind (``mode``, ``gnss_rejected``, ``spoof_suspected``, ...).
    severity : str
        One of :data:`SEVERITIES` (MAVLink's names, lower case).
    message : str
        Human text, at most 50 characters (one STATUSTEXT).
    detail : dict
        Parameters (mode names, counters, test ratios), JSON-plain.
    """

    time_us: int
    event: str
    severity: str
    message: str
    detail: dict[str, Any] = field(default_factory=dict)

    @property
    def mav_severity(self) -> int:
        """MAVLink ``MAV_SEVERITY`` value of :attr:`severity`."""
        return SEVERITIES.index(self.severity)


class NavEventDetector:
    """Turns successive estimates into :class:`NavEvent` records (see the module docstring).

    Parameters
    ----------
    min_interval_s : float
        Rate limit of the repeatable events, per kind, s of estimate time.
    spoof_after_s : float
        Rejections without a fused fix for this long (fixes still arriving) make
        ``spoof_suspected``, s.
    reject_run : int
        Rejections in a row (no fix fused between them) that make a persistent episode.
    reject_burst, reject_window_s : int, float
        Or this many rejections within this many seconds of estimate time.
    clear_after_s : float
        An episode ends at a fused fix with no rejection for this long, s.
    """

    def __init__(self, *, min_interval_s: float = 5.0, spoof_after_s: float = 3.0,
                 reject_run: int = 3, reject_burst: int = 10, reject_window_s: float = 20.0,
                 clear_after_s: float = 5.0) -> None:
        self.min_interval_s = min_interval_s
        self.spoof_after_s = spoof_after_s
        self.reject_run = reject_run
        self.reject_burst = reject_burst
        self.reject_window_s = reject_window_s
        self.clear_after_s = clear_after_s
        self._run = 0
        self._recent_rejects_us: deque[int] = deque()
        self._persisting = False
        self._mode: Mode | None = None
        self._health: Health | None = None
        self._last_sent_us: dict[str, int] = {}
        self._held: dict[str, int] = {}
        self._last_reject_us: int | None = None
        self._spoof_flagged = False
        self._frozen_episode = False
        self.events: list[NavEvent] = []
        """Every event so far (also returned by :meth:`update`)."""

    def update(self, est: NavEstimate) -> list[NavEvent]:
        """Events made by ``est`` (in order; empty most of the time)."""
        out: list[NavEvent] = []
        t = int(est.time_us)
        mode = Mode(est.mode)
        if mode != self._mode:
            out.append(self._mode_event(t, self._mode, mode))
            self._mode = mode
        h, prev = est.health, self._health
        self._health = h
        if prev is None:
            self.events.extend(out)
            return out
        if h.time_rebases < prev.time_rebases:  # counters never go back: a new filter
            prev = Health()
        if h.gnss_rejected > prev.gnss_rejected:
            self._last_reject_us = t
            ratio = est.test_ratios.gnss_pos
            self._limited(out, t, "gnss_rejected", "debug", "GNSS fix rejected by the gate", {
                "rejected_total": h.gnss_rejected,
                "gnss_pos_test_ratio": ratio if ratio == ratio else None,
            })
        self._gate_episode(out, t, h.gnss_rejected - prev.gnss_rejected,
                           h.gnss_fused > prev.gnss_fused)
        if h.gnss_fused > prev.gnss_fused:
            self._spoof_flagged = False
        since_s = float(est.time_since_gnss_s)
        arriving = self._last_reject_us is not None and t - self._last_reject_us <= 1_000_000
        if (not self._spoof_flagged and arriving and since_s >= self.spoof_after_s
                and h.gnss_fused > 0):
            self._spoof_flagged = True
            out.append(NavEvent(t, "spoof_suspected", "critical",
                                f"GNSS spoofing suspected: fixes rejected {since_s:.0f} s",
                                {"time_since_gnss_s": since_s, "rejected_total": h.gnss_rejected}))
        for counter, event, severity, message in _COUNTER_EVENTS:
            if getattr(h, counter) > getattr(prev, counter):
                self._limited(out, t, event, severity, message, {counter: getattr(h, counter)})
        if h.airspeed_blockages > prev.airspeed_blockages:
            fault = est.air_data.fault if est.air_data is not None else ""
            self._limited(out, t, "pitot_dropped", "warning",
                          f"Pitot dropped: {fault or 'fault'}",
                          {"fault": fault, "blockages": h.airspeed_blockages})
        if h.baro_frozen > prev.baro_frozen:
            if not self._frozen_episode:
                self._limited(out, t, "baro_frozen", "warning", "Baro frozen: readings dropped",
                              {"baro_frozen": h.baro_frozen})
            self._frozen_episode = True
        elif h.baro_fused > prev.baro_fused:
            self._frozen_episode = False
        bad_imu = h.imu_nan + h.imu_out_of_range
        if bad_imu > prev.imu_nan + prev.imu_out_of_range:
            self._limited(out, t, "imu_invalid", "warning", "IMU samples invalid (replaced)",
                          {"imu_nan": h.imu_nan, "imu_out_of_range": h.imu_out_of_range})
        self.events.extend(out)
        return out

    def _gate_episode(self, out: list[NavEvent], t: int, rejected: int, fused: bool) -> None:
        """Persistent rejections: one warning when an episode starts, one notice when it ends."""
        if fused:
            self._run = 0
        self._run += rejected
        self._recent_rejects_us.extend([t] * rejected)
        while self._recent_rejects_us and (
                t - self._recent_rejects_us[0] > self.reject_window_s * 1e6):
            self._recent_rejects_us.popleft()
        burst = len(self._recent_rejects_us)
        if not self._persisting and (self._run >= self.reject_run or burst >= self.reject_burst):
            self._persisting = True
            why = (f"{self._run} in a row" if self._run >= self.reject_run
                   else f"{burst} in {self.reject_window_s:g} s")
            out.append(NavEvent(t, "gnss_rejections_persist", "warning",
                                f"GNSS fixes rejected: {why}",
                                {"in_a_row": self._run, "in_window": burst,
                                 "window_s": self.reject_window_s}))
        elif (self._persisting and fused and self._last_reject_us is not None
              and t - self._last_reject_us >= self.clear_after_s * 1e6):
            self._persisting = False
            self._recent_rejects_us.clear()  # a new episode needs new rejections
            out.append(NavEvent(t, "gnss_gate_clear", "notice", "GNSS fixes accepted again",
                                {"clear_after_s": self.clear_after_s}))

    def _mode_event(self, t: int, old: Mode | None, new: Mode) -> NavEvent:
        label = MODE_LABELS[new]
        detail = {"from": None if old is None else str(old), "to": str(new)}
        if old is None and new == Mode.INITIALIZING:
            return NavEvent(t, "mode", "info", f"Nav mode: {label}", detail)
        if old is None or old == Mode.INITIALIZING:  # the first estimate may come aligned
            return NavEvent(t, "mode", "notice", f"Nav aligned: {label}", detail)
        if old == Mode.GNSS and new in _GNSS_LOST_MODES:
            return NavEvent(t, "mode", "warning", f"GNSS lost: {label}", detail)
        if new == Mode.GNSS:
            return NavEvent(t, "mode", "notice", "GNSS regained", detail)
        severity = "warning" if new in _GNSS_LOST_MODES else "notice"
        return NavEvent(t, "mode", severity, f"Nav mode: {label}", detail)

    def _limited(self, out: list[NavEvent], t: int, event: str, severity: str, message: str,
                 detail: dict[str, Any]) -> None:
        last = self._last_sent_us.get(event)
        if last is not None and t - last < self.min_interval_s * 1e6:
            self._held[event] = self._held.get(event, 0) + 1
            return
        self._last_sent_us[event] = t
        held = self._held.pop(event, 0)
        out.append(NavEvent(t, event, severity, message, {**detail, "suppressed": held}))
