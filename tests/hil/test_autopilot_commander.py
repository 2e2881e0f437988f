"""The commander (hil.autopilot.commander) against the autopilot's side of the protocols
(tests/helpers/autopilot_commands.py), message by message as MAVLink 2 bytes, on a simulated
clock: parameters read back, the mission handshake, arming through failing pre-arm checks,
the mode confirmed by HEARTBEAT, and each misbehaviour failing with a sentence naming it."""

from __future__ import annotations

import struct
from pathlib import Path
from typing import Any

import pytest

from hil.autopilot.commander import Commander, Script, StepTimeouts
from hil.autopilot.mission import loiter, return_to_launch, takeoff, waypoint
from hil.autopilot.modes import ARDUPLANE_MODES, PX4_MODES
from hil.autopilot.param_file import ParamValue, read_param_file
from hil.codec import mavlink2
from tests.helpers.autopilot_commands import CommandSide

HOME = (47.0, 8.0, 500.0)
STEP_S = 0.01


class Wire:
    """Carries messages both ways as bytes (header ids included), one hop per step."""

    def __init__(self) -> None:
        self.gcs = mavlink2.MAVLink(None, srcSystem=255, srcComponent=190)
        self.ap = mavlink2.MAVLink(None, srcSystem=1, srcComponent=1)
        self.parse_at_ap = mavlink2.MAVLink(None)
        self.parse_at_gcs = mavlink2.MAVLink(None)

    def to_ap(self, msg: Any) -> Any:
        return self.parse_at_ap.parse_buffer(bytes(msg.pack(self.gcs)))[0]

    def to_gcs(self, msg: Any) -> Any:
        return self.parse_at_gcs.parse_buffer(bytes(msg.pack(self.ap)))[0]


def run(commander: Commander, side: CommandSide, *, until_s: float = 300.0,
        heartbeat_every_s: float = 0.5) -> float:
    """Step the clock until the commander finishes; the autopilot sends HEARTBEATs."""
    wire = Wire()
    kind = (mavlink2.MAV_AUTOPILOT_PX4 if side.flavour == "px4"
            else mavlink2.MAV_AUTOPILOT_ARDUPILOTMEGA)
    t = 0.0
    next_hb = 0.0
    while t < until_s and not commander.finished:
        if t >= next_hb:
            next_hb += heartbeat_every_s
            commander.deliver(wire.to_gcs(mavlink2.MAVLink_heartbeat_message(
                mavlink2.MAV_TYPE_FIXED_WING, kind,
                mavlink2.MAV_MODE_FLAG_SAFETY_ARMED if side.armed else 0, side.custom_mode,
                mavlink2.MAV_STATE_ACTIVE, 3)))
        for msg in commander.take_outgoing():
            for reply in side.handle(wire.to_ap(msg), t):
                commander.deliver(wire.to_gcs(reply))
        for reply in side.tick(t):
            commander.deliver(wire.to_gcs(reply))
        commander.poll(t)
        t = round(t + STEP_S, 6)
    return t


def commander(autopilot: str, script: Script) -> Commander:
    return Commander(autopilot, script, HOME, wall_min_s=0.0, retry_wall_s=0.0)


ARDUPLANE_PARAMS = {"ARSPD_SKIP_CAL": 0.0, "TRIM_ARSPD_CM": 2200.0, "ARSPD_OFFSET": 0.0,
                    "SIM_RATE_HZ": 400.0}
PX4_PARAMS = {"FW_AIRSPD_TRIM": 15.0, "FW_AIRSPD_MAX": 20.0, "NAV_DLL_ACT": 2.0,
              "COM_ARM_WO_GPS": 0.0}


def test_parameters_are_set_and_read_back_on_arduplane(tmp_path: Path) -> None:
    path = tmp_path / "c172.parm"
    path.write_text("ARSPD_SKIP_CAL 1\nTRIM_ARSPD_CM 4500\nARSPD_OFFSET,1.7\n")
    side = CommandSide("ardupilot", ARDUPLANE_PARAMS)
    c = commander("ardupilot", Script(params=tuple(read_param_file(path)),
                                      params_file=str(path)))
    run(c, side)
    assert c.failure is None and c.finished
    assert side.params["TRIM_ARSPD_CM"] == 4500.0
    assert side.params["ARSPD_OFFSET"] == pytest.approx(1.7, rel=1e-6)  # a float32 on the way
    assert c.params_confirmed == 3
    assert [s["status"] for s in c.report()["steps"]] == ["done", "done", "skipped",
                                                           "skipped", "skipped"]


def test_px4_integer_parameters_travel_bytewise(tmp_path: Path) -> None:
    path = tmp_path / "c172.params"
    path.write_text("# Onboard parameters\n1\t1\tNAV_DLL_ACT\t0\t6\n"
                    "1\t1\tFW_AIRSPD_TRIM\t45.0\t9\n")
    side = CommandSide("px4", PX4_PARAMS, int_params={"NAV_DLL_ACT", "COM_ARM_WO_GPS"})
    c = commander("px4", Script(params=tuple(read_param_file(path)), params_file=str(path)))
    run(c, side)
    assert c.failure is None
    assert side.params == {**PX4_PARAMS, "NAV_DLL_ACT": 0.0, "FW_AIRSPD_TRIM": 45.0}
    # an INT32 of 2 sent as the float 2.0 would have been read as another integer by PX4
    wire = struct.unpack("<i", struct.pack("<f", 2.0))[0]
    assert wire != 2


def test_a_rejected_parameter_is_named_with_its_file_and_line(tmp_path: Path) -> None:
    path = tmp_path / "c172.parm"
    path.write_text("ARSPD_SKIP_CAL 1\n# the airspeed\nTRIM_ARSPD_CM 4500\n")
    side = CommandSide("ardupilot", ARDUPLANE_PARAMS, reject_params={"TRIM_ARSPD_CM"})
    c = commander("ardupilot", Script(params=tuple(read_param_file(path)),
                                      params_file=str(path)))
    run(c, side)
    assert c.failure is not None
    assert "rejected parameter TRIM_ARSPD_CM = 4500" in c.failure
    assert f"{path}:3" in c.failure
    assert "Param write denied (TRIM_ARSPD_CM)" in c.failure
    assert c.report()["steps"][1]["status"] == "failed"


def test_a_parameter_never_echoed_fails_after_its_timeout() -> None:
    side = CommandSide("ardupilot", ARDUPLANE_PARAMS)  # has no NO_SUCH_PARAM: never answers
    script = Script(params=(ParamValue("ARSPD_SKIP_CAL", 1.0, line=1),
                            ParamValue("NO_SUCH_PARAM", 3.0, line=2)),
                    params_file="p.parm", timeouts=StepTimeouts(params_s=5.0))
    c = commander("ardupilot", script)
    end = run(c, side)
    assert c.failure is not None and end < 6.0
    assert c.failure.startswith("ArduPilot did not confirm its parameters within 5 s")
    assert "parameter NO_SUCH_PARAM (p.parm:2) was never echoed back" in c.failure
    assert c.counters["param_sets"] >= 4  # sent again while it waited


MISSION = (takeoff(47.0, 8.0, 600.0), waypoint(47.01, 8.0, 700.0),
           loiter(47.01, 8.01, 700.0, radius_m=300.0, turns=2.0), return_to_launch())


@pytest.mark.parametrize("legacy", [False, True])
def test_mission_upload_to_arduplane_keeps_its_home_slot(legacy: bool) -> None:
    side = CommandSide("ardupilot", {}, legacy_requests=legacy)
    c = commander("ardupilot", Script(mission=MISSION))
    run(c, side)
    assert c.failure is None and side.mission_accepted
    assert len(side.mission) == 5  # home + 4
    home, to, wp, lo, rtl = side.mission
    assert (home.x, home.y) == (470000000, 80000000)
    assert to.command == mavlink2.MAV_CMD_NAV_TAKEOFF and to.z == pytest.approx(600.0)
    assert (wp.x, wp.y, wp.frame) == (470100000, 80000000, mavlink2.MAV_FRAME_GLOBAL)
    assert lo.command == mavlink2.MAV_CMD_NAV_LOITER_TURNS and (lo.param1, lo.param3) == (2, 300)
    assert rtl.command == mavlink2.MAV_CMD_NAV_RETURN_TO_LAUNCH
    assert c.counters["mission_legacy_requests"] == (5 if legacy else 0)


def test_mission_upload_to_px4_starts_with_the_first_item() -> None:
    side = CommandSide("px4", {})
    c = commander("px4", Script(mission=MISSION))
    run(c, side)
    assert c.failure is None
    assert [m.command for m in side.mission] == [22, 16, 18, 20]


def test_a_lost_item_request_is_asked_again_and_the_upload_completes() -> None:
    side = CommandSide("ardupilot", {}, drop_request=2)
    c = commander("ardupilot", Script(mission=MISSION))
    run(c, side)
    assert c.failure is None and side.mission_accepted
    assert side.requests_sent == [0, 1, 2, 3, 4]


def test_a_mission_refused_for_space_early_in_the_boot_is_sent_again() -> None:
    # ArduPilot answers NO_SPACE while its mission storage is not set up yet
    side = CommandSide("ardupilot", {}, mission_ready_s=3.0)
    c = commander("ardupilot", Script(mission=MISSION))
    run(c, side)
    assert c.failure is None and side.mission_accepted and len(side.mission) == 5


def test_a_mission_always_refused_for_space_fails_saying_so() -> None:
    side = CommandSide("ardupilot", {}, mission_ready_s=1e9)
    c = commander("ardupilot", Script(mission=MISSION, timeouts=StepTimeouts(mission_s=5.0)))
    run(c, side)
    assert c.failure is not None and "MAV_MISSION_NO_SPACE" in c.failure


def test_an_item_never_asked_for_fails_naming_it() -> None:
    side = CommandSide("px4", {}, stall_request=2)
    c = commander("px4", Script(mission=MISSION, timeouts=StepTimeouts(mission_s=8.0)))
    run(c, side)
    assert c.failure is not None
    assert c.failure.startswith("PX4 did not take the mission within 8 s")
    assert "never for item 2 (loiter)" in c.failure


def test_arming_is_retried_while_prearm_checks_fail() -> None:
    side = CommandSide("px4", {}, prearm_ok_s=7.0)
    c = commander("px4", Script(arm=True))
    run(c, side)
    assert c.failure is None and side.armed
    assert side.arm_attempts >= 3
    assert c.armed_s is not None and c.armed_s >= 7.0


def test_never_arming_fails_quoting_the_prearm_reason() -> None:
    side = CommandSide("ardupilot", {}, prearm_ok_s=1e9,
                       prearm_reason="Airspeed 1 not healthy")
    c = commander("ardupilot", Script(arm=True, timeouts=StepTimeouts(arm_s=10.0)))
    run(c, side)
    assert c.failure is not None
    assert c.failure.startswith("ArduPilot did not arm within 10 s")
    assert "MAV_RESULT_FAILED" in c.failure
    assert "'PreArm: Airspeed 1 not healthy'" in c.failure


def test_a_long_prearm_reason_arrives_in_chunks_and_is_quoted_whole() -> None:
    reason = "Airspeed too high - check airspeed calibration"  # 62 characters with the prefix
    side = CommandSide("px4", {}, prearm_ok_s=1e9, prearm_reason=reason)
    c = commander("px4", Script(arm=True, timeouts=StepTimeouts(arm_s=5.0)))
    run(c, side)
    assert c.failure is not None
    assert "MAV_RESULT_TEMPORARILY_REJECTED" in c.failure
    assert f"its last message: 'Preflight Fail: {reason}'" in c.failure


def test_an_arming_command_never_acknowledged_fails() -> None:
    side = CommandSide("px4", {}, never_ack_arm=True)
    c = commander("px4", Script(arm=True, timeouts=StepTimeouts(arm_s=5.0)))
    run(c, side)
    assert c.failure is not None
    assert "did not arm within 5 s: no COMMAND_ACK" in c.failure


@pytest.mark.parametrize(("autopilot", "mode", "custom"), [
    ("ardupilot", "AUTO", ARDUPLANE_MODES["AUTO"]),
    ("px4", "MISSION", 4 << 16 | 4 << 24),
    ("px4", "HOLD", PX4_MODES["LOITER"]),
])
def test_the_mode_is_confirmed_by_heartbeat(autopilot: str, mode: str, custom: int) -> None:
    side = CommandSide(autopilot, {})
    c = commander(autopilot, Script(arm=True, mode=mode))
    run(c, side)
    assert c.failure is None
    assert side.custom_mode == custom
    assert c.mode_reached_s is not None and c.armed_s is not None
    assert c.mode_reached_s >= c.armed_s


def test_a_mode_never_reached_fails_saying_which_mode_it_reports() -> None:
    side = CommandSide("ardupilot", {}, never_reach_mode=True, custom_mode=0)
    c = commander("ardupilot", Script(arm=True, mode="AUTO",
                                      timeouts=StepTimeouts(mode_s=4.0)))
    run(c, side)
    assert c.failure is not None
    assert c.failure.startswith("ArduPilot did not reach the mode within 4 s (it reports MANUAL)")
    assert "MAV_RESULT_ACCEPTED" in c.failure


def test_a_silent_autopilot_fails_at_the_heartbeat_step() -> None:
    c = commander("px4", Script(arm=True, timeouts=StepTimeouts(heartbeat_s=3.0)))
    for i in range(400):
        c.poll(i * STEP_S)
    assert c.failure == ("PX4 did not send a HEARTBEAT within 3 s: no HEARTBEAT came on its "
                         "link")


def test_the_flight_ending_mid_script_fails_the_script() -> None:
    side = CommandSide("px4", {}, prearm_ok_s=1e9)
    c = commander("px4", Script(arm=True))
    run(c, side, until_s=5.0)
    c.end(5.0)
    assert c.failure is not None
    assert c.failure.startswith("the flight ended at 5.0 s while PX4 was still not armed")
