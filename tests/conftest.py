"""Shared fixtures: one short recorded lockstep flight reused by the CLI / replay tests, and an
in-process Zenoh router for the bus tests."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from hil.pipeline import SimSetup, record_flight
from hil.router import ZenohRouter

pytest_plugins = ["pytester"]


@pytest.fixture(scope="session")
def short_flight_log(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """180 s racetrack, industrial-mems IMU, seed 7, GNSS off from 120 s for 30 s."""
    path = tmp_path_factory.mktemp("flight") / "run.tlog"
    request = SimSetup.build(
        plan="racetrack", duration_s=180.0, seed=7, gnss_off=["120:30"], rate_hz=200.0
    )
    report = record_flight(request, path)
    assert report.ended is None
    return path


@pytest.fixture(scope="module")
def router() -> Iterator[str]:
    """An in-process Zenoh router on a free loopback port; its endpoint."""
    with ZenohRouter() as r:
        yield r.endpoint
