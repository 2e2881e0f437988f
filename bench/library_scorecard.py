"""Benchmark: the whole scenario library, scored with its own pass criteria.

Every ``scenarios/library/*.yaml`` is flown, fused and scored exactly as ``hilnav run`` does it
(:func:`scenarios.runner.run_scenario`, the filter tuned from the scenario's IMU datasheet,
the scenario's bridging and altitude methods unless ``--bridge`` / ``--altitude`` override
them). The scorecard lists per scenario whether it passed, every failing criterion with its
measured value and limit, and the wall time; and the totals.

Seeds: the library files carry their own seeds (1-19), and those are the seeds the criteria
and the filter tuning were looked at with. The scorecard flies **held-out** seeds instead:
``--seeds 100`` by default (one flight per scenario and seed; several seeds are
comma-separated, ``--seeds 100,101,102``). ``--seeds file`` uses each scenario's own seed.

The numbers depend on the code they were measured with: the JSON records ``git rev-parse
HEAD`` and ``git status --short`` so a result can be placed.

    python bench/library_scorecard.py [--out bench/results/library_scorecard.json]
        [--seeds 100] [--bridge gmdh] [--altitude mpc] [--jobs 1] [--only NAME,...]
        [--keep-runs DIR]
"""

from __future__ import annotations

import argparse
import os
import platform
import subprocess
import sys
import tempfile
import time
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from rich.console import Console  # noqa: E402
from rich.progress import (  # noqa: E402
    BarColumn,
    MofNCompleteColumn,
    Progress,
    TextColumn,
    TimeElapsedColumn,
)

from scenarios.jsonable import write_json  # noqa: E402
from scenarios.runner import run_scenario  # noqa: E402
from scenarios.schema import list_library, load_scenario  # noqa: E402

DEFAULT_OUT = ROOT / "bench" / "results" / "library_scorecard.json"
console = Console(stderr=True)


def parse_seeds(text: str) -> list[int] | None:
    """``"100,101"`` -> ``[100, 101]``; ``"file"`` -> ``None`` (each scenario's own seed)."""
    if text.strip() == "file":
        return None
    try:
        seeds = [int(s) for s in text.split(",") if s.strip()]
    except ValueError:
        raise ValueError(
            f"--seeds must be comma-separated integers or 'file', got {text!r}") from None
    if not seeds:
        raise ValueError("--seeds is empty")
    return seeds


def _git(*args: str) -> str:
    try:
        out = subprocess.run(["git", *args], cwd=ROOT, capture_output=True, text=True,
                             check=True, timeout=30)
    except (OSError, subprocess.SubprocessError) as error:
        return f"unavailable: {error}"
    return out.stdout.rstrip("\n")  # keep the leading blank of " M path"


def run_one(
    path: Path, seed: int | None, bridge: str | None, altitude: str | None, out_dir: Path,
) -> dict[str, Any]:
    """Fly, fuse and score one scenario; the scorecard row (module level: runs in workers)."""
    scn = load_scenario(path)
    scn = scn.with_overrides(seed=seed, bridge=bridge, altitude=altitude)
    t0 = time.perf_counter()
    result = run_scenario(scn, out_dir, tlog=False, reports=False)
    wall = time.perf_counter() - t0
    s = result.summary
    criteria = s.get("criteria", [])
    failing = [
        {"name": c["name"], "metric": c["path"], "value": c["value"], "op": c["op"],
         "limit": c["limit"]}
        for c in criteria if not c["ok"]
    ]
    return {
        "scenario": scn.name,
        "file": str(path.relative_to(ROOT)) if path.is_relative_to(ROOT) else str(path),
        "seed": scn.seed,
        "bridge": s.get("bridge"),
        "altitude": s.get("altitude"),
        "passed": bool(s.get("passed")),
        "criteria": len(criteria),
        "criteria_failed": len(failing),
        "failing": failing,
        "flight_ended": s.get("health", {}).get("flight_ended"),
        "sim_duration_s": s.get("sim_duration_s"),
        "wall_s": wall,
        "realtime_factor": s.get("sim_duration_s", 0.0) / wall if wall > 0 else None,
    }


def markdown_table(rows: Sequence[dict[str, Any]]) -> str:
    """The scorecard as a Markdown table (one line per scenario and seed)."""
    lines = ["| scenario | seed | bridge / altitude | result | failing criteria "
             "(measured vs limit) | wall (s) |", "|---|---|---|---|---|---|"]
    for r in rows:
        fails = "; ".join(
            f"{f['name']}: {_fmt(f['value'])} (limit {f['op']} {_fmt(f['limit'])})"
            for f in r["failing"]) or "-"
        if r.get("flight_ended"):
            fails = f"flight ended: {r['flight_ended']}; " + fails
        result = "pass" if r["passed"] else f"FAIL {r['criteria_failed']}/{r['criteria']}"
        lines.append(f"| {r['scenario']} | {r['seed']} | {r['bridge']} / {r['altitude']} "
                     f"| {result} | {fails} | {r['wall_s']:.0f} |")
    return "\n".join(lines) + "\n"


def _fmt(v: Any) -> str:
    return "missing" if v is None else format(v, ".3g")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, default=DEFAULT_OUT)
    ap.add_argument("--seeds", default="100",
                    help="comma-separated held-out seeds, or 'file' for the scenarios' own")
    ap.add_argument("--bridge", default=None, help="override every scenario's bridging method")
    ap.add_argument("--altitude", default=None, help="override every scenario's altitude method")
    ap.add_argument("--jobs", type=int, default=1, help="scenarios flown in parallel")
    ap.add_argument("--only", default=None, help="comma-separated scenario names (default all)")
    ap.add_argument("--keep-runs", type=Path, default=None,
                    help="keep each run's summary.json under this folder")
    args = ap.parse_args(argv)
    try:
        seeds = parse_seeds(args.seeds)
    except ValueError as error:
        ap.error(str(error))
    if args.jobs < 1:
        ap.error("--jobs must be >= 1")
    # a scenario flown by an autopilot (autopilot: px4 | ardupilot) needs that autopilot
    # connected; none runs here, so the scorecard of hilnav's own flights leaves it out
    flown_by_autopilot = [p for p in list_library() if load_scenario(p).autopilot.flies]
    paths = [p for p in list_library() if p not in flown_by_autopilot]
    for p in flown_by_autopilot:
        console.print(f"skipped {p.stem}: flown by an autopilot in the loop (none runs here)")
    if args.only:
        wanted = {n.strip() for n in args.only.split(",") if n.strip()}
        unknown = wanted - {p.stem for p in paths}
        if unknown:
            ap.error(f"--only: unknown scenarios {sorted(unknown)}; "
                     f"valid: {', '.join(p.stem for p in paths)}")
        paths = [p for p in paths if p.stem in wanted]
    jobs = [(p, s) for p in paths for s in (seeds if seeds is not None else [None])]

    tmp = None if args.keep_runs else tempfile.TemporaryDirectory(prefix="scorecard-")
    runs_dir = args.keep_runs or Path(tmp.name if tmp else ".")
    commit, status = _git("rev-parse", "HEAD"), _git("status", "--short")
    rows: list[dict[str, Any]] = []
    t0 = time.perf_counter()
    progress = Progress(TextColumn("[bold]{task.description}"), BarColumn(),
                        MofNCompleteColumn(), TimeElapsedColumn(), console=console)
    try:
        with progress:
            task = progress.add_task("library", total=len(jobs))

            def done(row: dict[str, Any]) -> None:
                rows.append(row)
                mark = "[green]pass[/]" if row["passed"] else "[red]FAIL[/]"
                progress.console.print(f"{mark} {row['scenario']} (seed {row['seed']}) "
                                       f"{row['wall_s']:.0f} s", highlight=False)
                progress.advance(task)

            def folder(p: Path, s: int | None) -> Path:
                return runs_dir / f"{p.stem}-seed{s if s is not None else 'file'}"

            if args.jobs == 1:
                for p, s in jobs:
                    progress.update(task, description=f"{p.stem} (seed {s})")
                    done(run_one(p, s, args.bridge, args.altitude, folder(p, s)))
            else:
                with ProcessPoolExecutor(max_workers=args.jobs) as pool:
                    futures = [pool.submit(run_one, p, s, args.bridge, args.altitude,
                                           folder(p, s)) for p, s in jobs]
                    for fut in as_completed(futures):
                        done(fut.result())
    finally:
        if tmp is not None:
            tmp.cleanup()
    order = {(p.stem, s): i for i, (p, s) in enumerate(jobs)}
    rows.sort(key=lambda r: order.get((r["scenario"], r["seed"] if seeds else None), 0))
    total_wall = time.perf_counter() - t0
    n_pass = sum(r["passed"] for r in rows)
    result = {
        "bench": "library_scorecard",
        "git_commit": commit,
        "git_status_short": status.splitlines() if status else [],
        "machine": {"platform": platform.platform(), "cpus": os.cpu_count(),
                    "python": platform.python_version()},
        "seeds": seeds if seeds is not None else "file",
        "overrides": {"bridge": args.bridge, "altitude": args.altitude},
        "jobs": args.jobs,
        "totals": {"runs": len(rows), "passed": n_pass, "failed": len(rows) - n_pass,
                   "criteria": sum(r["criteria"] for r in rows),
                   "criteria_failed": sum(r["criteria_failed"] for r in rows),
                   "wall_s": total_wall},
        "scenarios": rows,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    write_json(result, args.out)
    sys.stdout.write(markdown_table(rows))
    sys.stdout.write(f"\n{n_pass}/{len(rows)} passed in {total_wall:.0f} s -> {args.out}\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
