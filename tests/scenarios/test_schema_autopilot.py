"""The scenario key ``autopilot:``: who flies, its links and timeouts."""

from __future__ import annotations

import jsonschema
import pytest
import yaml

from scenarios.schema import LIBRARY_DIR, json_schema, load_scenario
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
