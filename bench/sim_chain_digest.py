"""Check: the simulator chain's frames are the same bytes as at a base revision.

Flies four flights through :class:`hil.pipeline.SimChain` (JSBSim + guidance + sensor models,
pitot fitted, + MAVLink encode) and hashes every frame (its target time and bytes, in order):
racetrack; manoeuvre; survey in a 5,-3,0 m/s wind with turbulence 0.43; climb-descent in a
power-law shear (8,-4,0 m/s, exponent 1/7). A speed change of the chain must leave all four
digests unchanged. ``--base REV`` also runs this script on a ``git archive`` of REV (first on
``PYTHONPATH``) and compares; the JSON says ``identical`` per flight.

    python bench/sim_chain_digest.py --base REV --out bench/results/sim_chain_digest.json
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

FLIGHTS: dict[str, dict[str, object]] = {
    "racetrack": {"plan": "racetrack"},
    "manoeuvre": {"plan": "manoeuvre"},
    "survey_wind_turbulence": {"plan": "survey", "wind_ned_mps": (5.0, -3.0, 0.0),
                               "turbulence": 0.43},
    "climb_descent_shear": {"plan": "climb-descent", "wind_ned_mps": (8.0, -4.0, 0.0),
                            "wind_shear_exponent": 1.0 / 7.0},
}


def digests(duration_s: float) -> dict[str, dict[str, object]]:
    """SHA-256 of each flight's frames, and their count (this process's code)."""
    from hil.pipeline import SimChain, SimSetup
    from sim import presets
    from sim.flight import FlightConfig
    from sim.plans import load_plan

    out: dict[str, dict[str, object]] = {}
    for name, spec in FLIGHTS.items():
        cfg = FlightConfig(**{k: v for k, v in spec.items() if k != "plan"})
        setup = SimSetup(flight=cfg, plan=load_plan(str(spec["plan"])),
                         sensors=presets.suite_config(), duration_s=duration_s, seed=3)
        h = hashlib.sha256()
        n = 0
        with SimChain(setup) as chain:
            for step in chain.steps(batch=1):
                for t, frame in step.frames:
                    h.update(t.to_bytes(8, "little", signed=True))
                    h.update(frame)
                    n += 1
        out[name] = {"sha256": h.hexdigest(), "frames": n}
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--duration", type=float, default=120.0, help="simulated seconds per flight")
    ap.add_argument("--base", help="git revision to compare with (git archive, on PYTHONPATH)")
    ap.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--out", type=Path, default=ROOT / "bench/results/sim_chain_digest.json")
    args = ap.parse_args()
    if args.child:
        print(json.dumps(digests(args.duration)))
        return
    result: dict[str, object] = {"benchmark": "sim_chain_digest", "duration_s": args.duration,
                                 "this_tree": digests(args.duration)}
    if args.base:
        with tempfile.TemporaryDirectory(prefix="hilnav-digest-") as tmp:
            archive = subprocess.run(["git", "archive", args.base], cwd=ROOT, check=True,
                                     capture_output=True).stdout
            subprocess.run(["tar", "-x", "-C", tmp], input=archive, check=True)
            env = {**os.environ, "PYTHONPATH": tmp}
            proc = subprocess.run([sys.executable, str(Path(__file__).resolve()), "--child",
                                   "--duration", str(args.duration)], env=env, cwd=tmp,
                                  check=True, capture_output=True, text=True)
        base = json.loads(proc.stdout.strip().splitlines()[-1])
        this = result["this_tree"]
        assert isinstance(this, dict)
        result["base"] = args.base
        result["base_tree"] = base
        result["identical"] = {k: base[k] == this[k] for k in FLIGHTS}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=2) + "\n", encoding="utf-8")
    print(json.dumps(result, indent=2))
    if args.base and not all(result["identical"].values()):  # type: ignore[union-attr]
        sys.exit("the frames differ from the base revision")


if __name__ == "__main__":
    main()
