"""physconst.airdata: the pitot-static relations (used by the pitot model and the filter)."""

from __future__ import annotations

import math

import pytest

from physconst import ISA_P0_PA, ISA_T0_K
from physconst.airdata import (
    air_density_kgpm3,
    calibrated_airspeed_mps,
    impact_pressure_pa,
    speed_of_sound_mps,
    true_airspeed_mps,
)


def test_sea_level_density_and_speed_of_sound_match_the_standard_atmosphere() -> None:
    # ISO 2533 sea-level values: rho0 = 1.2250 kg/m3, a0 = 340.29 m/s
    assert air_density_kgpm3(ISA_P0_PA, ISA_T0_K) == pytest.approx(1.2250, abs=5e-5)
    assert speed_of_sound_mps(ISA_T0_K) == pytest.approx(340.294, abs=5e-3)


@pytest.mark.parametrize("tas", [5.0, 30.0, 55.0, 120.0, 250.0])
@pytest.mark.parametrize(("p", "t"), [(ISA_P0_PA, ISA_T0_K), (70108.5, 268.66)])
def test_true_airspeed_inverts_impact_pressure(tas: float, p: float, t: float) -> None:
    qc = impact_pressure_pa(tas, p, t)
    # a few ulps of float64 through one power and one square root
    assert true_airspeed_mps(qc, p, t) == pytest.approx(tas, rel=1e-12)


def test_impact_pressure_exceeds_dynamic_pressure_by_the_compressibility_term() -> None:
    tas = 50.0
    q = 0.5 * air_density_kgpm3(ISA_P0_PA, ISA_T0_K) * tas * tas
    mach = tas / speed_of_sound_mps(ISA_T0_K)
    # q_c = q (1 + M^2/4 + M^4/40 + ...): the series to second order is good to O(M^6)
    assert impact_pressure_pa(tas, ISA_P0_PA, ISA_T0_K) == pytest.approx(
        q * (1.0 + mach**2 / 4.0 + mach**4 / 40.0), rel=1e-6
    )


def test_no_flow_reads_zero_airspeed() -> None:
    assert true_airspeed_mps(0.0, ISA_P0_PA, ISA_T0_K) == 0.0
    assert true_airspeed_mps(-3.0, ISA_P0_PA, ISA_T0_K) == 0.0
    assert math.isfinite(true_airspeed_mps(1e-9, ISA_P0_PA, ISA_T0_K))


def test_calibrated_airspeed_is_the_true_airspeed_at_isa_sea_level_and_less_aloft() -> None:
    assert calibrated_airspeed_mps(impact_pressure_pa(50.0, ISA_P0_PA, ISA_T0_K)) == \
        pytest.approx(50.0, rel=1e-12)
    # at 3000 m (70.1 kPa, 268.7 K) 60 m/s true reads about 60 * sqrt(rho/rho0) ~ 51.6 m/s
    cas = calibrated_airspeed_mps(impact_pressure_pa(60.0, 70108.5, 268.66))
    assert 51.0 < cas < 52.5
    assert calibrated_airspeed_mps(0.0) == 0.0
