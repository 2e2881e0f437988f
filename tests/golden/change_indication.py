"""Golden change indication: the canonical flight's estimate at 1 Hz, as a CSV under git.

In the manner of PX4 ECL's ``test/change_indication``: any change to the numbers the
navigation produces shows up as a diff of ``change_indication.csv``, so a numeric change is
always deliberate and reviewed. ``tests/integration/test_change_indication.py`` recomputes
the flight and fails when a value moved beyond round-off (see its tolerances). After a
deliberate change, regenerate the file with the documented command and commit it with the reason:

    python -m tests.golden.change_indication          # rewrites tests/golden/change_indication.csv

The flight is ``canonical.yaml`` (next to this file) through the same lockstep pipeline as
``hilnav run``: JSBSim, the sensor models and faults, MAVLink 2 encode/decode, the filter
with the scenario's bridging and altitude methods.
"""

from __future__ import annotations

import csv
import math
import sys
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
SCENARIO = HERE / "canonical.yaml"
CSV_PATH = HERE / "change_indication.csv"

#: Columns after ``time_s`` and ``mode``: SI values of the estimate (NED, rad).
NUMERIC_COLUMNS = (
    "lat_rad", "lon_rad", "alt_msl_m", "vn_mps", "ve_mps", "vd_mps",
    "roll_rad", "pitch_rad", "yaw_rad",
    "sigma_pn_m", "sigma_pe_m", "sigma_pd_m", "sigma_vn_mps", "sigma_ve_mps", "sigma_vd_mps",
    "sigma_roll_rad", "sigma_pitch_rad", "sigma_yaw_rad",
    "accel_bias_x_mps2", "accel_bias_y_mps2", "accel_bias_z_mps2",
    "gyro_bias_x_rps", "gyro_bias_y_rps", "gyro_bias_z_rps", "baro_bias_m",
)
COLUMNS = ("time_s", "mode", *NUMERIC_COLUMNS)


def _estimates() -> list[Any]:
    """Fly and fuse the canonical scenario; every estimate of the filter."""
    from hil.pipeline import fuse_frames
    from scenarios.runner import filter_config, simulate
    from scenarios.schema import load_scenario

    scenario = load_scenario(SCENARIO)
    frames: list[tuple[int, bytes]] = []
    simulate(scenario, lambda t, f: frames.append((t, f)))
    fused = fuse_frames(frames, filter_config(scenario), scenario.fusion.bridge,
                        keep_objects=True)
    assert fused.collector is not None
    return fused.collector.estimates


def rows() -> list[list[Any]]:
    """The first estimate of every whole second after alignment, as CSV rows."""
    out: list[list[Any]] = []
    next_s = None
    for e in _estimates():
        if str(e.mode) == "initializing":
            continue
        t_s = e.time_us * 1e-6
        if next_s is None:
            next_s = math.ceil(t_s)
        if t_s < next_s:
            continue
        next_s = math.floor(t_s) + 1
        sig = [math.sqrt(max(float(v), 0.0)) for v in e.P_diag[:9]]
        out.append([
            round(t_s, 6), str(e.mode), e.lat_rad, e.lon_rad, e.alt_msl_m,
            *map(float, e.v_ned_mps), *map(float, e.euler_rad), *sig,
            *map(float, e.accel_bias_b_mps2), *map(float, e.gyro_bias_b_rps),
            float(e.baro_bias_m),
        ])
    return out


def write(path: Path = CSV_PATH) -> int:
    data = rows()
    with path.open("w", newline="") as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(COLUMNS)
        for r in data:
            w.writerow([r[0], r[1], *(repr(float(v)) for v in r[2:])])
    return len(data)


def read(path: Path = CSV_PATH) -> list[list[Any]]:
    with path.open(newline="") as fh:
        reader = csv.reader(fh)
        header = next(reader)
        if tuple(header) != COLUMNS:
            raise ValueError(f"{path}: unexpected columns {header}")
        return [[float(r[0]), r[1], *(float(v) for v in r[2:])] for r in reader]


if __name__ == "__main__":
    n = write()
    sys.stdout.write(f"{n} rows -> {CSV_PATH}\n")
