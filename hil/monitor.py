"""``hilnav monitor``: live dashboard of one vehicle's Zenoh topics, and an MCAP recorder.

The dashboard (``rich.live``) shows the filter mode, the position, the errors against truth,
the GNSS outage timer, innovation test ratios and the health of every link (message rates, age
of the last message, MAVLink link and Zenoh bus counters, the fusion service's liveliness
token). Without a terminal (``--headless``, containers, CI) it prints one line per second.

``--record FILE.mcap`` writes every sample of the vehicle's subtree to MCAP: one channel per
key (``hilnav/<vehicle>/<topic>``), message encoding ``json``, each channel carrying its
topic's JSON Schema (encoding ``jsonschema``, :data:`hil.bus.SCHEMAS`), so Foxglove Studio and
PlotJuggler replay it as is. ``log_time`` is the wall-clock receive time; the simulated time is
the payload's ``time_us``.
"""

from __future__ import annotations

import json
import math
import signal
import sys
import threading
import time
from collections import deque
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import IO, Any, Final, Self

from mcap.writer import CompressionType, Writer
from rich.console import Console, Group
from rich.live import Live
from rich.table import Table
from rich.text import Text

from hil.bus import (
    PUBLISHED_TOPICS,
    SCHEMA_VERSION,
    SCHEMAS,
    Bus,
    BusStats,
    Message,
    Topic,
    validate_vehicle,
)

__all__ = ["McapRecorder", "MonitorState", "monitor_main"]

_RATE_WINDOW_S: Final = 2.0
_MODE_STYLE: Final = {
    "gnss": "bold green",
    "bridging": "bold yellow",
    "free-inertial": "bold red",
    "initializing": "cyan",
}


class McapRecorder:
    """Write :class:`hil.bus.Message` s to an MCAP file (thread-safe).

    Parameters
    ----------
    path : Path
        Output file (overwritten). Its folder must exist.
    metadata : mapping of str -> str, optional
        Written as an MCAP metadata record named ``hilnav``.

    Attributes
    ----------
    messages : int
        Messages written.
    skipped : int
        Samples not written because their payload is not a JSON object.
    """

    def __init__(self, path: Path, *, metadata: Mapping[str, str] | None = None) -> None:
        path = Path(path)
        if not path.parent.is_dir():
            raise ValueError(f"record: folder {path.parent} does not exist")
        self.path = path
        self._file: IO[bytes] = path.open("wb")
        self._writer = Writer(self._file, chunk_size=256 * 1024, compression=CompressionType.ZSTD)
        self._writer.start(profile="", library="hilnav")
        self._writer.add_metadata(
            "hilnav", {"schema_version": str(SCHEMA_VERSION), **dict(metadata or {})}
        )
        self._lock = threading.Lock()
        self._schemas: dict[Topic, int] = {}
        self._channels: dict[str, int] = {}
        self._sequence: dict[int, int] = {}
        self._closed = False
        self.messages = 0
        self.skipped = 0

    def _channel(self, msg: Message) -> int:
        cid = self._channels.get(msg.key)
        if cid is not None:
            return cid
        schema_id = 0  # 0 = no schema (a key outside the key space)
        if msg.topic is not None:
            schema_id = self._schemas.get(msg.topic, 0)
            if schema_id == 0:
                schema = SCHEMAS[msg.topic]
                schema_id = self._writer.register_schema(
                    name=schema["title"],
                    encoding="jsonschema",
                    data=json.dumps(schema).encode(),
                )
                self._schemas[msg.topic] = schema_id
        cid = self._writer.register_channel(
            topic=msg.key, message_encoding="json", schema_id=schema_id, metadata={}
        )
        self._channels[msg.key] = cid
        return cid

    def write(self, msg: Message) -> None:
        """Append one received sample (ignored after :meth:`close`)."""
        with self._lock:
            if self._closed:
                return
            if msg.payload is None:
                self.skipped += 1
                return
            cid = self._channel(msg)
            seq = self._sequence.get(cid, 0)
            self._sequence[cid] = seq + 1
            self._writer.add_message(
                channel_id=cid,
                log_time=msg.received_ns,
                data=msg.raw,
                publish_time=msg.received_ns,
                sequence=seq,
            )
            self.messages += 1

    @property
    def topics(self) -> list[str]:
        """Keys recorded so far."""
        with self._lock:
            return sorted(self._channels)

    def close(self) -> None:
        """Write the summary section and close the file (idempotent)."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
            self._writer.finish()
            self._file.close()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *_exc: object) -> None:
        self.close()


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
            if mode in ("bridging", "free-inertial")
            else (f"gnss age {_f(since, '.1f', ' s')}")
        )
        alive = {None: "?", True: "yes", False: "NO"}[self.alive]
        return (
            f"[{self._clock() - self.started:7.1f} s] {self.vehicle} t={_f(t_s, '.1f', ' s')} "
            f"mode={mode} lat={_f(est.get('lat_deg'), '.6f')} lon={_f(est.get('lon_deg'), '.6f')} "
            f"alt={_f(est.get('alt_msl_m'), '.1f', ' m')} | "
            f"err h={_f(err.get('horizontal_error_m'), '.2f')} "
            f"v={_f(err.get('vertical_error_m'), '.2f')} m | {outage} | "
            f"est {self.rate_hz(Topic.ESTIMATE):.1f} Hz | fusion alive={alive} "
            f"router={'up' if self.connected else 'DOWN'}{self._link_summary()}"
        )

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
            f"fusion {alive}  up {self._clock() - self.started:.0f} s"
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
        in_outage = mode in ("bridging", "free-inertial")
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


def monitor_main(
    *,
    connect: str,
    vehicle: str,
    record: Path | None,
    duration_s: float | None,
    headless: bool,
) -> int:
    """Subscribe to ``hilnav/<vehicle>/**`` and show it; optionally record it to MCAP.

    Parameters
    ----------
    connect : str
        Zenoh router endpoint, e.g. ``tcp/127.0.0.1:7447``. The monitor keeps running (and
        says "no router") until the router answers, and reconnects when it restarts.
    vehicle : str
        Vehicle key chunk.
    record : Path, optional
        MCAP file to write (overwritten); its folder must exist.
    duration_s : float, optional
        Stop after this many wall-clock seconds (None: until Ctrl-C / SIGTERM).
    headless : bool
        One text line per second instead of the live table (also used when stdout is not a
        terminal).

    Returns
    -------
    int
        0 after a clean stop. Bad input raises ``ValueError``.
    """
    validate_vehicle(vehicle)
    if duration_s is not None and not (math.isfinite(duration_s) and duration_s > 0.0):
        raise ValueError(f"duration must be > 0 s, got {duration_s}")
    if record is not None and Path(record).suffix.lower() != ".mcap":
        raise ValueError(f"record: expected a .mcap file name, got {record}")
    console = Console()
    live_table = not headless and console.is_terminal
    state = MonitorState(vehicle)
    stop = threading.Event()
    previous = None
    if threading.current_thread() is threading.main_thread():
        # `docker stop` sends SIGTERM: finish the MCAP file instead of dying mid-chunk
        previous = signal.signal(signal.SIGTERM, lambda *_: stop.set())
    recorder = (
        McapRecorder(Path(record), metadata={"vehicle": vehicle, "connect": connect})
        if record is not None
        else None
    )

    def on_message(msg: Message) -> None:
        state.ingest(msg)
        if recorder is not None:
            recorder.write(msg)

    deadline = None if duration_s is None else time.monotonic() + duration_s
    try:
        with Bus(connect, vehicle=vehicle) as bus:
            bus.subscribe("**", on_message)
            bus.subscribe_liveliness(state.set_alive)
            if live_table:
                with Live(state.render(), console=console, refresh_per_second=4) as live:
                    while _wait(stop, deadline, 0.25):
                        state.set_bus(bus.stats())
                        live.update(state.render())
            else:
                while _wait(stop, deadline, 1.0):
                    state.set_bus(bus.stats())
                    print(state.summary_line(), flush=True)
    except KeyboardInterrupt:
        pass
    finally:
        if recorder is not None:
            recorder.close()
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)
    total = sum(state.counts.values())
    print(f"received {total} messages on {len(state.counts)} topics", file=sys.stderr)
    if recorder is not None:
        print(
            f"recorded {recorder.messages} messages on {len(recorder.topics)} channels -> "
            f"{recorder.path}",
            file=sys.stderr,
        )
    return 0


def _wait(stop: threading.Event, deadline: float | None, period_s: float) -> bool:
    """Sleep one display period; False when it is time to stop."""
    if deadline is not None:
        period_s = min(period_s, deadline - time.monotonic())
        if period_s <= 0.0:
            return False
    return not stop.wait(period_s)
