"""`hilnav run` / `hilnav compare`: lockstep scenario runs, their files, verdicts and exit codes."""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest
from typer.testing import CliRunner

from scenarios.cli.app import app
from scenarios.compare import compare, parse_methods
from scenarios.replay import replay
from scenarios.runner import run_scenario
from scenarios.schema import Scenario, load_scenario

SCENARIO = """\
name: short-outage
description: 100 s racetrack with one 20 s GNSS outage and a slow spoof (test scenario)
plan: racetrack
duration_s: 100
seed: 3
sensors:
  imu: {preset: industrial-mems}
fusion: {bridge: none, altitude: ekf}
criteria:
  - {name: outage accuracy, metric: outages.horizontal_rmse_m, max: %s}
  - {name: outage drift, metric: outages.horizontal_max_m, max: 200 m}
events:
  - {type: gnss_outage, at: 40, duration: 20}
  - {type: gnss_spoof_drift, at: 75, duration: 15, rate_mps: 3.0, bearing_deg: 90}
"""


def _write(tmp: Path, limit: str = "100 m") -> Path:
    path = tmp / "short.yaml"
    path.write_text(SCENARIO % limit)
    return path


@pytest.fixture(scope="module")
def scenario(tmp_path_factory: pytest.TempPathFactory) -> Scenario:
    return load_scenario(_write(tmp_path_factory.mktemp("scn")))


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory: pytest.TempPathFactory, scenario: Scenario) -> Path:
    out = tmp_path_factory.mktemp("run")
    run_scenario(scenario, out)
    return out


def test_run_writes_the_contract_files(run_dir: Path) -> None:
    for name in ("summary.json", "run.tlog", "junit.xml", "report.html", "ground_track.png"):
        assert (run_dir / name).is_file(), name
    s = json.loads((run_dir / "summary.json").read_text())
    for key in ("scenario", "seed", "sim_duration_s", "wall_s", "realtime_factor", "bridge",
                "altitude", "outages", "gnss_on", "nees", "criteria", "passed"):
        assert key in s
    assert s["scenario"] == "short-outage" and s["seed"] == 3
    assert s["sim_duration_s"] == pytest.approx(100.0, abs=0.1)
    # the outage event removed the fixes: exactly one outage, where the timeline put it
    assert len(s["outages"]) == 1
    assert s["outages"][0]["start_s"] == pytest.approx(40.0, abs=1.5)
    assert s["outages"][0]["end_s"] == pytest.approx(60.0, abs=1.5)
    # the timeline is scored as events, the spoof as a spoof
    kinds = {e["type"]: e["kind"] for e in s["events"]}
    assert kinds == {"gnss_outage": "generic", "gnss_spoof_drift": "spoof"}
    assert s["health"]["faults"]["gnss_spoofed"] > 0
    assert s["passed"] is all(c["ok"] for c in s["criteria"])
    suite = ET.parse(run_dir / "junit.xml").getroot()
    assert len(suite.findall(".//testcase")) == len(s["criteria"])


def test_replay_of_the_run_log_scores_the_same(run_dir: Path, scenario: Scenario,
                                                tmp_path: Path) -> None:
    """The run fused the frames it wrote: replaying run.tlog reproduces its numbers."""
    from scenarios.runner import filter_config

    s = json.loads((run_dir / "summary.json").read_text())
    r = replay(run_dir / "run.tlog", tmp_path, config=filter_config(scenario)).summary
    assert r["outages"][0]["horizontal_rmse_m"] == pytest.approx(
        s["outages"][0]["horizontal_rmse_m"], rel=1e-9)
    # (gnss_on differs by design: the run knows the spoof window and leaves it out)
    assert r["health"]["filter"] == s["health"]["filter"]


def test_filter_models_the_scenario_gnss_receiver(scenario: Scenario, tmp_path: Path) -> None:
    """The filter's GNSS position-bias states take the scenario receiver's Gauss-Markov error."""
    from scenarios.runner import filter_config

    gnss = scenario.sensor_config().gnss
    config = filter_config(scenario)
    cfg = config.gnss
    # GIVEN the default (modern) receiver, whose position error is mostly Gauss-Markov
    assert gnss.horizontal_gm_sigma_m > 0.0
    # THEN the filter carries bias states with the receiver's sigma and correlation time
    # (and the scale-factor and misalignment states the IMU datasheet calls for, and the
    # air-data block, dormant until the stream carries air data)
    assert config.state_layout == "ins35+gnss+air"
    assert (cfg.bias_sigma_h_m, cfg.bias_tau_h_s) == (gnss.horizontal_gm_sigma_m,
                                                     gnss.horizontal_gm_tau_s)
    assert (cfg.bias_sigma_v_m, cfg.bias_tau_v_s) == (gnss.vertical_gm_sigma_m,
                                                     gnss.vertical_gm_tau_s)
    # AND a receiver without a correlated part keeps the white-noise model
    imu_line = "  imu: {preset: industrial-mems}\n"
    white_gnss = "  gnss: {preset: modern, horizontal_gm_sigma_m: 0, vertical_gm_sigma_m: 0}\n"
    text = SCENARIO.replace(imu_line, imu_line + white_gnss)
    (tmp_path / "white.yaml").write_text(text % "100 m")
    white = load_scenario(tmp_path / "white.yaml")
    assert filter_config(white).state_layout == "ins35+air"


def test_same_seed_same_numbers(run_dir: Path, scenario: Scenario, tmp_path: Path) -> None:
    run_scenario(scenario, tmp_path, reports=False, tlog=False)
    again = json.loads((tmp_path / "summary.json").read_text())
    first = json.loads((run_dir / "summary.json").read_text())
    assert again["outages"] == first["outages"]
    assert again["gnss_on"] == first["gnss_on"]
    assert again["events"] == first["events"]


def test_cli_exit_codes(tmp_path: Path) -> None:
    runner = CliRunner()
    ok = runner.invoke(app, ["run", str(_write(tmp_path, "100 m")), "--out",
                             str(tmp_path / "ok"), "--quiet", "--seed", "4"])
    assert ok.exit_code == 0, ok.output
    assert json.loads((tmp_path / "ok" / "summary.json").read_text())["seed"] == 4
    strict = tmp_path / "strict"
    strict.mkdir()
    bad = runner.invoke(app, ["run", str(_write(strict, "1 cm")), "--out",
                              str(tmp_path / "fail"), "--quiet", "--seed", "4"])
    assert bad.exit_code == 1, bad.output
    assert "outage accuracy" in bad.output
    summary = json.loads((tmp_path / "fail" / "summary.json").read_text())
    assert summary["passed"] is False
    missing = runner.invoke(app, ["run", str(tmp_path / "nope.yaml"), "--out", str(tmp_path)])
    assert missing.exit_code == 2
    assert "Traceback" not in missing.output
    unknown = runner.invoke(app, ["run", str(_write(tmp_path)), "--out", str(tmp_path),
                                  "--bridge", "kalman-magic"])
    assert unknown.exit_code == 2
    assert "gmdh" in unknown.output  # the message lists the valid methods


def test_compare_uses_the_same_frames_for_every_method(scenario: Scenario,
                                                         tmp_path: Path) -> None:
    short = scenario.with_overrides(duration_s=95.0)
    result = compare(short, ["none", "gmdh"], [5], tmp_path)
    for m in ("none", "gmdh"):
        row = result["methods"][m]
        assert set(row["outage_rmse"]) == {"lat_deg", "lon_deg", "h_m", "vn_mps", "ve_mps",
                                           "vd_mps", "horizontal_m"}
        assert row["update_us_per_sample"] > 0
        assert row["outages"] == 1
    # identical sensor data: GNSS-on accuracy before the first outage is the same for both
    s_none = json.loads((tmp_path / "seed5" / "none" / "summary.json").read_text())
    s_gmdh = json.loads((tmp_path / "seed5" / "gmdh" / "summary.json").read_text())
    assert s_none["sim_duration_s"] == s_gmdh["sim_duration_s"]
    assert s_none["outages"][0]["start_s"] == s_gmdh["outages"][0]["start_s"]
    on = json.loads((tmp_path / "compare.json").read_text())
    assert on["seeds"] == [5] and on["scenario"] == "short-outage"
    assert "| none |" in (tmp_path / "compare.md").read_text()
    assert (tmp_path / "drift_by_method.png").is_file()


def test_parse_methods_errors() -> None:
    assert parse_methods("none, gmdh") == ["none", "gmdh"]
    with pytest.raises(ValueError, match="valid methods"):
        parse_methods("none,bogus")
    with pytest.raises(ValueError, match="twice"):
        parse_methods("none,none")


def test_schema_command_prints_json_schema() -> None:
    out = CliRunner().invoke(app, ["schema"])
    assert out.exit_code == 0
    schema = json.loads(out.stdout)
    assert "properties" in schema and "events" in schema["properties"]


def test_pytest_plugin_runs_scenarios_as_tests(pytester: pytest.Pytester, tmp_path: Path) -> None:
    folder = pytester.mkdir("my_scenarios")
    (folder / "good.yaml").write_text((SCENARIO % "100 m").replace("duration_s: 100",
                                                                  "duration_s: 90"))
    (folder / "strict.yaml").write_text((SCENARIO % "1 cm").replace("duration_s: 100",
                                                                   "duration_s: 90"))
    (folder / "broken.yaml").write_text("name: x\nduration_s: -5\n")
    # without --hilnav the YAML files are not collected
    assert pytester.runpytest_inprocess(str(folder)).ret == pytest.ExitCode.NO_TESTS_COLLECTED
    res = pytester.runpytest_inprocess("--hilnav", str(folder), "--hilnav-out",
                                       str(tmp_path / "ci"))
    res.assert_outcomes(passed=1, failed=2)
    res.stdout.fnmatch_lines(["*broken.yaml:*duration*", "*strict.yaml: outage accuracy*"])
    assert (tmp_path / "ci" / "good" / "junit.xml").is_file()


def test_a_flight_that_ended_early_cuts_its_timeline_where_it_ended(scenario: Scenario) -> None:
    # GIVEN the short scenario's timeline (outage 40-60 s, spoof 75-90 s)
    from scenarios.runner import event_windows

    # WHEN the flight (hilnav's guidance or an autopilot) ended at 50 s
    rows = event_windows(scenario, 50.0, ended_early=True)
    # THEN the outage is cut at 50 s and marked so; the spoof was never reached
    outage, spoof = rows
    assert (outage["start_s"], outage["end_s"], outage["planned_end_s"]) == (40.0, 50.0, 60.0)
    assert outage["clipped"] and not outage.get("not_reached")
    assert spoof["not_reached"] and spoof["end_s"] is None and spoof["planned_end_s"] == 90.0
    # AND a flight that flew to its end keeps the timeline as it is
    assert [set(r) for r in event_windows(scenario, 100.0)] == [
        {"type", "kind", "start_s", "end_s"}] * 2
