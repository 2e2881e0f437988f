"""Benchmark: mechanise JSBSim's *own* specific force and inertial rates (no sensor errors).

Shows how far hilnav's strapdown (WGS-84, Somigliana normal gravity) drifts from a JSBSim
trajectory when fed JSBSim's truth directly: the difference is JSBSim's gravity model (WGS-84 +
J2) against normal gravity, ~1e-5 m/s^2.
(``tests/integration/test_mechanisation_flight.py`` checks the mechanisation itself with an
ideal IMU derived from the trajectory through hilnav's Earth model.)

    python bench/mechanisation_jsbsim.py   # writes bench/results/mechanisation_jsbsim.json
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

from fusion import earth, strapdown
from sim.flight import Flight, FlightConfig
from sim.plans import load_plan


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--rate", type=float, default=200.0)
    ap.add_argument("--duration", type=float, default=600.0)
    ap.add_argument("--plan", default="racetrack")
    ap.add_argument("--out", type=Path, default=Path("bench/results/mechanisation_jsbsim.json"))
    args = ap.parse_args()
    dt = 1.0 / args.rate
    rows = []
    with Flight(FlightConfig(rate_hz=args.rate), load_plan(args.plan)) as flight:
        prev = flight.truth()
        s = strapdown.InsState(prev.lat_rad, prev.lon_rad, prev.alt_msl_m,
                               tuple(prev.v_ned_mps), tuple(prev.q_nb))
        pth: tuple[float, ...] = (0.0, 0.0, 0.0)
        pdv: tuple[float, ...] = (0.0, 0.0, 0.0)
        n = round(args.duration * args.rate)
        for k in range(1, n + 1):
            tr = flight.step()
            th = tuple((0.5 * (prev.omega_b_rps + tr.omega_b_rps) * dt).tolist())
            dv = tuple((0.5 * (prev.specific_force_b_mps2 + tr.specific_force_b_mps2) * dt)
                       .tolist())
            s = strapdown.update(s, th, dv, pth, pdv, dt)
            pth, pdv, prev = th, dv, tr
            if k % round(60 * args.rate) == 0:
                r_m, r_n = (float(r) for r in earth.principal_radii(tr.lat_rad))
                rows.append({
                    "time_s": k * dt,
                    "north_m": (s.lat_rad - tr.lat_rad) * (r_m + tr.alt_msl_m),
                    "east_m": (s.lon_rad - tr.lon_rad) * (r_n + tr.alt_msl_m)
                    * math.cos(tr.lat_rad),
                    "up_m": s.alt_msl_m - tr.alt_msl_m,
                })
    result = {"benchmark": "mechanisation_jsbsim", "rate_hz": args.rate, "plan": args.plan,
              "error_vs_time": rows}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=2) + "\n")
    print(json.dumps(rows[-1], indent=2))


if __name__ == "__main__":
    main()
