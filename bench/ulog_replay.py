"""hilnav's filter against PX4's own EKF2 on PX4's sample ULog files.

Replays every ``*.ulg`` in ``--logs DIR`` (PX4's public sample logs ``sample_log_small``,
``sample_logging_tagged_and_default_params`` and ``sample_px4_events``, pyulog's test data)
with ``hilnav replay`` twice: ``--settle 0`` (the whole overlap of the two estimates is
compared) and the default ``--settle 60`` (fitted to the log, see ``summary.json``
``settling``); and the SITL hop with ``--gnss-off 18:8`` (an 8-s GNSS cut scored against
EKF2). Each row keeps the exit code (and the one-line error of a log that cannot be replayed),
the GNSS-on differences to EKF2 (horizontal / vertical position, roll / pitch / yaw), the
outage figures, the alignment and the settling actually applied.

These are *differences to another estimator*, not errors: EKF2 is the reference, not truth.
The logs are short (6-31 s) and mostly at rest; they test log import and alignment at rest.

    python bench/ulog_replay.py --logs DIR [--out bench/results/ulog_replay.json]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
GNSS_CUT = {"sample_px4_events": "18:8"}


def _hilnav() -> list[str]:
    exe = Path(sys.executable).with_name("hilnav")
    return [str(exe)] if exe.exists() else [sys.executable, "-m", "scenarios.cli"]


def _replay(log: Path, args: list[str]) -> dict[str, Any]:
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        res = subprocess.run([*_hilnav(), "replay", str(log), "--out", tmp, *args],
                             capture_output=True, text=True, cwd=ROOT, check=False,
                             env={**os.environ, "COLUMNS": "300"})
        row: dict[str, Any] = {"args": args, "exit": res.returncode,
                               "wall_s": time.perf_counter() - t0}
        if res.returncode != 0:
            row["error"] = (res.stderr or res.stdout).strip().splitlines()[-1]
            return row
        s = json.loads((Path(tmp) / "summary.json").read_text())
    row.update({
        "reference": s["reference"],
        "gnss_on": s["gnss_on"],
        "outages": [{k: o[k] for k in ("start_s", "end_s", "horizontal_rmse_m",
                                       "horizontal_max_m", "vertical_rmse_m")}
                    for o in s["outages"]],
        "settling": s["settling"],
        "alignment": s["alignment"],
        "gnss_off": s["gnss_off"],
        "log_duration_s": s["input"]["log_duration_s"],
    })
    return row


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--logs", type=Path, required=True,
                    help="folder of PX4 .ulg logs (pyulog's test data)")
    ap.add_argument("--out", type=Path, default=ROOT / "bench" / "results" / "ulog_replay.json")
    a = ap.parse_args()
    logs = sorted(a.logs.glob("*.ulg"))
    if not logs:
        print(f"no .ulg files in {a.logs}", file=sys.stderr)
        return 2
    results: dict[str, Any] = {}
    for log in logs:
        runs = [["--settle", "0"], []]
        if log.stem in GNSS_CUT:
            runs.append(["--gnss-off", GNSS_CUT[log.stem]])
        results[log.stem] = [_replay(log, args) for args in runs]
        for row in results[log.stem]:
            on = row.get("gnss_on", {})
            print(log.stem, row["args"], row["exit"], row.get("error", ""),
                  {k: None if v is None else round(v, 3) for k, v in on.items()})
    logs_dir = os.path.relpath(a.logs.resolve(), ROOT)  # relative to the repo: portable
    out = {"logs_dir": logs_dir, "load_average": os.getloadavg(), "results": results}
    a.out.parent.mkdir(parents=True, exist_ok=True)
    a.out.write_text(json.dumps(out, indent=1) + "\n")
    print(f"-> {a.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
