"""Benchmark: instructions of a short ``hilnav run`` (valgrind), before and after, load-free.

A short flight makes the fixed costs of ``hilnav run`` (start-up, set-up, scoring, reports,
exit) most of the process; its instruction count (valgrind ``cachegrind``'s ``I refs``) does
not depend on what else the machine runs, unlike CPU seconds. The scenario (default
``turning-60s-outages``) keeps its seed, sensors and plan; its duration is set by
``--duration`` (>= 80 s) with one 60 s GNSS outage from 10 s on (the library's criteria
measure the error 60 s into an outage), so every plot is drawn. The same
command runs on a ``git archive`` of ``--base`` (first on ``PYTHONPATH``, its root as working
folder) and on this tree, and ``same_bytes`` says whether both wrote ``run.tlog`` and the PNGs
with the same bytes. Slow: ~50x the plain run.

    python bench/fixed_cost_instructions.py --base 4f47f88 \\
        --out bench/results/fixed_cost_instructions_s14_fixed.json
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

import yaml
from run_end_to_end import same_bytes  # this folder (the script's own) is on sys.path

ROOT = Path(__file__).resolve().parent.parent
LIBRARY = ROOT / "scenarios" / "library"


def short_scenario(source: Path, duration_s: float, folder: Path) -> Path:
    """The scenario YAML lasting ``duration_s`` with one 60 s GNSS outage from 10 s on."""
    doc: dict[str, Any] = yaml.safe_load(source.read_text(encoding="utf-8"))
    doc["duration_s"] = duration_s
    doc["events"] = [{"type": "gnss_outage", "at": 10, "duration": 60}]
    path = folder / f"{doc['name']}-{duration_s:g}s.yaml"
    path.write_text(yaml.safe_dump(doc, sort_keys=False), encoding="utf-8")
    return path


def instructions(tree: Path, scenario: Path, out: Path) -> int:
    """Instructions of ``python -m scenarios.cli run SCENARIO --out OUT --quiet`` on the code
    of ``tree``, counted by valgrind."""
    cmd = ["valgrind", "--tool=cachegrind", "--cache-sim=no", "--cachegrind-out-file=/dev/null",
           sys.executable, "-m", "scenarios.cli", "run", str(scenario), "--out", str(out),
           "--quiet"]
    proc = subprocess.run(cmd, cwd=tree, env={**os.environ, "PYTHONPATH": str(tree)},
                          capture_output=True, text=True, check=False)
    found = re.search(r"I\s+refs:\s+([\d,]+)", proc.stderr)
    if proc.returncode not in (0, 1) or found is None:  # 1: criteria failed, a complete run
        sys.exit(f"hilnav run under valgrind failed ({proc.returncode}):\n{proc.stderr[-2000:]}")
    return int(found.group(1).replace(",", ""))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--base", required=True, help="git revision counted against this tree")
    ap.add_argument("--scenario", default="turning-60s-outages", help="library scenario name")
    ap.add_argument("--duration", type=float, default=80.0, help="simulated seconds (>= 80)")
    ap.add_argument("--out", type=Path,
                    default=ROOT / "bench/results/fixed_cost_instructions.json")
    args = ap.parse_args()
    if args.duration < 80:
        sys.exit("--duration must be >= 80 s")
    load_before = os.getloadavg()[0]
    with tempfile.TemporaryDirectory(prefix="hilnav-instr-") as tmp:
        folder = Path(tmp)
        base = folder / "base"
        base.mkdir()
        archive = subprocess.run(["git", "archive", args.base], cwd=ROOT, check=True,
                                 capture_output=True).stdout
        subprocess.run(["tar", "-x", "-C", str(base)], input=archive, check=True)
        scenario = short_scenario(LIBRARY / f"{args.scenario}.yaml", args.duration, folder)
        count = {key: instructions(tree, scenario, folder / key)
                 for key, tree in (("before", base), ("after", ROOT))}
        same = same_bytes(folder / "before", folder / "after")
    result = {
        "benchmark": "fixed_cost_instructions",
        "base": args.base,
        "scenario": args.scenario,
        "sim_duration_s": args.duration,
        "method": "valgrind cachegrind I refs of the whole hilnav run process",
        "load_average_1m_before": load_before,
        "load_average_1m_after": os.getloadavg()[0],
        "instructions": count,
        "after_minus_before": count["after"] - count["before"],
        "after_over_before": count["after"] / count["before"],
        "same_bytes": same,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=2) + "\n", encoding="utf-8")
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
