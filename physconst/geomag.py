"""The Earth's main magnetic field from the World Magnetic Model (NOAA/BGS WMM), via ``pygeomag``.

One definition for the simulator's magnetometer (``sim``) and the filter's reference field
(``fusion``): the field vector in the local North-East-Down frame at a geodetic position and a
date. The WMM is the model PX4 and ArduPilot derive their declination tables from. Its
uncertainty (WMM2025 technical report, Table 4.1) is about 0.3-0.5 deg in declination away
from the magnetic poles and ~150 nT in the components; crustal anomalies and the vehicle's own
field come on top.

``pygeomag`` carries the coefficients of WMM2010, WMM2015v2, WMM2020 and WMM2025 as Python
data (no file is read, nothing is downloaded). :func:`magnetic_field_ned_t` picks the model
whose five-year life span holds the date; a date outside 2010.0-2030.0 is evaluated with the
nearest model's secular variation extrapolated (the returned ``extrapolated`` flag says so).

Example::

    f = magnetic_field_ned_t(math.radians(47.0), math.radians(8.0), 500.0, 2026.9)
    math.degrees(f.declination_rad)    # ~ +3.5
"""

from __future__ import annotations

import datetime as _dt
import functools
import math
from typing import Final, NamedTuple

from pygeomag import GeoMag
from pygeomag.wmm.wmm_2010 import WMM_2010
from pygeomag.wmm.wmm_2015v2 import WMM_2015v2
from pygeomag.wmm.wmm_2020 import WMM_2020
from pygeomag.wmm.wmm_2025 import WMM_2025

__all__ = [
    "DEFAULT_DECIMAL_YEAR",
    "REEVALUATE_DISTANCE_M",
    "GeomagneticField",
    "decimal_year",
    "magnetic_field_ned_t",
    "moved_beyond",
]

DEFAULT_DECIMAL_YEAR: Final = 2026.0
"""Date of the simulated world when a scenario gives none (inside WMM2025's life span)."""

REEVALUATE_DISTANCE_M: Final = 500.0
"""A user of the field (the simulator's magnetometer, the filter's heading reference)
re-evaluates it after moving this far, horizontally or vertically, m. The main field's
gradient is about 0.1 deg of declination per 10 km at mid latitudes (a few nT per km), so
500 m keeps the field used within ~0.01 deg of the model's at the vehicle for one evaluation
(~0.2 ms of pure Python) per 500 m travelled."""
_EARTH_RADIUS_M: Final = 6_371_000.0  # only to measure how far something moved

_MODELS: Final = (WMM_2010, WMM_2015v2, WMM_2020, WMM_2025)
_NT_TO_T: Final = 1e-9


class GeomagneticField(NamedTuple):
    """Main-field vector in the local geodetic North-East-Down frame."""

    north_t: float
    east_t: float
    down_t: float
    extrapolated: bool
    """True when the date lies outside every bundled model's life span (2010.0-2030.0)."""

    @property
    def ned_t(self) -> tuple[float, float, float]:
        """``(north, east, down)``, tesla."""
        return (self.north_t, self.east_t, self.down_t)

    @property
    def declination_rad(self) -> float:
        """Angle from true north to the horizontal field, positive east, rad."""
        return math.atan2(self.east_t, self.north_t)

    @property
    def inclination_rad(self) -> float:
        """Dip below the horizontal, positive down (northern hemisphere), rad."""
        return math.atan2(self.down_t, math.hypot(self.north_t, self.east_t))

    @property
    def intensity_t(self) -> float:
        """Total field strength, tesla."""
        return math.sqrt(self.north_t**2 + self.east_t**2 + self.down_t**2)


@functools.cache
def _model(index: int) -> GeoMag:
    return GeoMag(coefficients_data=_MODELS[index])


def _model_index(year: float) -> int:
    for i, data in enumerate(_MODELS):
        epoch = float(data[0][0])
        if epoch <= year < epoch + 5.0:
            return i
    return 0 if year < float(_MODELS[0][0][0]) else len(_MODELS) - 1


def magnetic_field_ned_t(
    lat_rad: float, lon_rad: float, alt_m: float, year: float
) -> GeomagneticField:
    """WMM main field at a geodetic position and date.

    Parameters
    ----------
    lat_rad, lon_rad : float
        Geodetic latitude and longitude, rad.
    alt_m : float
        Height above the WGS-84 ellipsoid, m (the WMM's "altitude"; -1 km .. 850 km).
    year : float
        Decimal year, e.g. 2026.5 (see :func:`decimal_year`).

    Raises
    ------
    ValueError
        A non-finite input, or a latitude outside +-90 deg.
    """
    if not all(math.isfinite(v) for v in (lat_rad, lon_rad, alt_m, year)):
        raise ValueError("the geomagnetic model needs finite latitude, longitude, height and date")
    lat_deg = math.degrees(lat_rad)
    if abs(lat_deg) > 90.0:
        raise ValueError(f"latitude {lat_deg:.3f} deg is outside +-90 deg")
    lon_deg = (math.degrees(lon_rad) + 180.0) % 360.0 - 180.0
    index = _model_index(year)
    model = _model(index)
    lo, hi = model.life_span
    r = model.calculate(
        glat=lat_deg, glon=lon_deg, alt=alt_m / 1000.0, time=year, allow_date_outside_lifespan=True
    )
    return GeomagneticField(
        north_t=float(r.x) * _NT_TO_T,
        east_t=float(r.y) * _NT_TO_T,
        down_t=float(r.z) * _NT_TO_T,
        extrapolated=not (lo <= year < hi),
    )


def moved_beyond(
    a: tuple[float, float, float], b: tuple[float, float, float], distance_m: float
) -> bool:
    """True when the geodetic positions ``a`` and ``b`` (lat rad, lon rad, height m) are more
    than ``distance_m`` apart horizontally (spherical approximation) or vertically; a NaN
    position is always "moved"."""
    lat0, lon0, h0 = a
    lat1, lon1, h1 = b
    dn = (lat1 - lat0) * _EARTH_RADIUS_M
    de = (lon1 - lon0) * _EARTH_RADIUS_M * math.cos(lat1)
    return not (dn * dn + de * de <= distance_m * distance_m and abs(h1 - h0) <= distance_m)


def decimal_year(when: _dt.datetime | _dt.date) -> float:
    """Decimal year of a date or (UTC) date-time: 2026-07-02 12:00 -> 2026.5."""
    if not isinstance(when, _dt.datetime):
        when = _dt.datetime(when.year, when.month, when.day)
    start = _dt.datetime(when.year, 1, 1, tzinfo=when.tzinfo)
    end = _dt.datetime(when.year + 1, 1, 1, tzinfo=when.tzinfo)
    return when.year + (when - start) / (end - start)
