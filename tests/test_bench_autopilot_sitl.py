"""The real-autopilot bench's altitude hold: judged against the commanded mission altitude,
outside turns, from when the truth reached it (bench/autopilot_sitl.py)."""

from __future__ import annotations

import importlib.util
import math
from pathlib import Path
from types import ModuleType
from typing import Any

import pytest

from fusion.rotations import euler_to_quat
from hil.codec import mavlink2
from hil.tlog import TlogWriter

BENCH = Path(__file__).resolve().parent.parent / "bench" / "autopilot_sitl.py"


def _bench() -> ModuleType:
    spec = importlib.util.spec_from_file_location("bench_autopilot_sitl", BENCH)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _truth(t_s: float) -> tuple[float, float]:
    """(alt MSL m, roll deg) of the synthetic flight: a take-off climb to 748 m in 20 s, 748 m
    on the waypoint leg but 700 m in a 30 deg turn at 40-45 s, a climb at 5.2 m/s to the
    loiter's 800 m from 60 s, 810 m from 70 s, 600 m on the return from 80 s."""
    if t_s < 20.0:
        return 450.0 + 298.0 * t_s / 20.0, 0.0
    if t_s < 60.0:
        return (700.0, 30.0) if 40.0 <= t_s < 45.0 else (748.0, 0.0)
    if t_s < 70.0:
        return 748.0 + 5.2 * (t_s - 60.0), 0.0
    return (810.0, 0.0) if t_s < 80.0 else (600.0, 0.0)


def test_the_hold_is_judged_against_the_mission_altitude_outside_turns(
        tmp_path: Path) -> None:
    tlog = tmp_path / "run.tlog"
    pack = mavlink2.MAVLink(None, srcSystem=1, srcComponent=200)
    with TlogWriter(tlog) as w:
        for k in range(1000):
            t_s = 0.1 * k
            alt_m, roll_deg = _truth(t_s)
            q = [float(v) for v in euler_to_quat([math.radians(roll_deg), 0.0, 0.0])]
            msg = mavlink2.MAVLink_hil_state_quaternion_message(
                round(t_s * 1e6), q, 0, 0, 0, 470000000, 80000000, round(alt_m * 1e3),
                0, 0, 0, 0, 0, 0, 0, 0)
            w.write(msg.pack(pack), round(t_s * 1e6))
    mission = [{"seq": 0, "label": "home", "alt_msl_m": 450.0},
               {"seq": 1, "label": "takeoff 1", "alt_msl_m": 750.0},
               {"seq": 2, "label": "waypoint 1", "alt_msl_m": 750.0},
               {"seq": 3, "label": "loiter 1", "alt_msl_m": 800.0},
               {"seq": 4, "label": "rtl 1", "alt_msl_m": None}]
    summary: dict[str, Any] = {"autopilot": {
        "script": {"mission": mission},
        "health": {"mission_current": [{"time_s": 0.0, "seq": 1}, {"time_s": 20.0, "seq": 2},
                                       {"time_s": 60.0, "seq": 3}, {"time_s": 80.0, "seq": 4}]}}}
    hold = _bench().altitude_hold(tlog, summary)
    # the take-off and the return are not judged; the climb to the loiter only from its
    # first sample within 10 m of 800 m (790.12 m at 68.1 s)
    assert hold["commanded_alt_msl_m"] == [750.0, 800.0]
    out = hold["outside_turns"]
    assert out["min_deviation_m"] == pytest.approx(-9.9)
    assert out["max_deviation_m"] == pytest.approx(10.0)
    assert out["seconds"] == pytest.approx(35.0 + 11.9, abs=0.2)
    assert hold["in_turns"]["min_deviation_m"] == pytest.approx(-50.0)
    assert hold["in_turns"]["seconds"] == pytest.approx(5.0, abs=0.2)
    assert hold["within_target"] is True
    # AND without the autopilot's mission progress nothing is judged, and it says why
    summary["autopilot"]["health"]["mission_current"] = []
    assert _bench().altitude_hold(tlog, summary) == {
        "problem": "the autopilot reported no MISSION_CURRENT"}
