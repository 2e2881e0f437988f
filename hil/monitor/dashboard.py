"""Live dashboard of one vehicle: what the monitor knows from the bus, as a table or one line.

The dashboard (``rich``) shows the filter mode, the position, the errors against truth, the
GNSS outage timer, innovation test ratios and the health of every link (message rates, age of
the last message, MAVLink link and Zenoh bus counters, the fusion service's liveliness token);
:meth:`MonitorState.summary_line` is the one-line form for a headless monitor.
"""

from __future__ import annotations

import math
import threading
import time
from collections import deque
from collections.abc import Callable
from typing import Any, Final

from rich.console import Group
from rich.table import Table
from rich.text import Text

from hil.bus import PUBLISHED_TOPICS, BusStats, Message, Topic

__all__ = ["MonitorState"]

_RATE_WINDOW_S: Final = 2.0
_MODE_STYLE: Final = {
    "gnss": "bold green",
    "bridging": "bold yellow",
    "free-inertial": "bold red",
    "dead-reckoning": "bold yellow",
    "initializing": "cyan",
}



def _f(v: Any, spec: str = ".2f", unit: str = "") -> str:
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "-"
    try:
        return f"{format(v, spec)}{unit}"
    except (TypeError, ValueError):
        return str(v)


class MonitorState:
    """What the dashboard knows about one vehicle, fed by bus callbacks (thread-safe).

    Parameters
    ----------
    vehicle : str
    clock : callable
        Monotonic seconds (injectable for tests).
    """

    def __init__(self, vehicle: str, *, clock: Callable[[], float] = time.monotonic) -> None:
        self.vehicle = vehicle
        self._clock = clock
        self._lock = threading.Lock()
        self.started = clock()
        self.latest: dict[Topic, dict[str, Any]] = {}
        self.counts: dict[Topic, int] = {}
        self.last_seen: dict[Topic, float] = {}
        self._arrivals: dict[Topic, deque[float]] = {}
        self.alive: bool | None = None
        self.verified: bool | None = None
        """With the shared key: whether the token's owner answered the challenge (None: not
        checked)."""
        self.connected = False
        self.bus_stats: BusStats | None = None
        self.unknown = 0
        self.last_event: dict[str, Any] | None = None

    def ingest(self, msg: Message) -> None:
        """Take one received sample."""
        now = self._clock()
        with self._lock:
            if msg.topic is None or msg.payload is None or msg.vehicle != self.vehicle:
                self.unknown += 1
                return
            t = msg.topic
            self.latest[t] = msg.payload
            self.counts[t] = self.counts.get(t, 0) + 1
            self.last_seen[t] = now
            q = self._arrivals.setdefault(t, deque())
            q.append(now)
            while q and q[0] < now - _RATE_WINDOW_S:
                q.popleft()
            if t is Topic.EVENTS:
                self.last_event = msg.payload

    def set_alive(self, _key: str, alive: bool) -> None:
        """Liveliness callback of the fusion service's token."""
        with self._lock:
            self.alive = alive

    def set_verified(self, verified: bool | None) -> None:
        """Result of the last challenge of the fusion (:meth:`hil.bus.Bus.verify_fusion`)."""
        with self._lock:
            self.verified = verified

    def _verified_text(self) -> str:
        return {None: "", True: " verified", False: " UNVERIFIED"}[self.verified]

    def set_bus(self, stats: BusStats) -> None:
        """The monitor's own bus counters (router connection)."""
        with self._lock:
            self.bus_stats = stats
            self.connected = stats.connected

    def rate_hz(self, topic: Topic) -> float:
        """Messages per second of ``topic`` over the last two seconds."""
        now = self._clock()
        with self._lock:
            q = self._arrivals.get(topic)
            if not q:
                return 0.0
            n = sum(1 for t in q if t >= now - _RATE_WINDOW_S)
        return n / _RATE_WINDOW_S

    def age_s(self, topic: Topic) -> float | None:
        """Seconds since the last message of ``topic`` (None: never)."""
        with self._lock:
            seen = self.last_seen.get(topic)
        return None if seen is None else self._clock() - seen

    def _get(self, topic: Topic) -> dict[str, Any]:
        with self._lock:
            return dict(self.latest.get(topic, {}))

    def _mode_and_outage(self) -> tuple[str, float | None]:
        est, status = self._get(Topic.ESTIMATE), self._get(Topic.STATUS)
        mode = est.get("mode") or status.get("mode") or "-"
        since = est.get("time_since_gnss_s")
        if since is None:
            since = status.get("time_since_gnss_s")
        return str(mode), since

    def summary_line(self) -> str:
        """One line for headless mode."""
        est, err = self._get(Topic.ESTIMATE), self._get(Topic.ERROR)
        mode, since = self._mode_and_outage()
        t_s = est.get("time_us", 0) / 1e6 if est else None
        outage = (
            f"OUTAGE {_f(since, '.1f', ' s')}"
            if mode in ("bridging", "free-inertial", "dead-reckoning")
            else (f"gnss age {_f(since, '.1f', ' s')}")
        )
        alive = {None: "?", True: "yes", False: "NO"}[self.alive]
        return (
            f"[{self._clock() - self.started:7.1f} s] {self.vehicle} t={_f(t_s, '.1f', ' s')} "
            f"mode={mode} lat={_f(est.get('lat_deg'), '.6f')} lon={_f(est.get('lon_deg'), '.6f')} "
            f"alt={_f(est.get('alt_msl_m'), '.1f', ' m')} | "
            f"err h={_f(err.get('horizontal_error_m'), '.2f')} "
            f"v={_f(err.get('vertical_error_m'), '.2f')} m | {outage} | "
            f"est {self.rate_hz(Topic.ESTIMATE):.1f} Hz | fusion alive={alive}"
            f"{self._verified_text()} "
            f"router={'up' if self.connected else 'DOWN'}{self._link_summary()}"
            f"{self._rejected_summary()}"
        )

    def _rejected_summary(self) -> str:
        """Samples the bus dropped for a missing / wrong HMAC tag or a replay (shared key)."""
        stats = self.bus_stats
        if stats is None or not (stats.unauthenticated or stats.replayed):
            return ""
        return f" | REJECTED forged {stats.unauthenticated} replayed {stats.replayed}"

    def _link_summary(self) -> str:
        """MAVLink frames lost / dropped and Zenoh drops reported in the last status."""
        status = self._get(Topic.STATUS)
        parts = []
        for name, c in (status.get("links") or {}).items():
            if isinstance(c, dict):
                dropped = c.get("received", 0) - c.get("accepted", 0)
                parts.append(f"{name} lost={c.get('lost_seq', 0)} drop={dropped}")
        bus = status.get("bus") or {}
        if bus:
            parts.append(f"zenoh drop={bus.get('dropped_queue_full', 0)}")
        return (" | " + " ".join(parts)) if parts else ""

    def render(self) -> Group:
        """The dashboard as a rich renderable."""
        est, err, status = (
            self._get(Topic.ESTIMATE),
            self._get(Topic.ERROR),
            self._get(Topic.STATUS),
        )
        truth = self._get(Topic.TRUTH)
        mode, since = self._mode_and_outage()
        alive = {None: "unknown", True: "[green]alive[/]", False: "[red]GONE[/]"}[self.alive]
        router = "[green]connected[/]" if self.connected else "[red]no router[/]"
        head = Text.from_markup(
            f"[bold]hilnav monitor[/]  vehicle [bold]{self.vehicle}[/]  router {router}  "
            f"fusion {alive}{self._verified_text().replace('UNVERIFIED', '[red]UNVERIFIED[/]')}"
            f"  up {self._clock() - self.started:.0f} s"
            + self._rejected_summary().replace("REJECTED", "[red]REJECTED[/]")
        )

        nav = Table(title="navigation", show_header=False, expand=True)
        nav.add_column("field", style="dim")
        nav.add_column("value")
        nav.add_row("mode", Text(mode, style=_MODE_STYLE.get(mode, "")))
        nav.add_row("sim time", _f(est.get("time_us", 0) / 1e6 if est else None, ".1f", " s"))
        nav.add_row(
            "lat / lon", f"{_f(est.get('lat_deg'), '.6f')} / {_f(est.get('lon_deg'), '.6f')} deg"
        )
        nav.add_row("alt MSL", _f(est.get("alt_msl_m"), ".1f", " m"))
        v = est.get("v_ned_mps") or [None] * 3
        gs = math.hypot(v[0], v[1]) if None not in v[:2] else None
        nav.add_row("ground speed / vd", f"{_f(gs, '.1f')} / {_f(v[2], '.1f')} m/s")
        nav.add_row(
            "roll / pitch / yaw",
            f"{_f(est.get('roll_deg'), '.1f')} / {_f(est.get('pitch_deg'), '.1f')} / "
            f"{_f(est.get('yaw_deg'), '.1f')} deg",
        )
        sd = est.get("pos_sigma_ned_m") or [None] * 3
        nav.add_row("1-sigma N/E/D", " / ".join(_f(x, ".2f") for x in sd) + " m")
        if truth:
            nav.add_row("truth alt", _f(truth.get("alt_msl_m"), ".1f", " m"))

        errs = Table(title="errors vs truth", show_header=False, expand=True)
        errs.add_column("field", style="dim")
        errs.add_column("value")
        errs.add_row("horizontal", _f(err.get("horizontal_error_m"), ".2f", " m"))
        errs.add_row("vertical", _f(err.get("vertical_error_m"), ".2f", " m"))
        dv = err.get("vel_error_ned_mps")
        errs.add_row(
            "velocity", _f(math.sqrt(sum(x * x for x in dv)) if dv else None, ".2f", " m/s")
        )
        errs.add_row("yaw", _f(err.get("yaw_error_deg"), ".2f", " deg"))
        errs.add_row("attitude", _f(err.get("att_error_deg"), ".2f", " deg"))
        in_outage = mode in ("bridging", "free-inertial", "dead-reckoning")
        errs.add_row(
            "GNSS outage" if in_outage else "last GNSS fix",
            Text(_f(since, ".1f", " s"), style="bold red" if in_outage else ""),
        )
        ratios = status.get("test_ratios") or {}
        errs.add_row(
            "test ratios", ", ".join(f"{k} {_f(r, '.2f')}" for k, r in ratios.items()) or "-"
        )
        if self.last_event:
            errs.add_row(
                "last event",
                f"{self.last_event.get('event')} @ {self.last_event.get('time_us', 0) / 1e6:.1f} s",
            )

        links = Table(title="link health", expand=True)
        links.add_column("topic")
        links.add_column("rate", justify="right")
        links.add_column("age", justify="right")
        links.add_column("count", justify="right")
        for topic in PUBLISHED_TOPICS:
            n = self.counts.get(topic, 0)
            if n == 0:
                continue
            age = self.age_s(topic)
            links.add_row(
                topic.value,
                f"{self.rate_hz(topic):.1f} Hz",
                Text(_f(age, ".1f", " s"), style="red" if age is not None and age > 3.0 else ""),
                str(n),
            )
        for name, c in (status.get("links") or {}).items():
            if isinstance(c, dict):
                dropped = c.get("received", 0) - c.get("accepted", 0)
                links.add_row(
                    f"mavlink {name}",
                    f"ok {c.get('accepted', '-')}",
                    f"lost {c.get('lost_seq', '-')}",
                    f"drop {dropped} crc {c.get('bad_crc', '-')}",
                )
        bus = status.get("bus") or {}
        if bus:
            links.add_row(
                "fusion zenoh bus",
                f"pub {bus.get('published', '-')}",
                f"unrouted {bus.get('unrouted', '-')}",
                f"drop {bus.get('dropped_queue_full', '-')}",
            )
        grid = Table.grid(expand=True)
        grid.add_column()
        grid.add_column()
        grid.add_row(nav, errs)
        return Group(head, grid, links)
