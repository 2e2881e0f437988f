"""Benchmark: ArduPilot SITL JSON lockstep, steps per second against the ArduPilot-side peer.

The simulator (:class:`hil.autopilot.ardupilot.ArduPilotBackend` in
:func:`hil.autopilot.fly_with_autopilot`) runs in this process; the protocol peer
(``tests/helpers/ardupilot_peer.py``: its estimator, controller and simulated GPS) in a child
process over loopback UDP, stopped by PID. Reported:

* ``steps_per_s``: lockstep steps per wall second (each step: one servo packet in, one JSON
  line out; both processes' work and the two UDP hops are in it);
* ``sim_cpu_us_per_step``: CPU time of this process per step (the whole simulator side:
  JSBSim, sensor models, MAVLink frames, the JSON protocol);
* ``chain_cpu_us_per_step``: the same chain flown without an autopilot (external control,
  constant commands), so ``protocol_added_us_per_step`` = the difference is what the JSON
  interface adds on the simulator side (target: <= 300 us per step);
* ``codec_us_per_step``: parsing a packet + the servo map + the state line alone.

    python bench/ardupilot_lockstep.py --duration 60 --out bench/results/ardupilot_lockstep.json
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import time
from pathlib import Path

from hil.autopilot import fly_with_autopilot
from hil.autopilot.ardupilot import ArduPilotBackend
from hil.autopilot.servos import ServoMap
from hil.autopilot.sitl_json import (
    JsonOrigin,
    encode_servo_packet,
    json_state_line,
    parse_servo_packet,
)
from hil.pipeline import SimChain, SimSetup
from scenarios.cli.up import stop_process

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))
from tests.helpers.ardupilot_peer import trimmed_controls  # noqa: E402

_PEER = """
import signal, sys, threading
from tests.helpers.ardupilot_peer import ArduPilotPeer, PeerPlan
trim = [float(x) for x in sys.argv[2].split(",")]
peer = ArduPilotPeer(sys.argv[1], plan=PeerPlan(headings=((20.0, 90.0),)), trim=trim)
done = threading.Event()
signal.signal(signal.SIGTERM, lambda *a: done.set())
peer.start()
done.wait()
peer.stop()
"""


def lockstep(setup: SimSetup) -> dict[str, float]:
    trim = trimmed_controls(setup)
    with ArduPilotBackend("udpin:127.0.0.1:0") as backend:
        port = backend.local_address[1]
        peer = subprocess.Popen(
            [sys.executable, "-c", _PEER, f"udp:127.0.0.1:{port}", ",".join(map(str, trim))],
            cwd=ROOT, start_new_session=True)
        cpu: list[float] = []  # CPU time at every step's end: the stepping alone is timed
        try:
            flown = fly_with_autopilot(setup, backend, connect_timeout_s=60.0,
                                       on_step=lambda step: cpu.append(time.process_time()))
        finally:
            stop_process(peer)
    if not flown.connected or flown.stalled or flown.ended:
        raise SystemExit(f"the flight did not complete: {flown}")
    return {"steps": flown.steps, "wall_s": flown.wall_s,
            "steps_per_s": flown.steps / flown.wall_s,
            "realtime_factor": flown.realtime_factor,
            "sim_cpu_us_per_step": (cpu[-1] - cpu[0]) / (len(cpu) - 1) * 1e6}


def chain_alone(setup: SimSetup) -> float:
    """CPU us per step of the same chain with constant external commands (no protocol)."""
    setup = setup.__class__(**{**setup.__dict__, "flight": setup.flight.model_copy(
        update={"control": "external"})})
    trim = list(trimmed_controls(setup))
    steps = 0
    with SimChain(setup) as chain:
        assert chain.flight is not None
        t0 = time.process_time()
        for _ in chain.steps():
            chain.flight.command(trim)
            steps += 1
        return (time.process_time() - t0) / steps * 1e6


def codec(setup: SimSetup, n: int = 20000) -> float:
    servo_map = ServoMap.default()
    packet = encode_servo_packet(1, [1500, 1480, 1700, 1500])
    with SimChain(setup) as chain:
        truth = next(chain.steps()).truth
    origin = JsonOrigin(0.8, 0.14, 0.0)
    t0 = time.process_time()
    for _ in range(n):
        p = parse_servo_packet(packet)
        assert not isinstance(p, str)
        servo_map.controls(p.pwm_us)
        json_state_line(truth, origin)
    return (time.process_time() - t0) / n * 1e6


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=60.0)
    ap.add_argument("--rate", type=float, default=200.0)
    ap.add_argument("--out", type=Path, default=Path("bench/results/ardupilot_lockstep.json"))
    args = ap.parse_args()
    setup = SimSetup.build(duration_s=args.duration, rate_hz=args.rate, seed=1)
    load0 = os.getloadavg()
    result = lockstep(setup)
    chain_us = chain_alone(setup)
    out = {
        "bench": "ardupilot_lockstep",
        "command": "python bench/ardupilot_lockstep.py " + " ".join(sys.argv[1:]),
        "duration_s": args.duration,
        "rate_hz": args.rate,
        **result,
        "chain_cpu_us_per_step": chain_us,
        "protocol_added_us_per_step": result["sim_cpu_us_per_step"] - chain_us,
        "codec_us_per_step": codec(setup),
        "target_protocol_added_us_per_step": 300.0,
        "loadavg_before": load0,
        "loadavg_after": os.getloadavg(),
        "python": platform.python_version(),
        "machine": platform.machine(),
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(out, indent=2) + "\n")
    print(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
