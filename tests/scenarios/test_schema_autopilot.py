"""The scenario key ``autopilot:``: who flies, its links and timeouts."""

from __future__ import annotations

import math

import jsonschema
import pytest
import yaml

from hil.autopilot.param_file import read_param_file
from scenarios.schema import LIBRARY_DIR, json_schema, load_scenario
from scenarios.schema.autopilot_script import TAKEOFF_AHEAD_M, mission_items
from scenarios.schema.sections import MissionItemSection
from tests.scenarios.test_schema import error_of, write

BASE = """
duration_s: 60
"""


def test_without_the_key_hilnav_flies() -> None:
    scn = load_scenario(LIBRARY_DIR / "turning-60s-outages.yaml")
    assert scn.autopilot.kind == "none" and not scn.autopilot.flies


def test_shorthand_and_full_form(tmp_path) -> None:  # type: ignore[no-untyped-def]
    short = load_scenario(write(tmp_path, BASE + "autopilot: ardupilot\n"))
    assert short.autopilot.kind == "ardupilot" and short.autopilot.flies
    assert short.autopilot.telemetry == "udpin:127.0.0.1:14550"
    full = load_scenario(write(tmp_path, BASE + """
autopilot:
  kind: px4
  link: tcpin:0.0.0.0:4560
  actuator_map: maps/plane.yaml
  stall_timeout_s: 3
""", name="full.yaml"))
    ap = full.autopilot
    assert (ap.kind, ap.link, ap.stall_timeout_s) == ("px4", "tcpin:0.0.0.0:4560", 3.0)
    # files named in the section are relative to the scenario file
    assert full.autopilot_path(ap.actuator_map) == tmp_path / "maps" / "plane.yaml"


@pytest.mark.parametrize(("text", "needle"), [
    ("autopilot: betaflight\n", "autopilot"),
    ("autopilot: {kind: px4, servo_map: s.yaml}\n", "servo_map is a setting of autopilot kind "
                                                    "'ardupilot'"),
    ("autopilot: {kind: ardupilot, actuator_map: a.yaml}\n", "actuator_map is a setting"),
    ("autopilot: {kind: px4, stall_timeout_s: 0}\n", "stall_timeout_s"),
    ("autopilot: {kind: px4, baud: 57600}\n", "baud"),
])
def test_bad_autopilot_settings_are_one_line_errors(tmp_path, text: str,  # type: ignore[no-untyped-def]
                                                    needle: str) -> None:
    err = error_of(write(tmp_path, BASE + text))
    assert needle in str(err)


def test_library_autopilot_scenario_is_valid_and_flown_by_px4() -> None:
    path = LIBRARY_DIR / "px4-fixed-wing-gnss-outage.yaml"
    scn = load_scenario(path)
    assert scn.autopilot.kind == "px4" and scn.autopilot.link == "tcpin:127.0.0.1:4560"
    validator = jsonschema.Draft202012Validator(json_schema())
    assert list(validator.iter_errors(yaml.safe_load(path.read_text()))) == []
    assert list(validator.iter_errors({"duration_s": 10, "autopilot": "px4"})) == []
    bad = {"duration_s": 10, "autopilot": {"kind": "inav"}}
    assert list(validator.iter_errors(bad))


def test_campaign_and_compare_refuse_a_scenario_flown_by_an_autopilot(tmp_path) -> None:  # type: ignore[no-untyped-def]
    from scenarios.campaign.plan import plan_runs
    from scenarios.compare import compare

    path = LIBRARY_DIR / "px4-fixed-wing-gnss-outage.yaml"
    with pytest.raises(ValueError, match="fly it with `hilnav run`, not a campaign"):
        plan_runs([path], [1], {})
    with pytest.raises(ValueError, match="not `compare`"):
        compare(load_scenario(path), ["none"], [1], tmp_path)


SCRIPT = """
autopilot:
  kind: ardupilot
  params: c172.parm
  arm: true
  mode: auto
  timeouts: {arm_s: 90}
  mission:
    - {type: takeoff, alt_m: 100}
    - {type: waypoint, north_m: 1000, east_m: 0, alt_m: 200}
    - {type: loiter, radius_m: 300, turns: 2}
    - {type: waypoint, lat_deg: 47.01, lon_deg: 8.0, alt_m: 150}
    - {type: rtl}
"""


def test_the_script_keys_become_the_commanders_script(tmp_path) -> None:  # type: ignore[no-untyped-def]
    (tmp_path / "c172.parm").write_text("ARSPD_SKIP_CAL 1\nTRIM_ARSPD_CM 4500\n")
    start = "start: {lat_deg: 47.0, lon_deg: 8.0, alt_msl_m: 1000, heading_deg: 0}\n"
    scn = load_scenario(write(tmp_path, BASE + start + SCRIPT))
    assert scn.autopilot.scripted
    script = scn.autopilot_script()
    assert script.arm and script.mode == "AUTO" and script.timeouts.arm_s == 90.0
    assert [p.name for p in script.params] == ["ARSPD_SKIP_CAL", "TRIM_ARSPD_CM"]
    takeoff, wp, loiter, wp2, rtl = script.mission
    # a takeoff without a position: TAKEOFF_AHEAD_M ahead on the start's heading (000)
    assert takeoff.lat_deg == pytest.approx(47.0 + TAKEOFF_AHEAD_M / 111_180, abs=2e-6)
    assert (takeoff.lon_deg, takeoff.alt_msl_m) == (8.0, 1100.0)
    assert wp.lat_deg == pytest.approx(47.0 + 1000 / 111_180, abs=2e-5)  # ~1 km north
    assert wp.lon_deg == 8.0 and wp.alt_msl_m == 1200.0
    # a loiter without a position circles the previous item's, at its altitude
    assert (loiter.lat_deg, loiter.alt_msl_m, loiter.param1, loiter.param3) == (
        wp.lat_deg, 1200.0, 2.0, 300.0)
    assert (wp2.lat_deg, wp2.alt_msl_m) == (47.01, 1150.0)
    assert rtl.lat_deg is None


def test_a_takeoff_without_a_position_lies_ahead_on_the_start_heading() -> None:
    # GIVEN a start facing 090 (east) WHEN the takeoff item has no position
    item = MissionItemSection.model_validate({"type": "takeoff", "alt_m": 300})
    (takeoff,) = mission_items([item], (47.0, 8.0, 450.0), heading_deg=90.0)
    # THEN it lies TAKEOFF_AHEAD_M east of the start (PX4 rolls along that bearing)
    east_m = math.radians(takeoff.lon_deg - 8.0) * 6_389_000 * math.cos(math.radians(47.0))
    assert east_m == pytest.approx(TAKEOFF_AHEAD_M, rel=2e-3)
    assert takeoff.lat_deg == pytest.approx(47.0, abs=1e-9) and takeoff.alt_msl_m == 750.0


@pytest.mark.parametrize(("text", "needle"), [
    ("autopilot: {kind: px4, mode: AUTO}\n",
     "unknown px4 mode 'AUTO'; valid: MANUAL, STABILIZED, ACRO, ALTCTL, POSCTL, OFFBOARD, HOLD"),
    ("autopilot: {kind: ardupilot, mode: MISION}\n", "unknown ardupilot mode 'MISION'"),
    ("autopilot: {kind: none, arm: true}\n", "arm scripts an autopilot"),
    ("autopilot: {kind: px4, arm: true, telemetry: null}\n", "set telemetry"),
    ("autopilot: {kind: px4, mission: [{type: waypoint, alt_m: 1}]}\n",
     "a waypoint needs lat_deg/lon_deg or north_m/east_m"),
    ("autopilot: {kind: px4, mission: [{type: rtl, alt_m: 1}]}\n",
     "alt_m is not a key of a rtl item"),
    ("autopilot: {kind: px4, mission: [{type: loiter, radius_m: 100}]}\n",
     "turns or time_s"),
    ("autopilot: {kind: px4, mission: [{type: waypoint, north_m: 1, lat_deg: 2, lon_deg: 3, "
     "alt_m: 1}]}\n", "not both"),
    ("autopilot: {kind: px4, mission: [{type: dive}]}\n", "type"),
    ("autopilot: {kind: px4, params: none.params}\n", "cannot read the parameter file"),
])
def test_bad_script_keys_are_one_line_errors(tmp_path, text: str,  # type: ignore[no-untyped-def]
                                             needle: str) -> None:
    err = str(error_of(write(tmp_path, BASE + text)))
    assert needle in err and "\n" not in err


def test_a_bad_parameter_file_names_its_line(tmp_path) -> None:  # type: ignore[no-untyped-def]
    (tmp_path / "bad.params").write_text("1 1 FW_AIRSPD_TRIM 45 9\n1 1 FW_AIRSPD_MAX fast 9\n")
    err = str(error_of(write(tmp_path, BASE + "autopilot: {kind: px4, params: bad.params}\n")))
    assert f"{tmp_path / 'bad.params'}:2: the value of FW_AIRSPD_MAX is not a number" in err


@pytest.mark.parametrize(("name", "kind", "mode", "added"), [
    ("arduplane-mission-gnss-outage.yaml", "ardupilot", "AUTO", 0),
    ("px4-mission-gnss-outage.yaml", "px4", "MISSION", 0),
    # the same with aiding: hilnav, its parameters added to the file's
    ("arduplane-mission-gnss-outage-aided.yaml", "ardupilot", "AUTO", 2),
    ("px4-mission-gnss-outage-aided.yaml", "px4", "MISSION", 1),
])
def test_library_mission_scenarios_load_with_their_script(name: str, kind: str, mode: str,
                                                          added: int) -> None:
    path = LIBRARY_DIR / "autopilot" / name
    scn = load_scenario(path)
    validator = jsonschema.Draft202012Validator(json_schema())
    assert list(validator.iter_errors(yaml.safe_load(path.read_text()))) == []
    assert scn.autopilot.kind == kind and scn.duration_s == 600.0
    script = scn.autopilot_script()
    params_path = scn.autopilot_path(scn.autopilot.params)
    assert params_path is not None
    shipped = read_param_file(params_path)
    assert script.arm and script.mode == mode
    assert len(script.params) == len(shipped) + added
    assert [p.name for p in script.params[:len(shipped)]] == [p.name for p in shipped]
    labels = ["waypoint 1", "waypoint 2", "waypoint 3", "waypoint 4", "loiter 1", "rtl 1"]
    # from the runway: both take off on their first item
    assert scn.start_state().kind == "ground"
    assert [item.label for item in script.mission] == ["takeoff 1", *labels]
    assert scn.outage_windows() == ((300.0, 360.0),)


def test_ground_start_for_an_autopilot(tmp_path) -> None:  # type: ignore[no-untyped-def]
    short = load_scenario(write(tmp_path, BASE + "start: ground\nautopilot: ardupilot\n"))
    start = short.start_state()
    assert start.on_ground and start.alt_msl_m == 1000.0  # the c172x's suggested altitude
    full = load_scenario(write(tmp_path, BASE + """
start: {kind: ground, alt_msl_m: 450, heading_deg: 250}
autopilot: px4
""", name="full.yaml"))
    start = full.start_state()
    assert (start.kind, start.alt_msl_m, start.heading_deg) == ("ground", 450.0, 250.0)
    assert full.flight_config().start.terrain_alt_msl_m == 450.0
    assert load_scenario(write(tmp_path, BASE + "start: air\n", name="air.yaml")).start_state(
    ).kind == "air"
    validator = jsonschema.Draft202012Validator(json_schema())
    assert list(validator.iter_errors({"duration_s": 10, "start": "ground",
                                       "autopilot": "px4"})) == []


@pytest.mark.parametrize(("text", "needle"), [
    ("start: ground\n", "a ground start needs an autopilot to take off"),
    ("start: ground\nautopilot: none\n", "ground start needs an autopilot"),
    ("start: {kind: ground, airspeed_mps: 40}\nautopilot: px4\n",
     "a ground start is at rest: remove airspeed_mps"),
    ("start: {alt_msl_m: 50}\n", "in-air start needs alt_msl_m >= 100"),
    ("start: runway\nautopilot: px4\n", "kind"),
    ("start: ground\nautopilot: px4\nwind_ned_mps: [5, 0, 0]\nwind_shear_exponent: 0.14\n",
     "wind_ref_agl_m"),
])
def test_bad_ground_starts_are_one_line_errors(tmp_path, text: str,  # type: ignore[no-untyped-def]
                                               needle: str) -> None:
    err = error_of(write(tmp_path, BASE + text))
    assert needle in str(err)
