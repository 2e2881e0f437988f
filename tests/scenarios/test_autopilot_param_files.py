"""The parameter files shipped for the default aircraft: they parse, name each parameter once,
and agree with the simulator and with each other.

Whether every name is a parameter of the autopilot was checked against each autopilot's own
parameter definitions when the files were written (the file headers say which versions); CI has
neither source tree, so here the names are checked for MAVLink's ``param_id`` form.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import pytest

from scenarios.schema import LIBRARY_DIR
from sim.flight import FlightConfig

ARDUPLANE = LIBRARY_DIR / "autopilot" / "arduplane-c172x.parm"
PX4 = LIBRARY_DIR / "autopilot" / "px4-c172x.params"
_NAME = re.compile(r"[A-Z][A-Z0-9_]{0,15}")


def _arduplane(path: Path) -> dict[str, float]:
    values: dict[str, float] = {}
    for number, raw in enumerate(path.read_text().splitlines(), 1):
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        fields = line.split()
        assert len(fields) == 2, f"{path.name}:{number}: NAME VALUE expected: {raw!r}"
        name, value = fields[0], float(fields[1])
        assert _NAME.fullmatch(name), f"{path.name}:{number}: bad name {name!r}"
        assert name not in values, f"{path.name}:{number}: {name} given twice"
        assert math.isfinite(value)
        values[name] = value
    return values


def _px4(path: Path) -> dict[str, float]:
    values: dict[str, float] = {}
    for number, raw in enumerate(path.read_text().splitlines(), 1):
        if not raw.strip() or raw.startswith("#"):
            continue
        fields = raw.split("\t")
        assert len(fields) == 5, f"{path.name}:{number}: SYSID COMPID NAME VALUE TYPE expected"
        system, component, name, text, kind = fields
        assert (system, component) == ("1", "1")
        assert _NAME.fullmatch(name), f"{path.name}:{number}: bad name {name!r}"
        assert name not in values, f"{path.name}:{number}: {name} given twice"
        assert kind in ("6", "9"), f"{path.name}:{number}: type {kind} is neither INT32 nor REAL32"
        value = float(text)
        assert math.isfinite(value)
        if kind == "6":
            assert value == int(value) and "." not in text, f"{path.name}:{number}: INT32 {text}"
        values[name] = value
    return values


@pytest.fixture(scope="module")
def arduplane() -> dict[str, float]:
    return _arduplane(ARDUPLANE)


@pytest.fixture(scope="module")
def px4() -> dict[str, float]:
    return _px4(PX4)


def test_arduplane_file_fits_the_simulator(arduplane: dict[str, float]) -> None:
    assert arduplane["SIM_RATE_HZ"] == FlightConfig().rate_hz  # lockstep at hilnav's rate
    assert arduplane["ARSPD_TYPE"] == 100 and arduplane["ARSPD_SKIP_CAL"] == 1
    assert arduplane["ARSPD_OFFSET"] == 0  # the SITL sensor's pressure carries no offset
    speeds = [arduplane[k] for k in ("AIRSPEED_STALL", "AIRSPEED_MIN", "AIRSPEED_CRUISE",
                                     "AIRSPEED_MAX")]
    assert speeds == sorted(speeds) and len(set(speeds)) == 4
    assert arduplane["SCALING_SPEED"] == arduplane["AIRSPEED_CRUISE"]
    assert arduplane["TKOFF_ROTATE_SPD"] < arduplane["AIRSPEED_MIN"]


def test_px4_file_fits_the_simulator(px4: dict[str, float]) -> None:
    speeds = [px4[k] for k in ("FW_AIRSPD_STALL", "FW_AIRSPD_MIN", "FW_AIRSPD_TRIM",
                               "FW_AIRSPD_MAX")]
    assert speeds == sorted(speeds) and len(set(speeds)) == 4
    assert 0.0 <= px4["FW_THR_MIN"] < px4["FW_THR_TRIM"] < px4["FW_THR_MAX"] <= 1.0
    assert px4["RWTO_TKOFF"] == 1 and px4["RWTO_ROT_AIRSPD"] < px4["FW_AIRSPD_MIN"]


def test_both_autopilots_fly_the_same_aircraft(arduplane: dict[str, float],
                                               px4: dict[str, float]) -> None:
    assert arduplane["AIRSPEED_CRUISE"] == px4["FW_AIRSPD_TRIM"]
    assert arduplane["AIRSPEED_MIN"] == px4["FW_AIRSPD_MIN"]
    assert arduplane["AIRSPEED_STALL"] == px4["FW_AIRSPD_STALL"]
    assert arduplane["TRIM_THROTTLE"] / 100.0 == pytest.approx(px4["FW_THR_TRIM"])
    assert arduplane["TKOFF_ROTATE_SPD"] == px4["RWTO_ROT_AIRSPD"]
    assert arduplane["WP_LOITER_RAD"] == px4["NAV_LOITER_RAD"]
