"""GIVEN the canonical flight (tests/golden/canonical.yaml), WHEN it is flown and fused again,
THEN its 1 Hz estimate equals the committed tests/golden/change_indication.csv.

A failure means the navigation's numbers changed. If the change is deliberate, regenerate the
file (``python -m tests.golden.change_indication``) and commit it with the reason; otherwise it
is a regression.

Tolerances: the same code gives bit-identical numbers on one machine, but BLAS kernels differ
in summation order and FMA use. Flown under OPENBLAS_CORETYPE Prescott, Haswell, SkylakeX and
Zen, the largest differences over the 300 s flight were 1.2e-10 m in position, 7e-12 m/s in
velocity, 3e-14 rad in attitude, 2e-14 m in a sigma and 6e-13 m in the baro bias: the filter is
stable, so round-off does not grow. The tolerances below sit about 10^3-10^4 above that (any
kernel's round-off) and far below the smallest deliberate change this file has shown (a
process-noise or gating change moves positions by millimetres or more).
"""

from __future__ import annotations

import math

import pytest

from tests.golden import change_indication as golden

R_EARTH_M = 6.4e6
TOLERANCE = {
    "lat_rad": 1e-6 / R_EARTH_M, "lon_rad": 1e-6 / R_EARTH_M, "alt_msl_m": 1e-6,
    "vn_mps": 1e-8, "ve_mps": 1e-8, "vd_mps": 1e-8,
    "roll_rad": 1e-10, "pitch_rad": 1e-10, "yaw_rad": 1e-10,
    "sigma_pn_m": 1e-10, "sigma_pe_m": 1e-10, "sigma_pd_m": 1e-10,
    "sigma_vn_mps": 1e-11, "sigma_ve_mps": 1e-11, "sigma_vd_mps": 1e-11,
    "sigma_roll_rad": 1e-12, "sigma_pitch_rad": 1e-12, "sigma_yaw_rad": 1e-12,
    "accel_bias_x_mps2": 1e-11, "accel_bias_y_mps2": 1e-11, "accel_bias_z_mps2": 1e-11,
    "gyro_bias_x_rps": 1e-13, "gyro_bias_y_rps": 1e-13, "gyro_bias_z_rps": 1e-13,
    "baro_bias_m": 1e-8,
}


@pytest.mark.slow
def test_canonical_flight_matches_the_golden_file():
    assert set(TOLERANCE) == set(golden.NUMERIC_COLUMNS)
    expected = golden.read()
    actual = golden.rows()
    assert [r[0] for r in actual] == [r[0] for r in expected], "1 Hz epochs changed"
    moved: list[str] = []
    for exp, act in zip(expected, actual, strict=True):
        if exp[1] != act[1]:
            moved.append(f"t={exp[0]:g} s mode {exp[1]} -> {act[1]}")
        for name, e, a in zip(golden.NUMERIC_COLUMNS, exp[2:], act[2:], strict=True):
            if not (abs(e - a) <= TOLERANCE[name] or (math.isnan(e) and math.isnan(a))):
                moved.append(f"t={exp[0]:g} s {name}: {e!r} -> {a!r}")
    assert not moved, (f"{len(moved)} values moved (first: {moved[:5]}); regenerate with "
                       "`python -m tests.golden.change_indication` only if deliberate")
