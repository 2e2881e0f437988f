"""The standard atmosphere (physconst.isa) against the ICAO table, its inverse, and its users."""

from __future__ import annotations

import math

import numpy as np
import pytest

from fusion.altitude import atmosphere as fusion_atm
from physconst import ISA_P0_PA, ISA_T0_K, isa
from sim import atmosphere as sim_atm


def test_sea_level_is_zero_pressure_altitude() -> None:
    assert isa.pressure_altitude_m(101325.0) == 0.0
    assert isa.isa_pressure_pa(0.0) == ISA_P0_PA
    assert isa.isa_temperature_k(0.0) == ISA_T0_K


@pytest.mark.parametrize(
    ("alt_gp_m", "p_table_pa", "t_table_k"),
    [
        # ICAO Doc 7488 / US Standard Atmosphere 1976, geopotential altitude
        (-2000.0, 127774.0, 301.15),
        (1000.0, 89874.6, 281.65),
        (5000.0, 54019.9, 255.65),
        (11000.0, 22632.06, 216.65),  # tropopause
        (20000.0, 5474.89, 216.65),
        (32000.0, 868.02, 228.65),
    ],
)
def test_table(alt_gp_m: float, p_table_pa: float, t_table_k: float) -> None:
    assert isa.isa_pressure_pa(alt_gp_m) == pytest.approx(p_table_pa, abs=0.5)
    assert isa.isa_temperature_k(alt_gp_m) == pytest.approx(t_table_k, abs=1e-9)
    assert isa.pressure_altitude_m(p_table_pa) == pytest.approx(alt_gp_m, abs=0.2)


def test_tropopause_is_continuous() -> None:
    below, above = isa.isa_pressure_pa(11000.0 - 1e-6), isa.isa_pressure_pa(11000.0)
    assert above == pytest.approx(22632.06, abs=0.05)  # the ICAO table's 11 km pressure
    assert above == pytest.approx(below, rel=1e-9)
    assert isa.pressure_altitude_m(above) == pytest.approx(11000.0, abs=1e-9)


def test_round_trip_over_the_model_range() -> None:
    for h in np.linspace(-5000.0, 47000.0, 521):
        assert isa.pressure_altitude_m(isa.isa_pressure_pa(float(h))) == pytest.approx(h, abs=1e-7)
    for p in np.geomspace(isa.ISA_P_MIN_PA, isa.ISA_P_MAX_PA, 301):
        assert isa.isa_pressure_pa(isa.pressure_altitude_m(float(p))) == pytest.approx(p, rel=1e-12)


def test_model_range() -> None:
    assert isa.ISA_P_MAX_PA == pytest.approx(177687.0, rel=1e-5)  # -5 km
    assert isa.ISA_P_MIN_PA == pytest.approx(110.906, rel=1e-5)  # 47 km


@pytest.mark.parametrize("bad", [0.0, -1.0, math.nan])
def test_no_altitude_without_a_positive_pressure(bad: float) -> None:
    assert math.isnan(isa.pressure_altitude_m(bad))


def test_exponent_is_the_textbook_constant() -> None:
    # R* L / (g0 M) with R = R*/M of dry air: the 0.190263 of the six-figure formulas
    assert round(isa.ISA_TROPOSPHERE_EXPONENT, 6) == 0.190263
    p = 80000.0
    textbook = ISA_T0_K / 0.0065 * (1.0 - (p / ISA_P0_PA) ** isa.ISA_TROPOSPHERE_EXPONENT)
    assert isa.pressure_altitude_m(p) == pytest.approx(textbook, abs=1e-9)


def test_simulator_and_filter_use_the_same_atmosphere() -> None:
    heights = np.linspace(-4999.0, 46999.0, 97)
    pressures = np.geomspace(isa.ISA_P_MIN_PA, isa.ISA_P_MAX_PA, 97)
    for h, p in zip(heights.tolist(), pressures.tolist(), strict=True):
        assert sim_atm.isa_pressure_pa(h) == isa.isa_pressure_pa(h)
        assert sim_atm.isa_temperature_k(h) == isa.isa_temperature_k(h)
        assert sim_atm.pressure_altitude_m(p) == isa.pressure_altitude_m(p)
        assert fusion_atm.isa_pressure_pa(h) == isa.isa_pressure_pa(h)
        assert fusion_atm.pressure_altitude_m(p) == isa.pressure_altitude_m(p)
    # the simulator's array form is the scalar function element by element
    np.testing.assert_array_equal(
        sim_atm.pressure_altitude_m(pressures), [isa.pressure_altitude_m(p) for p in pressures]
    )
    # the simulated barometer in a standard atmosphere reads the ISA pressure
    baro = sim_atm.TroposphereBaro(0.0)
    for h in (-300.0, 0.0, 1234.5, 10999.0, 15000.0):
        p, t = baro.pressure_temperature(h, 0.0)
        assert (p, t) == (isa.isa_pressure_pa(h), isa.isa_temperature_k(h))


def test_geopotential_round_trip() -> None:
    h = np.array([-1000.0, 0.0, 1000.0, 10000.0])
    np.testing.assert_allclose(
        isa.geometric_from_geopotential(isa.geopotential_from_geometric(h)), h, atol=1e-9
    )
    assert 1000.0 - isa.geopotential_from_geometric(1000.0) == pytest.approx(0.157, abs=1e-3)
