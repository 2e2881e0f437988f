"""Standard / non-standard atmosphere (sim.atmosphere) against tables and P4's relations."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import physconst as pc
from sim import atmosphere as atm


@pytest.mark.parametrize(
    ("h_geometric_m", "p_table_pa"),
    [
        # US Standard Atmosphere 1976 / ISA tables by geometric altitude.
        (0.0, 101325.0),
        (1000.0, 89876.0),
        (5000.0, 54048.0),
        (11000.0, 22700.0),
    ],
)
def test_isa_pressure_matches_tables_by_geometric_altitude(
    h_geometric_m: float, p_table_pa: float
) -> None:
    p = atm.isa_pressure_pa(atm.geopotential_from_geometric(h_geometric_m))
    assert p == pytest.approx(p_table_pa, abs=1.0)


@pytest.mark.parametrize(
    ("h_geopotential_m", "p_table_pa", "t_table_k"),
    [
        (0.0, 101325.0, 288.15),
        (11000.0, 22632.06, 216.65),  # tropopause (tables list 22632 Pa at 11 km geopotential)
        (20000.0, 5474.89, 216.65),
        (32000.0, 868.02, 228.65),
    ],
)
def test_isa_layer_bases_by_geopotential_altitude(
    h_geopotential_m: float, p_table_pa: float, t_table_k: float
) -> None:
    assert atm.isa_pressure_pa(h_geopotential_m) == pytest.approx(p_table_pa, abs=0.1)
    assert atm.isa_temperature_k(h_geopotential_m) == pytest.approx(t_table_k, abs=1e-9)


def test_sea_level_density_and_types() -> None:
    assert atm.density_from_altitude(0.0) == pytest.approx(1.2250, abs=1e-4)
    assert isinstance(atm.isa_pressure_pa(100.0), float)
    arr = atm.isa_pressure_pa(np.array([[0.0, 1000.0], [2000.0, 3000.0]]))
    assert isinstance(arr, np.ndarray) and arr.shape == (2, 2)


def test_pressure_altitude_is_p4_formula_in_troposphere() -> None:
    p = np.linspace(30000.0, 105000.0, 50)
    hp = atm.pressure_altitude_m(p)
    # P4: Hp = (T0/L)·((Ps/P0)^(−L·R/g) − 1) + H0
    p4 = (pc.ISA_T0_K / pc.ISA_L0_KPM) * (
        (p / pc.ISA_P0_PA) ** (-pc.ISA_L0_KPM * pc.ISA_R_AIR_JPKGK / pc.G0_MPS2) - 1.0
    ) + pc.ISA_H0_M
    np.testing.assert_allclose(hp, p4, rtol=0, atol=1e-9)


def test_isa_inverse_round_trips_over_all_layers() -> None:
    h = np.linspace(pc.ISA_H_MIN_M, pc.ISA_H_MAX_M, 5001)
    np.testing.assert_allclose(atm.pressure_altitude_m(atm.isa_pressure_pa(h)), h, atol=1e-6)


@settings(max_examples=200, deadline=None)
@given(
    h=st.floats(-400.0, 15000.0),
    d_t=st.floats(-40.0, 40.0),
    d_p=st.floats(-5000.0, 5000.0),
)
def test_nonstandard_round_trip(h: float, d_t: float, d_p: float) -> None:
    p = atm.pressure_from_altitude(h, d_t, d_p)
    assert atm.altitude_from_pressure(p, d_t, d_p) == pytest.approx(h, abs=1e-6)
    hp = atm.pressure_altitude_m(p)
    # P4: H = Hp + s·(Hp − H0) + b
    s, b = d_t / pc.ISA_T0_K, (pc.ISA_R_AIR_JPKGK * pc.ISA_T0_K / pc.G0_MPS2) * (d_p / pc.ISA_P0_PA)
    assert hp + s * (hp - pc.ISA_H0_M) + b == pytest.approx(h, abs=1e-6)


def test_pure_temperature_offset_equals_warm_atmosphere_with_same_lapse_rate() -> None:
    # P4's scale s = dT/T0 is exact for a troposphere with sea-level temperature T0 + dT.
    d_t = 15.0
    h = np.linspace(0.0, 10000.0, 21)
    exact = pc.ISA_P0_PA * (1.0 + pc.ISA_L0_KPM * h / (pc.ISA_T0_K + d_t)) ** (
        -pc.G0_MPS2 / (pc.ISA_L0_KPM * pc.ISA_R_AIR_JPKGK)
    )
    np.testing.assert_allclose(atm.pressure_from_altitude(h, d_t, 0.0), exact, rtol=1e-12)
    # Warmer air: higher pressure aloft than ISA, so pressure altitude under-reads.
    assert np.all(atm.pressure_from_altitude(h[1:], d_t) > atm.isa_pressure_pa(h[1:]))
    assert atm.temperature_from_altitude(0.0, d_t, 0.0) == pytest.approx(pc.ISA_T0_K + d_t)


def test_pressure_offset_shifts_sea_level_pressure() -> None:
    d_p = 1500.0  # +15 hPa, a strong high
    p0 = atm.pressure_from_altitude(0.0, 0.0, d_p)
    # P4's bias b is linear in dP; the sea-level pressure is P0 + dP to first order.
    assert p0 - pc.ISA_P0_PA == pytest.approx(d_p, rel=0.01)
    s, b = atm.nonstandard_scale_bias(0.0, d_p)
    assert s == 0.0
    assert b == pytest.approx(8434.5 * d_p / pc.ISA_P0_PA, rel=1e-3)
    # The altimeter set to standard reads low by b in a high.
    assert atm.pressure_altitude_m(atm.pressure_from_altitude(1000.0, 0.0, d_p)) == (
        pytest.approx(1000.0 - b, abs=1e-6)
    )


def test_nonstandard_atmosphere_is_hydrostatic() -> None:
    d_t, d_p, h, dh = -12.0, -800.0, 2500.0, 0.5
    dp_dh = (
        atm.pressure_from_altitude(h + dh, d_t, d_p) - atm.pressure_from_altitude(h - dh, d_t, d_p)
    ) / (2.0 * dh)
    rho = atm.density_from_altitude(h, d_t, d_p)
    assert dp_dh == pytest.approx(-rho * pc.G0_MPS2, rel=1e-6)


def test_geopotential_conversion_round_trip() -> None:
    h = np.array([-500.0, 0.0, 1000.0, 20000.0])
    np.testing.assert_allclose(
        atm.geometric_from_geopotential(atm.geopotential_from_geometric(h)), h
    )
    assert 1000.0 - atm.geopotential_from_geometric(1000.0) == pytest.approx(0.157, abs=1e-3)


def test_scalar_fast_path_matches_array_functions() -> None:
    fast = atm.TroposphereBaro(7.0)
    for h, d_p in [(0.0, 0.0), (1234.0, 300.0), (-300.0, -900.0), (15000.0, 100.0)]:
        p, t = fast.pressure_temperature(h, d_p)
        assert p == pytest.approx(atm.pressure_from_altitude(h, 7.0, d_p), rel=1e-13)
        assert t == pytest.approx(atm.temperature_from_altitude(h, 7.0, d_p), rel=1e-13)


@pytest.mark.parametrize("bad", [0.0, -1.0, math.nan, 50.0, 2.0e5])
def test_bad_pressure_raises(bad: float) -> None:
    with pytest.raises(ValueError, match="pressure"):
        atm.pressure_altitude_m(bad)


@pytest.mark.parametrize("bad", [-6000.0, 60000.0, math.inf])
def test_altitude_out_of_range_raises(bad: float) -> None:
    with pytest.raises(ValueError, match="altitude"):
        atm.isa_pressure_pa(bad)


def test_bad_offsets_raise() -> None:
    with pytest.raises(ValueError, match="temperature offset"):
        atm.pressure_from_altitude(0.0, -300.0, 0.0)
    with pytest.raises(ValueError, match="finite"):
        atm.pressure_from_altitude(0.0, 0.0, math.nan)
