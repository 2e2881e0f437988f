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
    args = ap.parse_args()
    load_before = os.getloadavg()[0]
    cpu: dict[str, dict[str, list[float]]] = {"before": {}, "after": {}}
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
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=2) + "\n", encoding="utf-8")
    print(json.dumps(best, indent=2))


if __name__ == "__main__":
    main()
