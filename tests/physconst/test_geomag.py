"""The World Magnetic Model wrapper: model choice by date, units, frame, bad input."""

from __future__ import annotations

import datetime as dt
import math

import pytest
from pygeomag import GeoMag
from pygeomag.wmm.wmm_2025 import WMM_2025

from physconst.geomag import decimal_year, magnetic_field_ned_t

_ZURICH = (math.radians(47.0), math.radians(8.0), 500.0)


def test_field_is_pygeomag_wmm2025_in_tesla_ned() -> None:
    ref = GeoMag(coefficients_data=WMM_2025).calculate(glat=47.0, glon=8.0, alt=0.5, time=2026.9)
    f = magnetic_field_ned_t(*_ZURICH, 2026.9)
    assert f.ned_t == (ref.x * 1e-9, ref.y * 1e-9, ref.z * 1e-9)
    assert math.degrees(f.declination_rad) == pytest.approx(ref.d, abs=1e-9)
    assert math.degrees(f.inclination_rad) == pytest.approx(ref.i, abs=1e-9)
    assert f.intensity_t == pytest.approx(ref.f * 1e-9, rel=1e-12)
    assert not f.extrapolated


def test_declination_has_the_sign_of_the_real_world() -> None:
    # NOAA's calculator: about +3.5 deg east at 47N 8E in 2026, +12.5 deg at Sydney; the
    # simulator's former dipole gave -13.7 deg at 47N 8E
    assert 3.0 < math.degrees(magnetic_field_ned_t(*_ZURICH, 2026.0).declination_rad) < 4.0
    sydney = magnetic_field_ned_t(math.radians(-33.9), math.radians(151.2), 0.0, 2026.0)
    assert 12.0 < math.degrees(sydney.declination_rad) < 13.5
    assert sydney.down_t < 0.0  # southern hemisphere: the field points up


def test_the_date_picks_the_model_of_its_epoch() -> None:
    old = magnetic_field_ned_t(*_ZURICH, 2016.5)
    new = magnetic_field_ned_t(*_ZURICH, 2026.5)
    # secular variation: ~0.15 deg/yr of declination change in central Europe
    assert 0.8 < math.degrees(new.declination_rad - old.declination_rad) < 2.5
    assert not old.extrapolated
    assert magnetic_field_ned_t(*_ZURICH, 2005.0).extrapolated
    assert magnetic_field_ned_t(*_ZURICH, 2031.0).extrapolated


def test_longitude_wraps() -> None:
    a = magnetic_field_ned_t(math.radians(47.0), math.radians(8.0 + 360.0), 500.0, 2026.0)
    b = magnetic_field_ned_t(*_ZURICH, 2026.0)
    assert a.ned_t == pytest.approx(b.ned_t, rel=1e-9)


@pytest.mark.parametrize(
    "args",
    [
        (math.nan, 0.0, 0.0, 2026.0),
        (0.0, 0.0, math.inf, 2026.0),
        (math.radians(91.0), 0.0, 0.0, 2026.0),
    ],
)
def test_bad_input_raises_value_error(args: tuple[float, float, float, float]) -> None:
    with pytest.raises(ValueError):
        magnetic_field_ned_t(*args)


def test_decimal_year() -> None:
    assert decimal_year(dt.date(2026, 1, 1)) == 2026.0
    assert decimal_year(dt.datetime(2026, 7, 2, 12)) == pytest.approx(2026.5)
    assert decimal_year(dt.datetime(2024, 7, 2, 0, tzinfo=dt.UTC)) == pytest.approx(2024.5)
