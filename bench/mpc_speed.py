"""Benchmark: cost of one Laguerre-MPC step (P4's compensator) and of the altitude channel.

Target: the MPC step costs ≤ 20 µs per call with precomputed gains. Measured:

- ``first_move_fast``: the receding-horizon move ``Δu = −K_mpc·x̃`` alone (plain floats);
- ``compensator_step``: :meth:`fusion.altitude.mpc.MpcCompensator.step` — move, control update and
  the error-model propagation (what the channel calls every period);
- ``compensator_step_bounded``: the same with move bounds that are active on most calls (the
  active-set QP runs);
- ``channel_per_imu_sample``: a whole :class:`fusion.altitude.channel.AltitudeChannel` per IMU
  sample at 100 Hz with baro at 25 Hz and GNSS at 5 Hz (loop, calibration, monitor,
  compensator), amortised, for each method.

    PYTHONPATH=. .venv/bin/python bench/mpc_speed.py   # writes bench/results/mpc_speed.json
"""

from __future__ import annotations

import argparse
import json
import math
import platform
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from fusion.altitude.channel import AltitudeChannel, AltitudeChannelConfig
from fusion.altitude.mpc import MpcCompensator, MpcConfig


def per_call_us(fn: Callable[[], object], n: int, repeats: int = 5) -> float:
    """Best-of-``repeats`` mean time per call, µs."""
    best = math.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        for _ in range(n):
            fn()
        best = min(best, (time.perf_counter() - t0) / n)
    return best * 1e6


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--n", type=int, default=200_000)
    ap.add_argument("--out", type=Path, default=Path("bench/results/mpc_speed.json"))
    args = ap.parse_args()
    rng = np.random.default_rng(0)
    refs = (rng.normal(size=4096) * 2.0).tolist()

    comp = MpcCompensator(MpcConfig())
    mpc = comp.mpc
    dx = [0.01, -0.02, 0.0]
    t_fast = per_call_us(lambda: mpc.first_move_fast(dx, 0.3), args.n)

    i = 0

    def step_free() -> None:
        nonlocal i
        comp.step(refs[i & 4095])
        i += 1

    t_step = per_call_us(step_free, args.n)

    bounded = MpcCompensator(MpcConfig(delta_u_max_mps2=0.01, u_max_mps2=0.05))
    j = 0

    def step_bounded() -> None:
        nonlocal j
        bounded.step(refs[j & 4095] * 5.0)
        j += 1

    n_b = max(1, args.n // 20)
    t_bounded = per_call_us(step_bounded, n_b)
    active_fraction = bounded.qp_active / (5 * n_b)  # 5 repeats

    t_numpy = per_call_us(lambda: mpc.first_move(dx, 0.5, 0.2), max(1, args.n // 10))

    channel: dict[str, float] = {}
    for method in ("loop", "loop-mpc", "loop-kf"):
        ch = AltitudeChannel(AltitudeChannelConfig(method=method))
        k = 0

        def imu(ch: AltitudeChannel = ch) -> None:
            # 100 Hz IMU, 25 Hz baro, 5 Hz GNSS: per IMU sample, amortised
            nonlocal k
            k += 1
            ch.update_imu(0.001, 0.01)
            if k % 4 == 0:
                ch.update_baro(90000.0 + (k & 3), 280.0, ch.time_s)
            if k % 20 == 0:
                ch.update_gnss_height(988.0 + 0.1 * (k & 7), 2.0, ch.time_s)

        channel[method] = per_call_us(imu, max(1, args.n // 4))

    result = {
        "benchmark": "mpc_speed",
        "python": platform.python_version(),
        "machine": platform.machine(),
        "calls": args.n,
        "mpc": {
            "pole": mpc.pole,
            "n_terms": mpc.n_terms,
            "np_horizon": mpc.np_horizon,
            "nc_horizon": mpc.nc_horizon,
        },
        "us_per_call": {
            "first_move_fast": t_fast,
            "first_move_numpy": t_numpy,
            "compensator_step": t_step,
            "compensator_step_bounded": t_bounded,
            "channel_per_imu_sample": channel,
        },
        "bounded_qp_active_fraction": active_fraction,
        "target_us": 20.0,
        "target_met": t_step <= 20.0,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=2))
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
