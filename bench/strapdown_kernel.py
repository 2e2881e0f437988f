"""Benchmark: the compiled INS kernel (``fusion._strapdown``) against the Python reference.

    python bench/strapdown_kernel.py        # writes bench/results/strapdown_kernel.json

Times :func:`fusion.strapdown.update` and the three increment helpers as the filter calls them
(exact floats in tuples), compiled and Python, alternating the two ``--rounds`` times in this
one process and keeping the best of each (CPU time per call over ``--calls`` calls; the load
average is recorded). The inputs are the states and IMU samples of a short turning flight of
the test suite's synthetic trajectory (``tests/helpers/nav_synth.py``), fed in order, so both
series branches' frequencies are the filter's. The outputs of the two implementations on those
inputs are compared bit for bit (``bit_identical``).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import struct
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent


def _inputs(n: int) -> dict[str, list[tuple[Any, ...]]]:
    """Argument tuples of each function over ``n`` IMU samples of a turning flight."""
    import numpy as np

    from fusion import strapdown
    from tests.helpers.nav_synth import Flight, prepare

    prep = prepare(Flight(duration_s=n / 100.0 + 1.0, turns=[(1.0, n / 100.0, 0.2)]), 100.0)
    dt = 0.01
    kin0 = prep.traj(prep.edges_us[:1] * 1e-6)
    state = strapdown.InsState.from_arrays(*kin0.lla[0], kin0.v_ned_mps[0], kin0.q_nb[0])
    rng = np.random.default_rng(1)
    zero = (0.0, 0.0, 0.0)
    prev_th, prev_dv = zero, zero
    calls: dict[str, list[tuple[Any, ...]]] = {
        "update": [],
        "increments": [],
        "increments_scaled": [],
        "increments_compensated": [],
    }
    bias_a = tuple((rng.normal(size=3) * 0.01).tolist())
    bias_g = tuple((rng.normal(size=3) * 1e-5).tolist())
    scale = tuple((rng.normal(size=3) * 1e-4).tolist())
    inverse = strapdown.sensor_inverse(scale, (rng.normal(size=6) * 1e-4).tolist())
    for w, f in zip((prep.w_b[:n] * dt).tolist(), (prep.f_b[:n] * dt).tolist(), strict=True):
        th, dv = tuple(w), tuple(f)
        calls["update"].append((state, th, dv, prev_th, prev_dv, dt))
        state = strapdown.update_python(state, th, dv, prev_th, prev_dv, dt)
        prev_th, prev_dv = th, dv
        fw = tuple(x / dt for x in dv) + tuple(x / dt for x in th)
        calls["increments"].append((fw, dt, bias_a, bias_g))
        calls["increments_scaled"].append((fw, dt, bias_a, bias_g, scale, scale))
        calls["increments_compensated"].append((fw, dt, bias_a, bias_g, inverse, inverse))
    return calls


def _cpu_us_per_call(fn: Callable[..., Any], args: list[tuple[Any, ...]]) -> float:
    c0 = time.process_time()
    for a in args:
        fn(*a)
    return 1e6 * (time.process_time() - c0) / len(args)


def _bits(x: Any) -> list[Any]:
    if isinstance(x, tuple):
        return [type(x), *(b for v in x for b in _bits(v))]
    return ["nan" if math.isnan(x) else struct.pack("<d", x)]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--calls", type=int, default=20_000, help="calls per timing (IMU samples)")
    ap.add_argument("--rounds", type=int, default=5, help="alternations of the two")
    ap.add_argument("--out", type=Path,
                    default=ROOT / "bench" / "results" / "strapdown_kernel.json")
    args = ap.parse_args(argv)
    sys.path.insert(0, str(ROOT))
    from fusion import strapdown
    from physconst.kernel import KERNEL_ENV

    if strapdown.KERNEL != "c":
        print("the compiled kernel is not in use (no C compiler at install time, or "
              f"{KERNEL_ENV}=python): nothing to compare", file=sys.stderr)
        return 1
    load0 = os.getloadavg()
    calls = _inputs(args.calls)
    result: dict[str, Any] = {}
    for name, args_list in calls.items():
        compiled = getattr(strapdown, name)
        reference = getattr(strapdown, name + "_python")
        identical = all(_bits(compiled(*a)) == _bits(reference(*a)) for a in args_list)
        best = {"c": math.inf, "python": math.inf}
        for r in range(args.rounds):
            for impl in (("c", "python") if r % 2 == 0 else ("python", "c")):
                fn = compiled if impl == "c" else reference
                best[impl] = min(best[impl], _cpu_us_per_call(fn, args_list))
        result[name] = {
            "c_us_per_call": round(best["c"], 3),
            "python_us_per_call": round(best["python"], 3),
            "speedup": round(best["python"] / best["c"], 1),
            "bit_identical": identical,
        }
        print(f"{name:24s} C {best['c']:6.2f} us  Python {best['python']:6.2f} us  "
              f"x{best['python'] / best['c']:5.1f}  identical={identical}", flush=True)
    out = {
        "method": ("CPU us per call, best of --rounds alternations of compiled and Python on "
                   "the same argument list (a turning flight's IMU samples, in order)"),
        "calls": args.calls,
        "rounds": args.rounds,
        "functions": result,
        "load_average_start": load0,
        "load_average_end": os.getloadavg(),
        "machine": platform.processor() or platform.machine(),
        "python": platform.python_version(),
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(out, indent=2) + "\n")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
