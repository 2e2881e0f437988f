"""Benchmark: the real autopilots fly the library's scripted GNSS-outage scenarios.

For each SITL binary given (ArduPlane ``arduplane``, PX4 ``build/px4_sitl_default/bin/px4``,
built by the user from each project's own sources; hilnav ships neither), this runs the
library scenario of that autopilot as a user does, with one command::

    hilnav run scenarios/library/autopilot/arduplane-mission-gnss-outage.yaml \\
        --autopilot-binary PATH --out DIR --quiet

(hilnav starts the binary on free loopback ports, scripts it, scores it and stops it by PID)
and collects from the run's ``summary.json``: the exit code and wall time, the failures, the
version string the binary printed, its instance and ports and how it stopped, lockstep
counters, when the trim was released, hilnav's and the autopilot's horizontal error in each
GNSS outage and with GNSS, and the altitude hold (:func:`altitude_hold`: the truth's height
against the mission item's commanded altitude, outside turns). A scenario with
``aiding: hilnav`` and ``unaided_baseline`` adds its card of hilnav, the aided and the unaided
autopilot (``aided_vs_unaided``) and the unaided flight's own row. Nothing is judged here: the
numbers are recorded as they came, with the exact command.

Scenarios: ``scenarios/library/autopilot/{arduplane,px4}-mission-gnss-outage.yaml`` when the
library has them (scripted missions), else ``scenarios/library/px4-fixed-wing-gnss-outage.yaml``
and ``scenarios/library/arduplane-fixed-wing-gnss-outage.yaml`` (the autopilot flies whatever
its own mode is).

    python bench/autopilot_sitl.py --arduplane PATH --px4 PATH \\
        --out bench/results/autopilot_sitl.json
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import shlex
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
LIBRARY = ROOT / "scenarios" / "library"
SCENARIOS = {
    "ardupilot": (LIBRARY / "autopilot" / "arduplane-mission-gnss-outage.yaml",
                  LIBRARY / "arduplane-fixed-wing-gnss-outage.yaml"),
    "px4": (LIBRARY / "autopilot" / "px4-mission-gnss-outage.yaml",
            LIBRARY / "px4-fixed-wing-gnss-outage.yaml"),
}
_TAIL_LINES = 8


def scenario_for(kind: str) -> Path:
    """The library scenario the bench flies with autopilot ``kind``."""
    scripted, fallback = SCENARIOS[kind]
    return scripted if scripted.is_file() else fallback


def run_one(kind: str, binary: Path, out: Path, scenario: Path | None = None,
            timeout_s: float = 7200.0) -> dict[str, Any]:
    """Fly ``scenario`` (default: :func:`scenario_for`) with ``binary``; the row of the
    results."""
    scenario = scenario or scenario_for(kind)
    argv = [sys.executable, "-m", "scenarios.cli", "run", str(scenario),
            "--autopilot-binary", str(binary), "--out", str(out), "--quiet"]
    shown = ["hilnav", *argv[3:]]
    t0 = time.perf_counter()
    proc = subprocess.Popen(argv, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                            text=True, start_new_session=True,
                            env={**os.environ, "COLUMNS": "200"})
    try:
        text, _ = proc.communicate(timeout=timeout_s)
    except subprocess.TimeoutExpired:
        from scenarios.cli.children import stop_process

        stop_process(proc)  # hilnav stops the autopilot it started when it is stopped
        text = (proc.stdout.read() if proc.stdout else "") + "\n(bench timeout)"
    wall_s = time.perf_counter() - t0
    row: dict[str, Any] = {
        "autopilot": kind, "binary": binary.name,
        "scenario": portable(str(scenario), binary, out),
        "command": portable(shlex.join(shown), binary, out), "exit_code": proc.returncode,
        "wall_s": round(wall_s, 1),
        "output_tail": [portable(ln, binary, out)
                        for ln in text.splitlines() if ln.strip()][-_TAIL_LINES:],
    }
    summary_path = out / "summary.json"
    if not summary_path.is_file():
        row["summary"] = None
        return row
    s = json.loads(summary_path.read_text())
    row.update(summary_row(s))
    row["altitude_hold"] = altitude_hold(out / "run.tlog", s)
    ap = s.get("autopilot") or {}
    if ap.get("aided_vs_unaided") is not None:
        row["aided_vs_unaided"] = ap["aided_vs_unaided"]
        base = out / "unaided"
        if (base / "summary.json").is_file():
            b = json.loads((base / "summary.json").read_text())
            row["unaided_flight"] = {**summary_row(b),
                                     "altitude_hold": altitude_hold(base / "run.tlog", b)}
    return row


def portable(text: str, binary: Path, out: Path) -> str:
    """``text`` without this machine's paths: the binary by its file name, the run folder as
    ``OUT``, files of the repository relative to it (the result file is committed)."""
    return (text.replace(str(out), "OUT").replace(str(binary), binary.name)
            .replace(f"{ROOT}/", ""))


def summary_row(s: dict[str, Any]) -> dict[str, Any]:
    """What the bench keeps of one run's ``summary.json``."""
    ap = s.get("autopilot") or {}
    process = ap.get("process") or {}
    counters = ap.get("counters") or {}
    lockstep_keys = ("steps", "steps_answered", "packets", "repeated_frames", "skipped_frames",
                     "restarts", "controls", "lockstep_controls", "reconnects",
                     "clipped_controls", "params_sent", "params_acked",
                     "telemetry_position_reports", "telemetry_statustexts")

    def outage(o: dict[str, Any]) -> dict[str, Any]:
        return {k: o.get(k) for k in ("start_s", "end_s", "horizontal_rmse_m",
                                      "horizontal_max_m", "vertical_rmse_m")}

    return {
        "passed": s.get("passed"),
        "failures": s.get("failures") or [],
        "sim_duration_s": s.get("sim_duration_s"),
        "flight_ended": (s.get("health") or {}).get("flight_ended"),
        "version": process.get("version"),
        "process": {k: process.get(k) for k in ("instance", "ports", "pid", "exit_code",
                                                "stopped_by")},
        "connected": ap.get("connected"),
        "stalled": ap.get("stalled"),
        "trim_released_s": ap.get("trim_released_s"),
        "estimate_from_s": ap.get("estimate_from_s"),
        "lockstep": {k: counters[k] for k in lockstep_keys if k in counters},
        "hilnav": {"outages": [outage(o) for o in s.get("outages") or []],
                   "gnss_on_horizontal_rmse_m": (s.get("gnss_on") or {}).get(
                       "horizontal_rmse_m")},
        "autopilot_estimate": {"outages": [outage(o) for o in ap.get("outages") or []],
                               "gnss_on_horizontal_rmse_m": (ap.get("gnss_on") or {}).get(
                                   "horizontal_rmse_m"),
                               "outages_not_denied": ap.get("outages_not_denied"),
                               "problem": ap.get("problem")},
        "script": ap.get("script"),
        "failsafes": [t.get("text") for t in (ap.get("health") or {}).get("failsafes") or []],
    }


TURN_ROLL_DEG = 10.0
"""A truth roll beyond this is a turn: the altitude hold is judged outside turns."""
REACHED_M = 10.0
"""After the commanded altitude changes, the hold is judged from when the truth first comes
this close to it (the climb or descent to it is not a hold)."""
HOLD_TARGET_M = 30.0
"""The bench's target: within this of the commanded altitude outside turns."""


def altitude_hold(tlog: Path, summary: dict[str, Any]) -> dict[str, Any]:
    """The truth's height against the altitude the autopilot was commanded to hold.

    The commanded altitude is that of the mission item the autopilot flew (its MISSION_CURRENT,
    recorded in ``autopilot.health.mission_current``; the list sent in
    ``autopilot.script.mission``): a waypoint's or loiter's altitude above mean sea level.
    Take-off, return to launch (the autopilot's own altitude rules) and the home slot command
    none. After each change of commanded altitude the hold starts when the truth
    (HIL_STATE_QUATERNION of the run's ``.tlog``) first comes within ``REACHED_M`` of it.
    Returns the deviation (truth - commanded, m) outside turns (|roll| <= ``TURN_ROLL_DEG``):
    lowest, highest, RMS and the seconds judged, the same inside turns, and whether it stays
    within ``HOLD_TARGET_M``; or ``{"problem": why}`` when there is nothing to judge."""
    ap = summary.get("autopilot") or {}
    mission = (ap.get("script") or {}).get("mission") or []
    changes = (ap.get("health") or {}).get("mission_current") or []
    if not mission:
        return {"problem": "no mission was sent"}
    if not changes:
        return {"problem": "the autopilot reported no MISSION_CURRENT"}
    if not tlog.is_file():
        return {"problem": f"no {tlog.name}"}
    import numpy as np

    from fusion.rotations import quat_to_euler
    from hil.codec import mavlink2
    from hil.tlog import read_tlog

    parser = mavlink2.MAVLink(None)
    parser.robust_parsing = True
    rows: list[tuple[float, float, float]] = []
    for _time_us, frame in read_tlog(tlog):
        for msg in parser.parse_buffer(frame) or []:
            if msg.get_msgId() == mavlink2.MAVLINK_MSG_ID_HIL_STATE_QUATERNION:
                roll = float(quat_to_euler(np.asarray(msg.attitude_quaternion, float))[0])
                rows.append((msg.time_usec * 1e-6, msg.alt * 1e-3, roll))
    if len(rows) < 2:
        return {"problem": f"no truth in {tlog.name}"}
    data = np.array(rows)
    t, alt, roll = data[:, 0] - data[0, 0], data[:, 1], data[:, 2]
    holds = {int(m["seq"]): m.get("alt_msl_m") for m in mission
             if str(m.get("label", "")).startswith(("waypoint", "loiter"))}
    change_t = np.array([float(c["time_s"]) for c in changes])
    change_seq = [int(c["seq"]) for c in changes]
    idx = np.searchsorted(change_t, t, side="right") - 1
    commanded = np.array([np.nan if i < 0 or holds.get(change_seq[i]) is None
                          else float(holds[change_seq[i]]) for i in idx])
    judged = np.zeros(t.size, bool)
    reached = False
    for k in range(t.size):
        if not np.isfinite(commanded[k]):
            reached = False
            continue
        if k > 0 and commanded[k] != commanded[k - 1]:
            reached = False
        reached = reached or abs(alt[k] - commanded[k]) <= REACHED_M
        judged[k] = reached
    dt = float(np.median(np.diff(t)))
    turning = np.abs(np.degrees(roll)) > TURN_ROLL_DEG

    def stats(keep: np.ndarray) -> dict[str, Any] | None:
        if not keep.any():
            return None
        dev = alt[keep] - commanded[keep]
        return {"seconds": round(float(keep.sum()) * dt, 1),
                "min_deviation_m": round(float(dev.min()), 1),
                "max_deviation_m": round(float(dev.max()), 1),
                "rms_deviation_m": round(float(np.sqrt(np.mean(dev ** 2))), 1)}

    straight = stats(judged & ~turning)
    return {"commanded_alt_msl_m": sorted({round(float(a), 1) for a in commanded[judged]}),
            "turn_roll_deg": TURN_ROLL_DEG, "target_m": HOLD_TARGET_M,
            "outside_turns": straight, "in_turns": stats(judged & turning),
            "within_target": None if straight is None else bool(
                max(-straight["min_deviation_m"], straight["max_deviation_m"])
                <= HOLD_TARGET_M)}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    ap.add_argument("--arduplane", type=Path, help="ArduPlane SITL binary (arduplane).")
    ap.add_argument("--px4", type=Path, help="PX4 SITL binary (build/px4_sitl_default/bin/px4).")
    ap.add_argument("--out", type=Path, default=ROOT / "bench" / "results" / "autopilot_sitl.json")
    ap.add_argument("--scenario", action="append", default=[], metavar="KIND=PATH",
                    help="Fly this scenario with autopilot KIND (ardupilot, px4) instead of "
                         "the library's (repeatable).")
    ap.add_argument("--runs", type=Path, default=None,
                    help="Folder of the runs (default: beside --out, autopilot_sitl_runs/).")
    args = ap.parse_args(argv)
    given = {"ardupilot": args.arduplane, "px4": args.px4}
    if not any(given.values()):
        ap.error("give --arduplane PATH and/or --px4 PATH")
    chosen: dict[str, Path] = {}
    for item in args.scenario:
        kind, sep, path = item.partition("=")
        if not sep or kind not in SCENARIOS:
            ap.error(f"--scenario {item!r}: expected ardupilot=PATH or px4=PATH")
        chosen[kind] = Path(path).resolve()
    runs = args.runs or args.out.parent / "autopilot_sitl_runs"
    rows = []
    for kind, binary in given.items():
        if binary is None:
            continue
        print(f"{kind}: {binary} ...", flush=True)
        row = run_one(kind, binary.expanduser().resolve(), runs / kind, chosen.get(kind))
        print(f"{kind}: exit {row['exit_code']} in {row['wall_s']} s; "
              f"version {row.get('version')}; failures {row.get('failures')}", flush=True)
        rows.append(row)
    result = {"bench": "autopilot_sitl", "python": platform.python_version(),
              "machine": platform.machine(), "cpus": os.cpu_count(), "runs": rows}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=2) + "\n")
    print(f"-> {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
