"""What a JSBSim flight is configured with (:class:`FlightConfig`): the aircraft, the rate,
the start state, the wind and turbulence, the guidance gains and who flies the aircraft.

Wind: the velocity the air moves towards, NED. ``FlightConfig.wind_ned_mps`` alone is a
steady wind, written to ``atmosphere/wind-{north,east,down}-fps`` once. A profile with
altitude is written there at every step from the altitude just reached (one step of lag:
< 3 cm of height at 2.5 m/s and 100 Hz): either a power-law shear of the horizontal wind,
``w(h) = w_ref (h_agl / h_ref)^p`` (``wind_shear_exponent`` p; p = 1/7 is the classical
neutral-stability boundary-layer value, see Peterson & Hennessey, "On the use of power laws
for estimates of wind power potential", J. Appl. Meteorol. 17 (1978) 390-394), or a table of
``(alt_msl_m, north, east)`` interpolated linearly (``wind_table``; e.g. MIL-F-8785C's
logarithmic low-altitude profile ``W20 ln(h / z0) / ln(20 ft / z0)``, §3.7.3, or a measured
sounding). Writing three properties costs ~1 us a step against ~60 us for JSBSim
(bench/sim_throughput.py). The true wind at the aircraft, turbulence included, is
``atmosphere/total-wind-*-fps`` and goes into ``Truth.wind_ned_mps``. The aircraft starts in
the wind without sideslip (see ``sim.flight.Flight._start``); the very first truth, read
before JSBSim has stepped, still reports the windless trim's air data and a zero wind.
"""

from __future__ import annotations

import itertools
import math
from typing import Literal, Self

from pydantic import BaseModel, ConfigDict, Field, model_validator

from sim.guidance import GuidanceGains


class StartState(BaseModel):
    """Where and how the aircraft starts, on ``heading_deg`` (true).

    ``kind="air"``: in the air at ``alt_msl_m``, wings level, trimmed at ``airspeed_mps``
    (JSBSim's terrain is then at sea level, so the start is ``alt_msl_m`` above ground; at
    least 100 m). ``kind="ground"``: at rest on a level runway whose elevation is
    ``alt_msl_m`` (the terrain under the whole flight is at that height), gear on the ground,
    brakes off, every engine idling; ``airspeed_mps`` is not used. An autopilot must fly a
    ground start (see :class:`FlightConfig`).
    """

    model_config = ConfigDict(frozen=True, extra="forbid")

    kind: Literal["air", "ground"] = "air"
    lat_deg: float = Field(default=47.0, ge=-85.0, le=85.0)
    lon_deg: float = Field(default=8.0, ge=-180.0, le=180.0)
    alt_msl_m: float = Field(default=1000.0, ge=-400.0, le=15000.0)
    heading_deg: float = Field(default=0.0, ge=-360.0, le=360.0)
    airspeed_mps: float = Field(default=50.0, gt=10.0, le=350.0)

    @model_validator(mode="after")
    def _air_start_above_terrain(self) -> Self:
        if self.kind == "air" and self.alt_msl_m < 100.0:
            raise ValueError(
                f"an in-air start needs alt_msl_m >= 100 m (got {self.alt_msl_m:g}): the "
                "terrain of an in-air start is at sea level; start on the ground with "
                "kind: ground"
            )
        return self

    @property
    def on_ground(self) -> bool:
        """True for a start at rest on the runway."""
        return self.kind == "ground"

    @property
    def terrain_alt_msl_m(self) -> float:
        """Height of the terrain under the flight: the runway's, or sea level in the air."""
        return self.alt_msl_m if self.kind == "ground" else 0.0


class FlightConfig(BaseModel):
    """Aircraft, rate, start state and atmosphere of a flight.

    Wind (the velocity the air moves *towards*, NED, m/s; see the module docstring):
    ``wind_ned_mps`` is the steady wind, at ``wind_ref_agl_m`` above ground when
    ``wind_shear_exponent`` p > 0 (power-law shear of the horizontal wind,
    ``w(h) = w_ref (h / h_ref)^p``; ``wind_ref_agl_m`` None = the start altitude above
    ground). ``wind_table`` instead gives the horizontal wind as rows
    ``(alt_msl_m, north_mps, east_mps)``, strictly increasing in altitude, interpolated
    linearly and held constant beyond its ends; with a table the horizontal part of
    ``wind_ned_mps`` and the exponent must be zero (its down component still applies).
    ``turbulence`` is a severity in [0, 1] (see "Turbulence" in :mod:`sim.flight` for the
    mapping to JSBSim's MIL-F-8785C model); ``seed`` seeds JSBSim's random generator.
    ``stall_alpha_deg``: an angle of attack above it for 0.5 s ends the flight as a stall
    (c172x and c310 reach their maximum lift near 14-16 deg; the guidance law itself stays
    below ``guidance.alpha_max_rad``, 12 deg by default).
    ``guidance``: gains of the guidance law (defaults tuned on c172x and c310).
    ``control``: who flies the aircraft after the trim: ``"guidance"`` (our guidance law flies
    the plan) or ``"external"`` (an autopilot in the loop: the controls given to
    :meth:`Flight.command` hold until the next command; the plan is not flown). The guidance
    law flies from an in-air trim only: a ground start (``start.kind="ground"``) needs
    ``"external"`` (checked when the flight starts, :class:`sim.flight.Flight`). With wind
    shear, a ground start needs ``wind_ref_agl_m`` (its start is 0 m above ground).
    """

    model_config = ConfigDict(frozen=True, extra="forbid")

    aircraft: str = "c172x"
    rate_hz: float = Field(default=200.0, ge=50.0, le=400.0)
    start: StartState = StartState()
    wind_ned_mps: tuple[float, float, float] = (0.0, 0.0, 0.0)
    wind_shear_exponent: float = Field(default=0.0, ge=0.0, le=1.0)
    wind_ref_agl_m: float | None = Field(default=None, gt=0.0, le=20000.0)
    wind_table: tuple[tuple[float, float, float], ...] = ()
    turbulence: float = Field(default=0.0, ge=0.0, le=1.0)
    seed: int = Field(default=0, ge=0, le=2**31 - 1)
    stall_alpha_deg: float = Field(default=15.0, gt=5.0, le=60.0)
    guidance: GuidanceGains = GuidanceGains()
    control: Literal["guidance", "external"] = "guidance"

    @model_validator(mode="after")
    def _one_wind_profile(self) -> Self:
        if (self.start.on_ground and self.wind_shear_exponent > 0.0
                and self.wind_ref_agl_m is None):
            raise ValueError(
                "wind shear from a ground start needs wind_ref_agl_m, the height above ground "
                "where wind_ned_mps holds (e.g. 10 m)"
            )
        table = self.wind_table
        if table:
            if any(not all(math.isfinite(x) for x in row) for row in table):
                raise ValueError("every value of the wind table must be finite")
            alts = [row[0] for row in table]
            if any(b <= a for a, b in itertools.pairwise(alts)):
                raise ValueError("the altitudes of the wind table must increase strictly")
            if self.wind_ned_mps[:2] != (0.0, 0.0) or self.wind_shear_exponent != 0.0:
                raise ValueError(
                    "a wind table replaces the horizontal wind: leave wind_ned_mps' north/east "
                    "at 0 and wind_shear_exponent at 0"
                )
        return self

    @property
    def wind_varies_with_altitude(self) -> bool:
        """True when the wind is a profile (shear or table): set anew at every step."""
        return bool(self.wind_table) or (
            self.wind_shear_exponent > 0.0 and self.wind_ned_mps[:2] != (0.0, 0.0)
        )

    def wind_at(self, alt_msl_m: float, alt_agl_m: float) -> tuple[float, float, float]:
        """The steady (non-turbulent) wind at this height, NED m/s (see the class docstring).

        ``alt_agl_m`` is floored at 1 m for the power law (an in-air flight ends below it).
        """
        wn, we, wd = self.wind_ned_mps
        if self.wind_table:
            n, e = _interpolate_table(self.wind_table, alt_msl_m)
            return (n, e, wd)
        p = self.wind_shear_exponent
        if p == 0.0:
            return (wn, we, wd)
        h_ref = self.wind_ref_agl_m if self.wind_ref_agl_m is not None else self.start.alt_msl_m
        scale = (max(alt_agl_m, 1.0) / h_ref) ** p
        return (wn * scale, we * scale, wd)


def _interpolate_table(
    table: tuple[tuple[float, float, float], ...], alt_m: float
) -> tuple[float, float]:
    """Linear interpolation of ``(alt, north, east)`` rows at ``alt_m``, constant outside."""
    if alt_m <= table[0][0]:
        return (table[0][1], table[0][2])
    for (a0, n0, e0), (a1, n1, e1) in itertools.pairwise(table):
        if alt_m <= a1:
            f = (alt_m - a0) / (a1 - a0)
            return (n0 + f * (n1 - n0), e0 + f * (e1 - e0))
    return (table[-1][1], table[-1][2])
