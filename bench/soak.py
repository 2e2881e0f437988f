"""Soak: `hilnav up` for a long simulated flight at speed, resident memory of every process.

Starts ``hilnav up --duration D --speed S --out DIR`` (extra ``up`` options after ``--``),
reads the children's PIDs from the lines ``up`` prints (``<name> pid N: ...``; the
children of ``up`` in ``/proc`` as a fallback) and samples ``VmRSS`` and ``VmHWM`` of ``up``
and each child from ``/proc/PID/status`` every ``--interval`` wall seconds (psutil is not a
dependency). The simulated time of each sample is estimated from the size of the sim's
recording (``run.tlog`` grows by a constant number of bytes per simulated second; scaled to the
scorecard's ``sim_duration_s`` at the end).

The JSON has, per process, the samples ``[wall_s, sim_s, rss_mb]`` and, after the warm-up
(``--warmup`` simulated seconds), the RSS min / max / range and the growth per simulated
hour of a least-squares line; the target is a fusion RSS range within 50 MB
after the warm-up (``target_ok``). The peak of each process (``VmHWM``, last read) includes
the end-of-run scoring, which is reported apart from the flat part.

    python bench/soak.py [--duration 3600] [--speed 20] [--out DIR] [--json FILE] [-- --lockstep]
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
_PID_LINE = re.compile(r"^(\w+)\s+pid (\d+):")
TARGET_RANGE_MB = 50.0


def _status_kb(pid: int, field: str) -> int | None:
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith(field + ":"):
                return int(line.split()[1])
    except (FileNotFoundError, ProcessLookupError, PermissionError):
        return None
    return None


def _proc_children(pid: int) -> list[int]:
    out: list[int] = []
    for task in Path(f"/proc/{pid}/task").glob("*"):
        try:
            out += [int(p) for p in (task / "children").read_text().split()]
        except (FileNotFoundError, ProcessLookupError):
            continue
    return out


def _comm(pid: int) -> str:
    try:
        args = Path(f"/proc/{pid}/cmdline").read_bytes().split(b"\0")
    except (FileNotFoundError, ProcessLookupError):
        return str(pid)
    words = [a.decode(errors="replace") for a in args]
    for name in ("fusion", "sim", "monitor"):
        if name in words:
            return name
    return str(pid)


def _fit_mb_per_hour(sim_s: np.ndarray, rss_mb: np.ndarray) -> float | None:
    if sim_s.size < 3 or np.ptp(sim_s) <= 0:
        return None
    slope = np.polyfit(sim_s, rss_mb, 1)[0]
    return float(slope * 3600.0)


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    extra: list[str] = []
    if "--" in argv:
        k = argv.index("--")
        argv, extra = argv[:k], argv[k + 1:]
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=3600.0, help="simulated s")
    ap.add_argument("--speed", type=float, default=20.0)
    ap.add_argument("--warmup", type=float, default=300.0, help="simulated s left out")
    ap.add_argument("--interval", type=float, default=1.0, help="wall s between samples")
    ap.add_argument("--out", type=Path, default=Path("/tmp/hilnav-soak"))
    ap.add_argument("--json", type=Path, default=ROOT / "bench" / "results" / "soak.json")
    args = ap.parse_args(argv)

    cmd = [sys.executable, "-m", "scenarios.cli", "up", "--duration", str(args.duration),
           "--speed", str(args.speed), "--out", str(args.out), *extra]
    env = {**os.environ, "COLUMNS": "200"}
    load0 = os.getloadavg()
    t0 = time.monotonic()
    up = subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                          text=True, env=env)
    pids: dict[str, int] = {"up": up.pid}
    lines: list[str] = []

    def read_output() -> None:
        assert up.stdout is not None
        for line in up.stdout:
            lines.append(line.rstrip("\n"))
            m = _PID_LINE.match(line)
            if m and "stopped" not in line:
                pids.setdefault(m.group(1), int(m.group(2)))

    reader = threading.Thread(target=read_output, daemon=True)
    reader.start()
    samples: dict[str, list[tuple[float, int, float]]] = {}
    peak_kb: dict[str, int] = {}
    tlog = args.out / "run.tlog"
    loads = [load0]
    while up.poll() is None:
        wall = time.monotonic() - t0
        for child in _proc_children(up.pid):
            name = _comm(child)
            if name in ("fusion", "sim", "monitor"):
                pids.setdefault(name, child)
        size = tlog.stat().st_size if tlog.exists() else 0
        for name, pid in list(pids.items()):
            rss = _status_kb(pid, "VmRSS")
            if rss is None:
                continue
            samples.setdefault(name, []).append((wall, size, rss / 1024.0))
            hwm = _status_kb(pid, "VmHWM")
            if hwm is not None:
                peak_kb[name] = max(peak_kb.get(name, 0), hwm)
        if int(wall) % 30 == 0:
            loads.append(os.getloadavg())
        time.sleep(args.interval)
    reader.join(5.0)
    wall_s = time.monotonic() - t0
    summary_path = args.out / "summary.json"
    summary = json.loads(summary_path.read_text()) if summary_path.is_file() else None
    sim_total = float(summary["sim_duration_s"]) if summary else args.duration
    final_bytes = tlog.stat().st_size if tlog.exists() else 0
    per_sim_s = final_bytes / sim_total if sim_total > 0 and final_bytes > 0 else None

    processes: dict[str, Any] = {}
    for name, rows in samples.items():
        arr = np.array(rows, dtype=float)
        sim_s = arr[:, 1] / per_sim_s if per_sim_s else arr[:, 0] * args.speed
        rss_mb = arr[:, 2]
        # after warm-up and before the recording stops growing (the end-of-run scoring)
        flying = (sim_s >= args.warmup) & (sim_s < sim_total - 1.0)
        entry: dict[str, Any] = {
            "pid": pids.get(name),
            "samples": [[round(float(w), 1), round(float(s), 1), round(float(r), 1)]
                        for w, s, r in zip(arr[:, 0], sim_s, rss_mb, strict=True)],
            "rss_first_mb": float(rss_mb[0]),
            "rss_last_mb": float(rss_mb[-1]),
            "peak_mb": peak_kb.get(name, 0) / 1024.0,
        }
        if np.any(flying):
            r = rss_mb[flying]
            entry.update({
                "after_warmup_min_mb": float(r.min()),
                "after_warmup_max_mb": float(r.max()),
                "after_warmup_range_mb": float(r.max() - r.min()),
                "after_warmup_mb_per_sim_hour": _fit_mb_per_hour(sim_s[flying], r),
            })
        processes[name] = entry
    fusion = processes.get("fusion", {})
    result = {
        "command": ["python", *cmd[1:]],  # the interpreter's path is this machine's own
        "exit_code": up.returncode,
        "duration_s": args.duration,
        "speed": args.speed,
        "warmup_s": args.warmup,
        "wall_s": wall_s,
        "sim_duration_s": sim_total if summary else None,
        "realtime_factor": summary.get("realtime_factor") if summary else None,
        "lost_frames": summary.get("live", {}).get("lost_frames") if summary else None,
        "load_avg_samples": loads,
        "target_range_mb": TARGET_RANGE_MB,
        "target_ok": (fusion.get("after_warmup_range_mb") is not None
                      and fusion["after_warmup_range_mb"] <= TARGET_RANGE_MB),
        "processes": processes,
        "up_output_tail": lines[-12:],
    }
    args.json.parent.mkdir(parents=True, exist_ok=True)
    args.json.write_text(json.dumps(result, indent=1) + "\n")
    brief = {k: v for k, v in result.items() if k not in ("processes", "up_output_tail")}
    brief["processes"] = {n: {k: v for k, v in p.items() if k != "samples"}
                          for n, p in processes.items()}
    print(json.dumps(brief, indent=1))
    return 0 if up.returncode == 0 and summary is not None else 1


if __name__ == "__main__":
    raise SystemExit(main())
