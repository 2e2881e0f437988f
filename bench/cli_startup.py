"""Benchmark: what the ``hilnav`` command line costs before a command does any work.

CPU seconds (``getrusage`` of the child) of ``python -m scenarios.cli ARGS`` for

- ``help``: ``hilnav --help``;
- ``run_help``: ``hilnav run --help``;
- ``run_bad_input``: ``hilnav run`` on a scenario file that does not exist (exit 2, one line);
- ``list``: ``hilnav list --json``;

each ``--rounds`` times, and with ``--base REV`` the same commands from a ``git archive`` of
REV (first on ``PYTHONPATH``, its root as working folder) alternately with this tree, so the
before / after holds on a loaded machine (the best of the rounds is compared). The load
average is recorded before and after.

    python bench/cli_startup.py --base 4be3151 --rounds 5 --out bench/results/cli_startup.json

``--imports`` adds ``imports``: where the imports of ``hilnav run``'s set-up go. One fresh
child per round imports :data:`IMPORT_STAGES` one after the other, in the order a run loads
them, and times each stage (CPU seconds, ``process_time``; a stage pays only what the stages
before it did not load) with the collector off, as the run command's settled heap has it;
``modules`` lists which of :data:`WATCHED` each stage loaded.

    python bench/cli_startup.py --base 4f47f88 --rounds 5 --imports \
        --out bench/results/cli_startup_s14_fixed.json
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
COMMANDS: dict[str, list[str]] = {
    "help": ["--help"],
    "run_help": ["run", "--help"],
    "run_bad_input": ["run", "no-such-scenario.yaml", "--out", "unused-run-folder"],
    "list": ["list", "--json"],
}
EXPECTED_EXIT = {"help": 0, "run_help": 0, "run_bad_input": 2, "list": 0}

#: The imports of ``hilnav run``, stage by stage in the order the run loads them (each stage
#: pays only what is not loaded yet).
IMPORT_STAGES: dict[str, tuple[str, ...]] = {
    "cli": ("scenarios.cli.app",),
    "numpy": ("numpy",),
    "pydantic": ("pydantic",),
    "scipy_linalg": ("scipy.linalg",),  # fusion.altitude
    "fusion": ("fusion.config", "fusion.filter", "fusion.bridging.registry"),
    "scipy_signal": ("scipy.signal",),  # sim.imu (lfilter)
    "hil_codec": ("hil.codec",),  # pymavlink's dialects
    "sim": ("sim.flight", "sim.presets", "sim.faults"),  # jsbsim, yaml
    "hil_pipeline": ("hil.pipeline",),
    "runner": ("scenarios.runner",),
    "report": ("scenarios.report", "scenarios.html", "scenarios.junit"),  # matplotlib
}
#: Libraries whose first load is named in ``modules``.
WATCHED = ("numpy", "scipy.linalg", "scipy.special", "scipy.optimize", "scipy.stats",
           "scipy.interpolate", "scipy.spatial", "scipy.signal", "pydantic", "pymavlink",
           "jsbsim", "yaml", "matplotlib", "PIL", "zenoh")

_IMPORT_CHILD = """
import gc, importlib, json, sys, time
gc.disable()
stages = json.loads(sys.argv[1])
watched = json.loads(sys.argv[2])
cpu, loaded = {}, {}
for stage, modules in stages.items():
    had = set(sys.modules)
    t0 = time.process_time()
    for m in modules:
        importlib.import_module(m)
    cpu[stage] = time.process_time() - t0
    loaded[stage] = [w for w in watched if w in sys.modules and w not in had]
print(json.dumps({"cpu_s": cpu, "modules": loaded}))
"""


def import_stages(tree: Path) -> dict[str, Any]:
    """One fresh child on the code of ``tree``: CPU seconds of each of :data:`IMPORT_STAGES`
    and the watched libraries each one loaded."""
    proc = subprocess.run([sys.executable, "-c", _IMPORT_CHILD, json.dumps(IMPORT_STAGES),
                           json.dumps(WATCHED)], cwd=tree,
                          env={**os.environ, "PYTHONPATH": str(tree)},
                          capture_output=True, text=True, check=False)
    if proc.returncode != 0:
        sys.exit(f"the import child in {tree} failed:\n{proc.stderr[-2000:]}")
    result: dict[str, Any] = json.loads(proc.stdout)
    return result


def cpu_of(tree: Path, args: list[str], expected: int) -> float:
    """CPU seconds of ``python -m scenarios.cli ARGS`` run on the code of ``tree``."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    proc = subprocess.run([sys.executable, "-m", "scenarios.cli", *args], cwd=tree,
                          env={**os.environ, "PYTHONPATH": str(tree), "COLUMNS": "100"},
                          capture_output=True, text=True, check=False)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode != expected:
        sys.exit(f"{args} in {tree} exited {proc.returncode}, expected {expected}:\n"
                 f"{proc.stderr[-2000:]}")
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--base", help="git revision timed alternately with this tree")
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--out", type=Path, default=ROOT / "bench/results/cli_startup.json")
    ap.add_argument("--imports", action="store_true",
                    help="also time the imports of `hilnav run`, stage by stage")
    args = ap.parse_args()
    load_before = os.getloadavg()[0]
    cpu: dict[str, dict[str, list[float]]] = {"before": {}, "after": {}}
    imports: dict[str, list[dict[str, Any]]] = {"before": [], "after": []}
    with tempfile.TemporaryDirectory(prefix="hilnav-cli-") as tmp:
        trees = {"after": ROOT}
        if args.base:
            base = Path(tmp) / "base"
            base.mkdir()
            archive = subprocess.run(["git", "archive", args.base], cwd=ROOT, check=True,
                                     capture_output=True).stdout
            subprocess.run(["tar", "-x", "-C", str(base)], input=archive, check=True)
            trees = {"before": base, "after": ROOT}
        for _ in range(args.rounds):
            for key, tree in trees.items():
                for name, cmd in COMMANDS.items():
                    cpu[key].setdefault(name, []).append(cpu_of(tree, cmd, EXPECTED_EXIT[name]))
                if args.imports:
                    imports[key].append(import_stages(tree))
    best = {key: {name: min(v) for name, v in rows.items()} for key, rows in cpu.items() if rows}
    result: dict[str, Any] = {
        "benchmark": "cli_startup",
        "python": platform.python_version(),
        "machine": platform.machine(),
        "base": args.base,
        "rounds": args.rounds,
        "timer": "CPU seconds of each child (getrusage)",
        "load_average_1m_before": load_before,
        "load_average_1m_after": os.getloadavg()[0],
        "commands": {name: ["hilnav", *cmd] for name, cmd in COMMANDS.items()},
        "cpu_s": cpu,
        "best_cpu_s": best,
    }
    if args.imports:
        result["imports"] = {
            "stages": IMPORT_STAGES,
            "cpu_s": {key: [r["cpu_s"] for r in rows] for key, rows in imports.items() if rows},
            "best_cpu_s": {key: {stage: min(r["cpu_s"][stage] for r in rows)
                                 for stage in IMPORT_STAGES}
                           for key, rows in imports.items() if rows},
            "best_total_cpu_s": {key: min(sum(r["cpu_s"].values()) for r in rows)
                                 for key, rows in imports.items() if rows},
            "modules": {key: rows[0]["modules"] for key, rows in imports.items() if rows},
        }
        print(json.dumps(result["imports"]["best_cpu_s"], indent=2))
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=2) + "\n", encoding="utf-8")
    print(json.dumps(best, indent=2))


if __name__ == "__main__":
    main()
