"""Benchmark: the live path over real loopback sockets.

What is measured (all on one machine, so every process reads the same CLOCK_MONOTONIC):

1. **End-to-end latency at 1x real time, 200 Hz IMU, routed and peer-to-peer.** The chain of
   ``hilnav up`` without the monitor: an in-process Zenoh router (in this process),
   ``hilnav fusion --zenoh ROUTER --zenoh-listen tcp/127.0.0.1:P --out`` as a child process,
   and the simulator as a child process running the same :func:`hil.live_sim.live_sim` as
   ``hilnav sim --live --zenoh`` plus an ``on_send`` hook that stamps ``time.monotonic_ns()``
   right before each HIL_SENSOR frame is handed to the link (signing / sequence number, then
   ``sendto``); the stamps go to a side file at the end (stamped before ``sendto``: a
   simulator descheduled right after the system call would stamp late). Two
   subscriber child processes (:class:`hil.bus.Bus`, as ``hilnav monitor`` subscribes) stamp
   ``time.monotonic_ns()`` when each ``fusion/estimate`` sample reaches their callback: one a
   Zenoh client of the router (*routed*), one a Zenoh peer connected to the fusion's
   ``--zenoh-listen`` endpoint (*p2p*, as ``hilnav monitor --peer``). Both see the same
   estimates of the same run, so the two modes are compared under the same load. Latency of
   an estimate with time ``T`` = its arrival - the send stamp of the HIL_SENSOR frame whose
   IMU time is ``T``: UDP hop, the fusion's reader thread and queue, decode, filter, the bus
   queue and publisher thread, JSON, the router hop (routed only) and the subscriber's
   callback (JSON decode).
   Estimates are published at the bus's 25 Hz (of the filter's 50 Hz outputs). The fusion
   runs under :func:`fusion_main`, which stamps each estimate's stages inside the fusion
   process (``stages`` in the JSON: UDP + link receive, reader -> filter thread, decode +
   filter, payload, JSON, enqueue, publisher-thread wake-up, Zenoh ``put``, put -> each
   subscriber's callback). ``--base REV`` (a git revision or a source tree) makes this part
   an A/B: the fusion of REV and of this tree alternately, ``--rounds`` runs each, order
   flipped every round, with the same simulator, subscribers and router code. ``--low-latency``
   starts the fusion (with ``--base``: this tree's only) with ``--zenoh-low-latency`` and
   makes both subscribers ask for Zenoh's low-latency transport. The subscribers also stamp
   each estimate when it reaches ``hil.bus``'s JSON decode (``end_to_end_before_json_decode``).
2. **The two socket hops alone**, for a split: (a) UDP: a child process sends HIL_SENSOR
   frames through :class:`hil.link.MavlinkLink` at 200 Hz carrying their monotonic send
   time, this process receives them on a ``udpin`` link; (b) Zenoh: a child process publishes
   ``scenario/events`` samples through :class:`hil.bus.Bus` at 25 Hz carrying their
   monotonic publish time, this process's subscriber receives them via the same router, and
   (c) the same as a direct peer of the publisher (``zenoh_p2p``).
   ``fusion internal`` = end-to-end median - both hop medians (an estimate, not a
   measurement; routed end-to-end with the routed hop).
   For calibration, the same two hops without hilnav's code: a plain blocking UDP socket
   (``sendto`` / ``recv`` of a time stamp) and a plain zenoh-python ``put`` -> router ->
   subscriber callback.
3. **CPU per process** during the 1x run: ``utime + stime`` from ``/proc/<pid>/stat`` of the
   simulator, the fusion, the two subscribers and this process (the router), from 15 s after
   the simulator started to 10 s before its flight ends, divided by the wall time in between;
   100 % = one core.
4. **Highest ``--speed`` without sample loss**: ``hilnav sim --live --speed X --zenoh
   --record`` into ``hilnav fusion --zenoh --out`` (what ``hilnav up`` starts), short flights
   at increasing X; loss = frames the simulator's link did not send + frames it sent that the
   fusion did not decode (its summary's decoder ``frames_ok``); the sequence gaps the link
   counted (``lost_seq``) are reported too. The simulator's achieved real-time factor is
   reported with each step (the simulator alone reaches ~25x on an idle core), and so is the
   fusion's own processing rate (its summary's ``realtime_factor``: simulated seconds over
   the wall time from its first frame in to its last frame fused). Then one ``--lockstep
   --speed 1000`` run (as fast as the slower process allows).
5. **Fusion capacity without the simulator**: a recording (``hilnav sim --record``, same
   flight) replayed into a fresh ``hilnav fusion --zenoh --out`` by a light sender (no
   JSBSim) at 25x and 50x, to see the fusion's limit when the simulator cannot reach the
   speed.

The machine has 2 cores and other jobs may run on it: the load averages before and after
each part are recorded. Run from the repository root:

    python bench/live_latency.py --out bench/results/live_latency.json

(``--parts latency,hops`` for the routed / p2p comparison alone, ~3 min;
``--parts latency --base REV --rounds 3 --duration 30`` for an A/B against a git revision,
~5 min.) Targets: at 1x, frame sent -> estimate at a subscriber, median <= 1 ms and p99
<= 3 ms; no sample lost up to >= 25x real time.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np
from _live_children import (
    fusion_main,
    raw_udp_main,
    raw_zenoh_main,
    replay_main,
    sender_main,
    subscriber_main,
    udp_hop_main,
    zenoh_client_config,
    zenoh_hop_main,
)
from _live_common import (
    HIL_SENSOR_ID,
    ROOT,
    START_TIMEOUT_S,
    base_tree,
    children,
    cpu_s,
    free_port,
    free_tcp_port,
    hilnav,
    load,
    stats_ms,
    this_script,
)

ROLES = {"sender": sender_main, "udp-hop": udp_hop_main, "zenoh-hop": zenoh_hop_main,
         "replay": replay_main, "raw-udp": raw_udp_main, "raw-zenoh": raw_zenoh_main,
         "subscriber": subscriber_main}
"""The child processes, by ``--role`` (the fusion child parses ``hilnav fusion``'s own
arguments: see :func:`main`)."""

_SENT = re.compile(
    r"sent (\d+)/(\d+) frames, ([\d.]+) s simulated in ([\d.]+) s \(([\d.]+)x real time")


def _wait_files(paths: list[Path], procs: list[subprocess.Popen[bytes]], timeout_s: float,
                what: str) -> None:
    deadline = time.monotonic() + timeout_s
    while not all(p.exists() for p in paths):
        if time.monotonic() > deadline or any(p.poll() is not None for p in procs):
            raise RuntimeError(f"{what} did not start")
        time.sleep(0.05)


def measure_latency(endpoint: str, duration_s: float, seed: int, tmp: Path, *,
                    code: Path | None = None, tag: str = "lat", low_latency: bool = False,
                    sub_low_latency: bool = False) -> dict[str, Any]:
    """Part 1 and 3: end-to-end latency (routed and p2p, same run), the fusion's stages, and
    CPU per process at 1x. ``code``: the fusion runs that tree's hilnav (the A/B base).
    ``low_latency``: the fusion asks for Zenoh's low-latency transport (the subscribers ask
    with ``--low-latency`` when ``sub_low_latency``)."""
    vehicle = tag
    tmp = tmp / tag
    tmp.mkdir()
    trace_file = tmp / "fusion_trace.json"
    port = free_port()
    listen = f"tcp/127.0.0.1:{free_tcp_port()}"
    stamps_file = tmp / "stamps.json"
    subs = {"routed": (endpoint, False), "p2p": (listen, True)}
    arrival_files = {mode: tmp / f"arrivals_{mode}.json" for mode in subs}
    load_before = load()
    with children() as procs:
        fusion = this_script("--role", "fusion", "--trace", str(trace_file), "fusion",
                             "--mavlink", f"udpin:127.0.0.1:{port}", "--zenoh", endpoint,
                             "--zenoh-listen", listen, "--vehicle", vehicle, "--out",
                             str(tmp / "lat_fusion"), "--idle-exit", "2", "--settle", "10",
                             *(["--zenoh-low-latency"] if low_latency else []),
                             log=tmp / "lat_fusion.log", code=code)
        procs.append(fusion)
        sub_procs = {}
        for mode, (ep, peer) in subs.items():
            sub_procs[mode] = this_script(
                "--role", "subscriber", "--zenoh", ep, *(["--peer"] if peer else []),
                *(["--low-latency"] if sub_low_latency else []),
                "--vehicle", vehicle, "--stamps", str(arrival_files[mode]), "--max-wall",
                str(START_TIMEOUT_S + duration_s + 60.0), log=tmp / f"lat_sub_{mode}.log")
            procs.append(sub_procs[mode])
        _wait_files([Path(str(f) + ".ready") for f in arrival_files.values()],
                    [fusion, *sub_procs.values()], START_TIMEOUT_S, "the subscribers")
        sender = this_script("--role", "sender", "--url", f"udpout:127.0.0.1:{port}",
                             "--speed", "1", "--duration", str(duration_s), "--seed", str(seed),
                             "--zenoh", endpoint, "--vehicle", vehicle, "--stamps",
                             str(stamps_file), log=tmp / "lat_sender.log")
        procs.append(sender)
        watched = {"sim": sender, "fusion": fusion, "subscriber_routed": sub_procs["routed"],
                   "subscriber_p2p": sub_procs["p2p"]}
        time.sleep(15.0)
        c0 = {k: cpu_s(p.pid) for k, p in watched.items()} | {"bench": cpu_s()}
        w0 = time.monotonic()
        time.sleep(max(1.0, duration_s - 25.0))
        c1 = {k: cpu_s(p.pid) for k, p in watched.items()} | {"bench": cpu_s()}
        w1 = time.monotonic()
        sender.wait(START_TIMEOUT_S + duration_s)
        fusion.wait(60.0)
        for p in sub_procs.values():
            p.wait(60.0)
    sent = json.loads(stamps_file.read_text())
    send_ns = {int(t): int(ns) for t, ns in sent["stamps"]}
    summary = json.loads((tmp / "lat_fusion" / "summary.json").read_text())
    window = w1 - w0
    out: dict[str, Any] = {"sim_duration_s": duration_s, "speed": 1.0, "imu_rate_hz": 200.0,
                           "fusion_low_latency": low_latency,
                           "subscribers_low_latency": sub_low_latency}
    lat_by_time: dict[str, dict[int, int]] = {}
    for mode in subs:
        arrivals = json.loads(arrival_files[mode].read_text())
        lat_by_time[mode] = {int(t): ns - send_ns[t] for t, ns in arrivals if t in send_ns}
        raw = json.loads(Path(str(arrival_files[mode]) + ".raw").read_text())
        out[mode] = {"estimates_received": len(arrivals),
                     "estimates_matched": len(lat_by_time[mode]),
                     "end_to_end": stats_ms(list(lat_by_time[mode].values())),
                     # the same path, stamped before the subscriber's JSON decode
                     "end_to_end_before_json_decode": stats_ms(
                         [ns - send_ns[t] for t, ns in raw if t in send_ns])}
    arrivals_by_mode = {mode: dict(json.loads(arrival_files[mode].read_text())) for mode in subs}
    trace = json.loads(trace_file.read_text())
    ran = Path(trace["code_from"]).resolve()
    if (code is not None and ran != code.resolve()) or (code is None and ran != ROOT):
        raise RuntimeError(f"the fusion ran the code in {ran}, not the tree asked for")
    trace["code_from"] = "base tree" if code is not None else "this tree"
    out["stages"] = fusion_stages(trace, send_ns, arrivals_by_mode)
    common = sorted(set(lat_by_time["routed"]) & set(lat_by_time["p2p"]))
    out["estimates_received_by_both"] = len(common)
    out["routed_minus_p2p_per_estimate"] = stats_ms(
        [lat_by_time["routed"][t] - lat_by_time["p2p"][t] for t in common])
    out |= {
        "cpu_window_wall_s": round(window, 2),
        "cpu_percent_of_one_core": {k: round(100.0 * (c1[k] - c0[k]) / window, 1) for k in c0},
        "cpu_processes": {
            "sim": "live_sim (= hilnav sim --live --zenoh) + send-stamp hook",
            "fusion": "hilnav fusion --zenoh ROUTER --zenoh-listen P2P --out",
            "subscriber_routed": "hil.bus.Bus client of the router (as hilnav monitor)",
            "subscriber_p2p": "hil.bus.Bus peer of the fusion (as hilnav monitor --peer)",
            "bench": "this process: the in-process Zenoh router",
        },
        "sim_realtime_factor": round(sent["realtime_factor"], 3),
        "frames_sent": sent["sent"],
        "fusion_frames_decoded": summary["live"]["links"]["decoder"]["frames_ok"],
        "fusion_lost_seq": summary["live"]["links"]["mavlink"]["lost_seq"],
        "load_before": load_before,
        "load_after": load(),
    }
    return out


def fusion_stages(trace: dict[str, Any], send_ns: dict[int, int],
                  arrivals: dict[str, dict[int, int]]) -> dict[str, Any]:
    """Where each estimate's time went, stage by stage (ms; see :func:`fusion_main`)."""
    rx = {int(t): ns for t, ns in reversed(trace["rx"])}  # first stamp of each IMU time
    start = {int(t): ns for t, ns in reversed(trace["start"])}
    names = ["udp_and_link_recv", "reader_to_filter_thread", "decode_filter_to_publish",
             "publish_call_to_payload_built", "payload_to_json_encoded",
             "json_to_enqueued_and_return", "bus_thread_wakeup", "zenoh_put_call"]
    # an estimate put by the filter's own thread (the bus idle): JSON encoded ->
    # the put starts, instead of the enqueue and the publisher thread's wake-up
    direct = ["json_to_direct_put_call"]
    names += [f"put_to_{mode}_callback" for mode in arrivals]
    stages: dict[str, list[int]] = {n: [] for n in names + direct}
    n_direct = 0
    for (t, p0, p1), (b0, b1), (q0, q1) in zip(trace["pub"], trace["built"], trace["put"],
                                               strict=False):
        if t not in send_ns or t not in rx or t not in start:
            continue
        if q0 < p1:  # put inside the publish call
            n_direct += 1
            marks = [send_ns[t], rx[t], start[t], p0, b0, b1, q0, q1]
            steps = [*names[:5], "json_to_direct_put_call", "zenoh_put_call"]
        else:
            marks = [send_ns[t], rx[t], start[t], p0, b0, b1, p1, q0, q1]
            steps = names[:8]
        for name, a, b in zip(steps, marks, marks[1:], strict=False):
            stages[name].append(b - a)
        for mode, arrived in arrivals.items():
            if t in arrived:
                stages[f"put_to_{mode}_callback"].append(arrived[t] - q0)
    return {"code_from": trace.get("code_from"), "estimates_published": len(trace["pub"]),
            "estimates_put_by_the_filter_thread": n_direct,
            **{name: stats_ms(v) for name, v in stages.items()}}


def measure_udp_hop(count: int, tmp: Path) -> dict[str, Any]:
    """Part 2a: one MavlinkLink UDP hop between two processes."""
    from hil.link import MavlinkLink
    from hil.service import input_role

    lat: list[int] = []
    with MavlinkLink("udpin:127.0.0.1:0", input_role()) as link, children() as procs:
        port = link.local_address[1]
        child = this_script("--role", "udp-hop", "--url", f"udpout:127.0.0.1:{port}",
                            "--count", str(count), log=tmp / "udp_hop.log")
        procs.append(child)
        deadline = time.monotonic() + START_TIMEOUT_S + count * 0.005
        while child.poll() is None and time.monotonic() < deadline:
            for m in link.recv(0.05):
                now = time.monotonic_ns()
                if m.get_msgId() == HIL_SENSOR_ID:
                    lat.append(now - int(m.time_usec) * 1000)
    return {"what": "HIL_SENSOR through MavlinkLink udpout -> udpin, child -> this process",
            "rate_hz": 200.0, **stats_ms(lat)}


def measure_zenoh_hop(endpoint: str, count: int, tmp: Path, *, p2p: bool = False
                      ) -> dict[str, Any]:
    """Part 2b/c: one Bus publish -> (router ->) subscriber hop between two processes."""
    from hil.bus import Bus, Message, Topic

    lat: list[int] = []

    def on_event(m: Message) -> None:
        now = time.monotonic_ns()
        if m.payload is not None:
            lat.append(now - int(m.payload["time_us"]) * 1000)

    listen = f"tcp/127.0.0.1:{free_tcp_port()}"
    tag = "p2p" if p2p else "routed"
    with children() as procs:
        child = this_script("--role", "zenoh-hop", "--zenoh", endpoint, "--vehicle", "hop",
                            "--count", str(count), *(["--peer", "--url", listen] if p2p else []),
                            log=tmp / f"zenoh_hop_{tag}.log")
        procs.append(child)
        with Bus(listen if p2p else endpoint, vehicle="hop",
                 mode="peer" if p2p else "client") as bus:
            bus.subscribe(Topic.EVENTS, on_event)
            bus.wait_connected(START_TIMEOUT_S)
            child.wait(START_TIMEOUT_S + count * 0.05)
    where = "-> the publisher's direct peer" if p2p else "-> router -> subscriber"
    return {"what": f"Bus.publish (queue, publisher thread, JSON) {where} callback, "
            "child -> this process", "rate_hz": 25.0,
            **stats_ms(lat)}


def measure_raw_udp(count: int, tmp: Path) -> dict[str, Any]:
    """Calibration: a plain blocking UDP socket between two processes."""
    import socket

    lat: list[int] = []
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock, children() as procs:
        sock.bind(("127.0.0.1", 0))
        sock.settimeout(START_TIMEOUT_S)
        procs.append(this_script("--role", "raw-udp", "--url", str(sock.getsockname()[1]),
                                 "--count", str(count), log=tmp / "raw_udp.log"))
        while True:
            data = sock.recv(64)
            now = time.monotonic_ns()
            if data == b"end":
                break
            lat.append(now - int(data))
    return {"what": "plain socket sendto -> blocking recv, child -> this process",
            "rate_hz": 200.0, **stats_ms(lat)}


def measure_raw_zenoh(endpoint: str, count: int, tmp: Path) -> dict[str, Any]:
    """Calibration: plain zenoh-python put -> router -> subscriber between two processes."""
    import zenoh

    lat: list[int] = []

    def on_sample(sample: Any) -> None:
        now = time.monotonic_ns()
        lat.append(now - int(sample.payload.to_bytes()))

    session = zenoh.open(zenoh_client_config(endpoint))
    try:
        session.declare_subscriber("bench/raw", on_sample)
        with children() as procs:
            child = this_script("--role", "raw-zenoh", "--zenoh", endpoint, "--count",
                                str(count), log=tmp / "raw_zenoh.log")
            procs.append(child)
            child.wait(START_TIMEOUT_S + count * 0.05)
    finally:
        session.close()
    return {"what": "zenoh-python put -> router -> subscriber callback, child -> this "
            "process", "rate_hz": 25.0, **stats_ms(lat)}


def speed_run(endpoint: str, speed: float, duration_s: float, tmp: Path, *,
              lockstep: bool = False) -> dict[str, Any]:
    """Part 4: one ``hilnav sim --live`` into ``hilnav fusion`` run; loss counters."""
    tag = f"{'lockstep_' if lockstep else ''}{speed:g}x"
    vehicle = "s" + tag.replace(".", "_")
    port = free_port()
    out = tmp / f"run_{tag}"
    load_before = load()
    with children() as procs:
        fusion = hilnav("fusion", "--mavlink", f"udpin:127.0.0.1:{port}", "--zenoh", endpoint,
                        "--vehicle", vehicle, "--out", str(out), "--idle-exit", "2",
                        "--settle", "5", log=tmp / f"{tag}_fusion.log")
        procs.append(fusion)
        args = ["sim", "--live", f"udpout:127.0.0.1:{port}", "--speed", f"{speed:g}",
                "--duration", f"{duration_s:g}", "--seed", "1", "--zenoh", endpoint,
                "--vehicle", vehicle, "--record", str(out / "run.tlog"), "--wait-peer", "60"]
        if lockstep:
            args.append("--lockstep")
        sim = hilnav(*args, log=tmp / f"{tag}_sim.log")
        procs.append(sim)
        sim_code = sim.wait(START_TIMEOUT_S + duration_s * 10)
        fusion_code = fusion.wait(120.0)
    text = (tmp / f"{tag}_sim.log").read_text()
    m = _SENT.search(text)
    if sim_code != 0 or fusion_code != 0 or m is None:
        return {"speed": speed, "lockstep": lockstep, "error": f"sim exit {sim_code}, fusion "
                f"exit {fusion_code}; see {tmp}", "sim_output": text[-500:]}
    sent, frames = int(m.group(1)), int(m.group(2))
    summary = json.loads((out / "summary.json").read_text())
    live = summary["live"]
    decoded = live["links"]["decoder"]["frames_ok"]
    return {
        "speed": speed,
        "lockstep": lockstep,
        "sim_duration_s": float(m.group(3)),
        "achieved_realtime_factor": float(m.group(5)),
        "frames": frames,
        "sent": sent,
        "decoded_by_fusion": decoded,
        "lost": (frames - sent) + (sent - decoded),
        "lost_seq": live["links"]["mavlink"]["lost_seq"],
        "fusion_realtime_factor": round(summary["realtime_factor"], 2),
        "lockstep_acks": live.get("lockstep_acks"),
        "load_before": load_before,
        "load_after": load(),
    }


def replay_run(endpoint: str, tlog: Path, speed: float, tmp: Path) -> dict[str, Any]:
    """Part 5: a recording replayed into the fusion by a light sender at ``speed``."""
    tag = f"replay_{speed:g}x"
    port = free_port()
    out = tmp / tag
    load_before = load()
    with children() as procs:
        fusion = hilnav("fusion", "--mavlink", f"udpin:127.0.0.1:{port}", "--zenoh", endpoint,
                        "--vehicle", tag, "--out", str(out), "--idle-exit", "2",
                        "--settle", "5", log=tmp / f"{tag}_fusion.log")
        procs.append(fusion)
        sender = this_script("--role", "replay", "--url", f"udpout:127.0.0.1:{port}",
                             "--tlog", str(tlog), "--speed", f"{speed:g}",
                             log=tmp / f"{tag}_sender.log")
        procs.append(sender)
        sender.wait(START_TIMEOUT_S + 120.0)
        fusion.wait(120.0)
    sent = json.loads((tmp / f"{tag}_sender.log").read_text().strip().splitlines()[-1])
    summary = json.loads((out / "summary.json").read_text())
    decoded = summary["live"]["links"]["decoder"]["frames_ok"]
    return {
        "speed": speed,
        "sender_achieved_realtime_factor": round(sent["achieved_realtime_factor"], 2),
        "frames": sent["frames"],
        "sent": sent["sent"],
        "decoded_by_fusion": decoded,
        "lost": sent["frames"] - decoded,
        "lost_seq": summary["live"]["links"]["mavlink"]["lost_seq"],
        "fusion_realtime_factor": round(summary["realtime_factor"], 2),
        "load_before": load_before,
        "load_after": load(),
    }


def latency_ab(endpoint: str, args: argparse.Namespace, code: Path | None, tmp: Path
               ) -> dict[str, Any]:
    """Part 1 as an A/B: base and new fusion alternately (order flipped each round), same
    simulator, subscribers and router; per run and the median over the runs of each."""
    runs: list[dict[str, Any]] = []
    for r in range(args.rounds):
        order = [("new", None), ("base", code)]
        for variant, tree in order if r % 2 == 0 else order[::-1]:
            print(f"1x latency run, {variant} (round {r + 1}) ...", flush=True)
            run = measure_latency(endpoint, args.duration, args.seed, tmp, code=tree,
                                  tag=f"{variant}{r}",
                                  low_latency=args.low_latency and variant == "new",
                                  sub_low_latency=args.low_latency)
            runs.append({"variant": variant, "round": r, **run})
    summary: dict[str, Any] = {}
    for variant in ("base", "new"):
        mine = [x for x in runs if x["variant"] == variant]
        summary[variant] = {
            f"{mode}_{q}": round(float(np.median([x[mode]["end_to_end"][q] for x in mine])), 4)
            for mode in ("routed", "p2p") for q in ("median_ms", "p99_ms")}
        summary[variant] |= {
            f"{mode}_before_json_decode_{q}": round(float(np.median(
                [x[mode]["end_to_end_before_json_decode"][q] for x in mine])), 4)
            for mode in ("routed", "p2p") for q in ("median_ms", "p99_ms")}
        summary[variant]["stage_medians_ms"] = {
            name: round(float(np.median([x["stages"][name]["median_ms"] for x in mine])), 4)
            for name, v in mine[0]["stages"].items() if isinstance(v, dict) and v.get("n")}
        summary[variant]["stage_p99s_ms"] = {
            name: round(float(np.median([x["stages"][name]["p99_ms"] for x in mine])), 4)
            for name, v in mine[0]["stages"].items() if isinstance(v, dict) and v.get("n")}
    base = "a source tree (directory)" if Path(args.base).is_dir() else args.base
    return {"base": base, "rounds": args.rounds, "duration_s": args.duration,
            "summary": summary, "runs": runs}


# ------------------------------------------------------------------------------ main
def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--role", default="bench",
                    choices=["bench", *ROLES],
                    help=argparse.SUPPRESS)
    ap.add_argument("--peer", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--max-wall", type=float, default=300.0, help=argparse.SUPPRESS)
    ap.add_argument("--url", help=argparse.SUPPRESS)
    ap.add_argument("--zenoh", help=argparse.SUPPRESS)
    ap.add_argument("--vehicle", default="lat", help=argparse.SUPPRESS)
    ap.add_argument("--stamps", help=argparse.SUPPRESS)
    ap.add_argument("--tlog", help=argparse.SUPPRESS)
    ap.add_argument("--count", type=int, default=1000, help=argparse.SUPPRESS)
    ap.add_argument("--speed", type=float, default=1.0, help=argparse.SUPPRESS)
    ap.add_argument("--seed", type=int, default=1, help="scenario seed")
    ap.add_argument("--duration", type=float, default=60.0,
                    help="simulated (= wall) seconds of the 1x latency run")
    ap.add_argument("--speeds", default="5,10,15,20,25,30,40",
                    help="speeds of the loss sweep, comma separated")
    ap.add_argument("--sweep-duration", type=float, default=30.0,
                    help="simulated seconds per sweep run")
    ap.add_argument("--parts", default="latency,hops,sweep,lockstep,capacity",
                    help="parts to run, comma separated")
    ap.add_argument("--base", help="A/B: the latency part alternates the fusion of this git "
                    "revision or source tree (base) and of this tree (new), --rounds times "
                    "each")
    ap.add_argument("--rounds", type=int, default=3, help="A/B rounds (with --base)")
    ap.add_argument("--low-latency", action="store_true",
                    help="the fusion (with --base: the new one only) runs with "
                    "--zenoh-low-latency; the subscribers always ask for the low-latency "
                    "transport then (a link falls back to the default one unless both ends "
                    "ask)")
    ap.add_argument("--out", type=Path, default=Path("bench/results/live_latency.json"))
    if sys.argv[1:3] == ["--role", "fusion"]:
        return fusion_main(sys.argv[3:])
    args = ap.parse_args()
    if args.role != "bench":
        return ROLES[args.role](args)

    from hil.router import zenoh_router

    t_start = time.monotonic()
    result: dict[str, Any] = {
        "benchmark": "live_latency",
        "python": platform.python_version(),
        "machine": platform.machine(),
        "cores": os.cpu_count(),
        "note": "other jobs may share this 2-core machine: see the load averages",
        "load_start": load(),
    }
    with tempfile.TemporaryDirectory(prefix="hilnav_bench_") as tmpdir, \
            zenoh_router() as endpoint:
        tmp = Path(tmpdir)
        parts = set(args.parts.split(","))
        if "latency" in parts and args.base is None:
            print("1x latency run ...", flush=True)
            result["latency_1x"] = measure_latency(
                endpoint, args.duration, args.seed, tmp, low_latency=args.low_latency,
                sub_low_latency=args.low_latency)
            print(json.dumps(result["latency_1x"], indent=1), flush=True)
        if "latency" in parts and args.base is not None:
            with base_tree(args.base) as code:
                result["latency_ab"] = latency_ab(endpoint, args, code, tmp)
            print(json.dumps(result["latency_ab"]["summary"], indent=1), flush=True)
        if "hops" in parts:
            print("socket hops ...", flush=True)
            udp = measure_udp_hop(1000, tmp)
            zen = measure_zenoh_hop(endpoint, 500, tmp)
            result["hops"] = {"udp": udp, "zenoh": zen,
                              "zenoh_p2p": measure_zenoh_hop(endpoint, 500, tmp, p2p=True),
                              "raw_udp": measure_raw_udp(1000, tmp),
                              "raw_zenoh": measure_raw_zenoh(endpoint, 500, tmp)}
            if "latency_1x" in result:
                e2e = result["latency_1x"]["routed"]["end_to_end"]
                result["hops"]["fusion_internal_median_ms_estimate"] = round(
                    e2e["median_ms"] - udp["median_ms"] - zen["median_ms"], 4)
            print(json.dumps(result["hops"], indent=1), flush=True)
        if "sweep" in parts:
            sweep = []
            for speed in (float(s) for s in args.speeds.split(",")):
                print(f"speed {speed:g}x ...", flush=True)
                sweep.append(speed_run(endpoint, speed, args.sweep_duration, tmp))
                print(json.dumps(sweep[-1]), flush=True)
            result["speed_sweep"] = sweep
            clean_prefix = []
            for r in sweep:
                if r.get("lost") != 0:
                    break
                clean_prefix.append(r)
            result["highest_speed_zero_loss"] = {
                "requested": clean_prefix[-1]["speed"] if clean_prefix else None,
                "achieved_realtime_factor": (clean_prefix[-1]["achieved_realtime_factor"]
                                             if clean_prefix else None),
                "achieved_max_zero_loss": max((r["achieved_realtime_factor"] for r in sweep
                                               if r.get("lost") == 0), default=None),
            }
        if "lockstep" in parts:
            print("lockstep at --speed 1000 ...", flush=True)
            result["lockstep"] = speed_run(endpoint, 1000.0, args.sweep_duration * 2, tmp,
                                           lockstep=True)
            print(json.dumps(result["lockstep"]), flush=True)
        if "capacity" in parts:
            recording = tmp / "capacity.tlog"
            subprocess.run([sys.executable, "-m", "scenarios.cli", "sim", "--record",
                            str(recording), "--duration", f"{args.sweep_duration:g}",
                            "--seed", "1"],
                           check=True, capture_output=True)
            result["fusion_capacity"] = []
            for speed in (25.0, 50.0):
                print(f"replay into the fusion at {speed:g}x ...", flush=True)
                result["fusion_capacity"].append(replay_run(endpoint, recording, speed, tmp))
                print(json.dumps(result["fusion_capacity"][-1]), flush=True)
    result["targets"] = {"median_ms_max": 1.0, "p99_ms_max": 3.0, "zero_loss_speed_min": 25.0}
    result["meets_targets"] = {}
    if "speed_sweep" in result:
        best = result["highest_speed_zero_loss"]["achieved_max_zero_loss"]
        result["meets_targets"]["zero_loss_speed"] = best is not None and best >= 25.0
    for mode in ("routed", "p2p"):
        if "latency_ab" in result:
            ab = result["latency_ab"]["summary"]["new"]
            lat = {q: ab[f"{mode}_{q}"] for q in ("median_ms", "p99_ms")}
        elif "latency_1x" in result:
            lat = result["latency_1x"][mode]["end_to_end"]
        else:
            continue
        result["meets_targets"][f"{mode}_median"] = lat.get("median_ms", math.inf) <= 1.0
        result["meets_targets"][f"{mode}_p99"] = lat.get("p99_ms", math.inf) <= 3.0
    result["load_end"] = load()
    result["bench_wall_s"] = round(time.monotonic() - t_start, 1)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=2) + "\n")
    print(json.dumps({k: result.get(k) for k in ("highest_speed_zero_loss", "meets_targets",
                                                 "bench_wall_s")}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
