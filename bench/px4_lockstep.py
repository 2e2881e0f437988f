"""Benchmark: PX4 lockstep over loopback TCP.

What the simulator side (``hil.autopilot.px4.Px4Backend`` in ``fly_with_autopilot``) adds per
lockstep step, and how fast a lockstep flight runs against the PX4 protocol peer:

1. **No protocol** (the reference): the same loop, flight and sensor chain with an in-process
   backend that holds the trim and sends nothing (``fly_with_autopilot`` with ``controls() ->
   []``, ``send()`` a no-op).
2. **Null PX4**: ``Px4Backend`` on ``tcpin:127.0.0.1:0`` against a minimal PX4 side in a child
   process (TCP client, ``TCP_NODELAY``, HEARTBEAT, then one HIL_ACTUATOR_CONTROLS with the
   lockstep flag per HIL_SENSOR, disarmed so the aircraft holds its trim, nothing else): the
   pace is set by the simulator side.
3. **The protocol peer**: the same against ``tests/helpers/px4_peer.py`` (estimator,
   controller, telemetry off) in a child process: a Python stand-in for PX4 SITL.

Per run: steps/s, wall ms per step, the simulator thread's CPU ms per step
(``time.thread_time``; waiting in ``select`` costs none), and the time spent inside the
backend's ``send`` / ``controls`` calls. **Added by the simulator side** = the simulator
thread's CPU per step in (2) minus (1) (target <= 0.3 ms: then PX4, not hilnav, sets the
pace); the wall difference (2) - (1) also contains the peer's turn-around on loopback.
The 2-core machine is shared: load averages before and after are recorded.

    python bench/px4_lockstep.py --out bench/results/px4_lockstep.json
"""

from __future__ import annotations

import argparse
import json
import math
import multiprocessing
import os
import platform
import socket
import sys
import threading
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from hil.autopilot import AutopilotBackend, fly_with_autopilot  # noqa: E402
from hil.autopilot.px4 import Px4Backend  # noqa: E402
from hil.pipeline import SimSetup, SimStep  # noqa: E402


class _HoldTrim:
    name = "no protocol"

    def wait_connected(self, timeout_s: float, stop: threading.Event) -> bool:
        return True

    def controls(self, timeout_s: float) -> Sequence[float] | None:
        return []

    def send(self, step: SimStep) -> None:
        pass

    def counters(self) -> dict[str, int]:
        return {}


class _Timed:
    """Wraps a backend and adds up the wall time spent in its calls."""

    def __init__(self, inner: Any) -> None:
        self.inner = inner
        self.name = inner.name
        self.send_s = self.controls_s = 0.0

    def wait_connected(self, timeout_s: float, stop: threading.Event) -> bool:
        ok: bool = self.inner.wait_connected(timeout_s, stop)
        return ok

    def controls(self, timeout_s: float) -> Sequence[float] | None:
        t0 = time.perf_counter()
        out: Sequence[float] | None = self.inner.controls(timeout_s)
        self.controls_s += time.perf_counter() - t0
        return out

    def send(self, step: SimStep) -> None:
        t0 = time.perf_counter()
        self.inner.send(step)
        self.send_s += time.perf_counter() - t0

    def counters(self) -> dict[str, int]:
        out: dict[str, int] = self.inner.counters()
        return out


def _null_px4(port: int) -> None:
    """A minimal PX4 side: one lockstep HIL_ACTUATOR_CONTROLS per HIL_SENSOR id 0."""
    from hil.codec import mavlink2

    mav = mavlink2.MAVLink(None, srcSystem=1, srcComponent=1)
    sock = socket.create_connection(("127.0.0.1", port))
    sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    sock.sendall(mavlink2.MAVLink_heartbeat_message(0, 12, 0, 0, 0, 3).pack(mav))
    controls = [0.0] * 16  # disarmed (mode 1: custom, not armed): the backend holds the trim
    while True:
        data = sock.recv(65536)
        if not data:
            return
        for msg in mav.parse_buffer(data) or []:
            if msg.get_type() == "HIL_SENSOR" and msg.id == 0:
                reply = mavlink2.MAVLink_hil_actuator_controls_message(
                    msg.time_usec, controls, 1, 1)
                sock.sendall(reply.pack(mav))


def _protocol_peer(port: int) -> None:
    from tests.helpers.px4_peer import Px4Peer

    peer = Px4Peer(f"tcp:127.0.0.1:{port}", outputs="legacy").start()
    assert peer._thread is not None
    peer._thread.join()


def _run(setup: SimSetup, backend: AutopilotBackend, timed: _Timed | None) -> dict[str, Any]:
    cpu0 = time.thread_time()
    flown = fly_with_autopilot(setup, timed or backend, stall_timeout_s=30.0,
                               connect_timeout_s=60.0)
    cpu = time.thread_time() - cpu0
    steps = max(flown.steps, 1)
    out: dict[str, Any] = {
        "steps": flown.steps, "sim_duration_s": flown.sim_duration_s, "wall_s": flown.wall_s,
        "steps_per_s": flown.steps / flown.wall_s,
        "realtime_factor": flown.realtime_factor,
        "wall_ms_per_step": 1e3 * flown.wall_s / steps,
        "sim_thread_cpu_ms_per_step": 1e3 * cpu / steps,
        "stalled": flown.stalled, "ended": None if flown.ended is None else str(flown.ended),
        "counters": flown.counters,
    }
    if timed is not None:
        out["in_send_ms_per_step"] = 1e3 * timed.send_s / steps
        out["in_controls_ms_per_step"] = 1e3 * timed.controls_s / steps
    return out


def _with_peer(setup: SimSetup, target: Any) -> dict[str, Any]:
    ctx = multiprocessing.get_context("spawn")
    with Px4Backend("tcpin:127.0.0.1:0") as backend:
        proc = ctx.Process(target=target, args=(backend.local_address[1],), daemon=True)
        proc.start()
        try:
            return _run(setup, backend, _Timed(backend))
        finally:
            backend.close()
            proc.join(timeout=10)
            if proc.is_alive():
                proc.terminate()  # by its own handle (PID), never by name
                proc.join(timeout=5)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=60.0, help="simulated s per run")
    parser.add_argument("--rate", type=float, default=200.0, help="step (IMU) rate, Hz")
    parser.add_argument("--out", type=Path, default=REPO / "bench/results/px4_lockstep.json")
    args = parser.parse_args()
    setup = SimSetup.build(duration_s=args.duration, rate_hz=args.rate, seed=1)
    load_before = os.getloadavg()
    plain = _run(setup, _HoldTrim(), None)
    null = _with_peer(setup, _null_px4)
    peer = _with_peer(setup, _protocol_peer)
    load_after = os.getloadavg()
    added_cpu = null["sim_thread_cpu_ms_per_step"] - plain["sim_thread_cpu_ms_per_step"]
    added_wall = null["wall_ms_per_step"] - plain["wall_ms_per_step"]
    result = {
        "command": f"python bench/px4_lockstep.py --duration {args.duration:g} "
                   f"--rate {args.rate:g}",
        "machine": {"python": platform.python_version(), "cpus": os.cpu_count(),
                    "load_before": load_before, "load_after": load_after},
        "no_protocol": plain, "null_px4": null, "protocol_peer": peer,
        "added_by_simulator_side": {
            "cpu_ms_per_step": added_cpu, "wall_ms_per_step": added_wall,
            "target_ms_per_step": 0.3, "met": bool(added_cpu <= 0.3),
        },
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=2, default=lambda x: None) + "\n")
    for name in ("no_protocol", "null_px4", "protocol_peer"):
        r = result[name]
        assert isinstance(r, dict)
        print(f"{name:14s} {r['steps_per_s']:8.0f} steps/s  wall {r['wall_ms_per_step']:.3f} "
              f"ms/step  sim-thread CPU {r['sim_thread_cpu_ms_per_step']:.3f} ms/step")
    print(f"added by the simulator side: CPU {added_cpu:.3f} ms/step, wall {added_wall:.3f} "
          f"ms/step (target <= 0.3 ms); load {load_before[0]:.1f} -> {load_after[0]:.1f}")
    if not math.isfinite(added_cpu):
        raise SystemExit(1)


if __name__ == "__main__":
    main()
