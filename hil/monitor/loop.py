"""``hilnav monitor``: subscribe to one vehicle's topics, show them, optionally record them.

Without a terminal (``headless``, containers, CI) the dashboard prints one line per second;
``record`` writes every sample of the vehicle's subtree to MCAP (:mod:`hil.monitor.recorder`);
``foxglove_port`` streams them live to Foxglove (:mod:`hil.monitor.foxglove_server`).
"""

from __future__ import annotations

import math
import signal
import sys
import threading
import time
from pathlib import Path

from rich.console import Console
from rich.live import Live

from hil.bus import Bus, BusAccess, BusConfig, Message, validate_vehicle
from hil.monitor.dashboard import MonitorState
from hil.monitor.foxglove_server import FoxgloveLive
from hil.monitor.recorder import McapRecorder

__all__ = ["monitor_main"]

_CHALLENGE_PERIOD_S = 2.0


def monitor_main(
    *,
    connect: str,
    vehicle: str,
    record: Path | None,
    duration_s: float | None,
    headless: bool,
    foxglove_port: int | None = None,
    bus_access: BusAccess | None = None,
    peer: bool = False,
    low_latency: bool = False,
) -> int:
    """Subscribe to ``hilnav/<vehicle>/**`` and show it; optionally record it to MCAP.

    Parameters
    ----------
    connect : str
        Zenoh router endpoint, e.g. ``tcp/127.0.0.1:7447``. The monitor keeps running (and
        says "no router") until the router answers, and reconnects when it restarts. With
        ``peer``: a fusion's ``--zenoh-listen`` endpoint.
    vehicle : str
        Vehicle key chunk.
    record : Path, optional
        MCAP file to write (overwritten); its folder must exist.
    duration_s : float, optional
        Stop after this many wall-clock seconds (None: until Ctrl-C / SIGTERM).
    headless : bool
        One text line per second instead of the live table (also used when stdout is not a
        terminal).
    foxglove_port : int, optional
        Serve a Foxglove WebSocket on ``127.0.0.1:<port>`` (0: a free port) streaming the same
        channels as the recording; the URL is printed.
    peer : bool
        Subscribe as a Zenoh peer connected directly to ``connect`` (peer-to-peer mode).
    low_latency : bool
        Ask for Zenoh's low-latency transport (:attr:`hil.bus.BusConfig.low_latency`; pays
        off with a fusion started with ``--zenoh-low-latency``).

    Returns
    -------
    int
        0 after a clean stop. Bad input raises ``ValueError``.
    """
    validate_vehicle(vehicle)
    if foxglove_port is not None and not 0 <= foxglove_port <= 65535:
        raise ValueError(f"foxglove port must be 0..65535, got {foxglove_port}")
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
    live_fox = None
    if foxglove_port is not None:
        try:
            live_fox = FoxgloveLive(foxglove_port)
        except Exception as exc:  # the SDK raises its own error types for a busy port
            if recorder is not None:
                recorder.close()
            raise ValueError(f"foxglove: cannot serve on port {foxglove_port}: {exc}") from None
        print(f"foxglove: open connection -> Foxglove WebSocket {live_fox.url}", flush=True)

    def on_message(msg: Message) -> None:
        state.ingest(msg)
        if recorder is not None:
            recorder.write(msg)
        if live_fox is not None:
            live_fox.write(msg)

    deadline = None if duration_s is None else time.monotonic() + duration_s
    try:
        access = bus_access or BusAccess()
        with Bus(connect, vehicle=vehicle, mode="peer" if peer else "client",
                 config=BusConfig(low_latency=low_latency), security=access.security,
                 auth_key=access.auth_key) as bus:
            bus.subscribe("**", on_message)
            bus.subscribe_liveliness(state.set_alive)
            done = threading.Event()
            challenger = threading.Thread(target=_challenge_fusion, args=(bus, state, done),
                                          name="hilnav-monitor-challenge", daemon=True)
            if bus.authenticated:
                challenger.start()
            try:
                if live_table:
                    with Live(state.render(), console=console, refresh_per_second=4) as live:
                        while _wait(stop, deadline, 0.25):
                            state.set_bus(bus.stats())
                            live.update(state.render())
                else:
                    while _wait(stop, deadline, 1.0):
                        state.set_bus(bus.stats())
                        print(state.summary_line(), flush=True)
            finally:
                done.set()
                if challenger.is_alive():
                    challenger.join(timeout=5.0)
    except KeyboardInterrupt:
        pass
    finally:
        if recorder is not None:
            recorder.close()
        if live_fox is not None:
            live_fox.close()
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


def _challenge_fusion(bus: Bus, state: MonitorState, stop: threading.Event) -> None:
    """With the shared key: every few seconds, ask the token's owner to answer a challenge, so
    a token declared by anyone else shows as UNVERIFIED."""
    while not stop.is_set():
        if state.alive:
            try:
                state.set_verified(bus.verify_fusion(timeout_s=1.0))
            except Exception:  # the bus closing under us at shutdown
                return
        else:
            state.set_verified(None)
        stop.wait(_CHALLENGE_PERIOD_S)


def _wait(stop: threading.Event, deadline: float | None, period_s: float) -> bool:
    """Sleep one display period; False when it is time to stop."""
    if deadline is not None:
        period_s = min(period_s, deadline - time.monotonic())
        if period_s <= 0.0:
            return False
    return not stop.wait(period_s)
