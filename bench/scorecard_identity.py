"""Behaviour check for refactors: the same seed gives the same scorecard bytes.

``record`` flies every library scenario with ``hilnav run --seed S`` (default 100) and replays
one of the recorded logs with ``hilnav replay`` (plain, and with ``--bridge gmdh --altitude
loop-mpc``), keeping each ``summary.json``. ``diff`` compares two such folders field by field
after dropping the wall-clock fields (``wall_s``, ``realtime_factor``, and the measured
``fusion_us_per_sample``), and exits 1 on any other difference, listing the paths that differ.

Only the command line is used (``hilnav run`` / ``hilnav replay``, the output contract of
docs/architecture.md), so the check holds across any restructuring of the code behind it.

    python bench/scorecard_identity.py record DIR [--seed 100] [--jobs 2] [--only NAME,...]
    python bench/scorecard_identity.py diff BEFORE_DIR AFTER_DIR
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
LIBRARY = ROOT / "scenarios" / "library"
#: Fields that measure the machine, not the navigation.
WALL_CLOCK_FIELDS = frozenset({"wall_s", "realtime_factor", "fusion_us_per_sample"})
#: The log replayed (a library run whose tlog has outages, turns and a baro).
REPLAY_SOURCE = "turning-60s-outages"
REPLAYS = {
    "replay-default": [],
    "replay-gmdh-loop-mpc": ["--bridge", "gmdh", "--altitude", "loop-mpc"],
}


def _hilnav() -> list[str]:
    # ``python -m`` with the tree's root as working folder, never the venv's ``hilnav`` script:
    # that script names the entry function of the tree it was installed from, which an export
    # of another revision on PYTHONPATH may not have
    return [sys.executable, "-m", "scenarios.cli"]


def _run(args: list[str], log: Path) -> int:
    with log.open("w") as fh:
        return subprocess.run(args, stdout=fh, stderr=subprocess.STDOUT, cwd=ROOT,
                              env={**os.environ, "COLUMNS": "200"}, check=False).returncode


def record(out: Path, seed: int, jobs: int, only: set[str] | None) -> int:
    out.mkdir(parents=True, exist_ok=True)
    names = sorted(p.stem for p in LIBRARY.glob("*.yaml"))
    if only:
        names = [n for n in names if n in only]

    def one(name: str) -> tuple[str, int]:
        run_dir = out / "runs" / name
        code = _run([*_hilnav(), "run", str(LIBRARY / f"{name}.yaml"), "--out", str(run_dir),
                     "--seed", str(seed), "--quiet"], out / f"{name}.log")
        src = run_dir / "summary.json"
        if src.is_file():
            (out / f"{name}.json").write_text(src.read_text())
        return name, code

    with ThreadPoolExecutor(max_workers=max(1, jobs)) as pool:
        for name, code in pool.map(one, names):
            print(f"{name}: exit {code}", flush=True)
    tlog = out / "runs" / REPLAY_SOURCE / "run.tlog"
    if tlog.is_file():
        for label, extra in REPLAYS.items():
            rdir = out / "runs" / label
            code = _run([*_hilnav(), "replay", str(tlog), "--out", str(rdir), *extra],
                        out / f"{label}.log")
            if (rdir / "summary.json").is_file():
                (out / f"{label}.json").write_text((rdir / "summary.json").read_text())
            print(f"{label}: exit {code}", flush=True)
    return 0


def _strip(node: Any) -> Any:
    if isinstance(node, dict):
        return {k: _strip(v) for k, v in node.items() if k not in WALL_CLOCK_FIELDS}
    if isinstance(node, list):
        return [_strip(v) for v in node]
    return node


def _differences(a: Any, b: Any, path: str = "") -> Iterator[str]:
    if isinstance(a, dict) and isinstance(b, dict):
        for k in sorted(set(a) | set(b)):
            if k not in a or k not in b:
                yield f"{path}.{k}: only in {'after' if k in b else 'before'}"
            else:
                yield from _differences(a[k], b[k], f"{path}.{k}")
    elif isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            yield f"{path}: {len(a)} vs {len(b)} items"
        for i, (x, y) in enumerate(zip(a, b, strict=False)):
            yield from _differences(x, y, f"{path}[{i}]")
    elif a != b and not (isinstance(a, float) and isinstance(b, float)
                         and math.isnan(a) and math.isnan(b)):
        yield f"{path}: {a!r} -> {b!r}"


def diff(before: Path, after: Path) -> int:
    names = sorted({p.name for p in before.glob("*.json")} | {p.name for p in after.glob("*.json")})
    if not names:
        print(f"no summaries in {before} or {after}", file=sys.stderr)
        return 2
    bad = 0
    for name in names:
        pa, pb = before / name, after / name
        if not (pa.is_file() and pb.is_file()):
            print(f"{name}: missing in {'after' if pa.is_file() else 'before'}")
            bad += 1
            continue
        sa = json.dumps(_strip(json.loads(pa.read_text())), sort_keys=True)
        sb = json.dumps(_strip(json.loads(pb.read_text())), sort_keys=True)
        if sa == sb:
            print(f"{name}: identical")
            continue
        bad += 1
        lines = list(_differences(json.loads(sa), json.loads(sb)))
        print(f"{name}: {len(lines)} differences")
        for line in lines[:20]:
            print(f"    {line}")
    print(f"{len(names) - bad} of {len(names)} identical (wall-clock fields excluded)")
    return 1 if bad else 0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    rec = sub.add_parser("record", help="run the library and the replays into DIR")
    rec.add_argument("out", type=Path)
    rec.add_argument("--seed", type=int, default=100)
    rec.add_argument("--jobs", type=int, default=2)
    rec.add_argument("--only", default="", help="comma-separated scenario names")
    dif = sub.add_parser("diff", help="compare two recorded folders")
    dif.add_argument("before", type=Path)
    dif.add_argument("after", type=Path)
    args = ap.parse_args(argv)
    if args.cmd == "record":
        only = {s.strip() for s in args.only.split(",") if s.strip()} or None
        return record(args.out, args.seed, args.jobs, only)
    return diff(args.before, args.after)


if __name__ == "__main__":
    raise SystemExit(main())
