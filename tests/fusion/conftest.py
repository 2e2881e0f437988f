"""Synthetic flights shared by the NavFilter tests (one preparation per test module)."""

from __future__ import annotations

import math

import pytest

from tests.helpers.nav_synth import Flight, Prepared, prepare


@pytest.fixture(scope="module")
def racetrack() -> Prepared:
    """45 s: straight, a 120 deg right turn, a climb, a left turn; 10 deg of crab (wind)."""
    return prepare(
        Flight(
            duration_s=45.0,
            crab_rad=math.radians(10.0),
            turns=[(12.0, 24.0, 0.2), (33.0, 43.0, -0.2)],
            climbs=[(25.0, 33.0, 3.0)],
        )
    )


@pytest.fixture(scope="module")
def straight() -> Prepared:
    """30 s straight and level with 10 deg of crab: heading unobservable from GNSS alone."""
    return prepare(Flight(duration_s=30.0, crab_rad=math.radians(10.0)))


@pytest.fixture(scope="module")
def parked() -> Prepared:
    """65 s at rest (pitch 3 deg, heading 57 deg)."""
    return prepare(Flight(duration_s=65.0, speed_mps=0.0, heading0_rad=1.0, aoa_rad=0.05))
