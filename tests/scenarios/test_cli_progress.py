"""What the command line says while and after it flies: progress, a missed speed target, the
first-run notice of unbuilt kernels, ``--version``, and the failures of a run.

GIVEN a user (or a CI log) watching a command, WHEN it flies, ends or fails, THEN it says how
far it is, whether it kept its speed, and every reason it failed.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import pytest
from typer.testing import CliRunner

from scenarios.cli import first_run, output
from scenarios.cli.app import app
from scenarios.cli.autopilot_hints import ARDUPILOT_MAVLINK, ardupilot_command, px4_command
from scenarios.cli.up import SimLogRelay

runner = CliRunner()


# ----------------------------------------------------------------------------- progress
def test_a_log_gets_a_progress_line_every_tenth_of_the_flight(
        capsys: pytest.CaptureFixture[str]) -> None:
    """GIVEN stderr is not a terminal (a CI log), WHEN a 100 s flight reports every second,
    THEN ten plain lines say the simulated time, and the GNSS window while it is on."""
    with output.progress_bar(100.0, "flying", events=[(30.0, 50.0, "GNSS off")]) as progress:
        for t in range(101):
            progress(float(t))
    lines = [ln for ln in capsys.readouterr().err.splitlines() if ln.startswith("flying:")]
    assert len(lines) == 10
    assert lines[0].startswith("flying: 10/100 s simulated (10 %)")
    assert [ln for ln in lines if "GNSS off" in ln] == [lines[2], lines[3]]  # 30 s and 40 s
    assert "x real time" in lines[-1]


def test_quiet_says_nothing(capsys: pytest.CaptureFixture[str]) -> None:
    with output.progress_bar(10.0, "flying", quiet=True) as progress:
        for t in range(11):
            progress(float(t))
    assert capsys.readouterr().err == ""


def test_a_missed_speed_target_is_said_as_such() -> None:
    said, missed = output.speed_sentence(8.19, 10.0)
    assert missed and said == ("8.19x real time: missed the 10x target (the machine was too "
                               "slow)")
    said, missed = output.speed_sentence(9.9, 10.0)
    assert not missed and "target 10x" in said


def test_up_relays_the_sim_childs_progress_warnings_and_result(tmp_path: Path) -> None:
    """GIVEN the sim child's log grows line by line, WHEN up polls it, THEN its progress lines
    become progress, its warning a warning and its result line a log line."""
    seen: dict[str, list[Any]] = {"progress": [], "log": [], "warn": []}
    relay = SimLogRelay(lambda t, info: seen["progress"].append((t, info)),
                        seen["log"].append, seen["warn"].append)
    log = tmp_path / "sim.log"
    log.write_text("sim: streaming to udpout:127.0.0.1:1 at 10x real time\n"
                   "flying: 60/600 s simulated (10 %), 9.8x real time\nflying: 120/6")
    relay.poll(log)
    with log.open("a") as f:
        f.write("00 s simulated (20 %), 8.1x real time, GNSS off\n"
                "sent 10/10 frames, 600.0 s simulated in 73.3 s (8.19x real time: missed the "
                "10x target (the machine was too slow))\n"
                "warning: 8.19x real time: missed the 10x target (the machine was too slow)\n")
    relay.poll(log)
    assert seen["progress"] == [(60.0, "9.8x real time"), (120.0, "8.1x real time, GNSS off")]
    assert seen["warn"] == ["8.19x real time: missed the 10x target (the machine was too slow)"]
    assert len(seen["log"]) == 1 and "missed the 10x target" in seen["log"][0]


# ----------------------------------------------------------------- version, first run
def test_version_names_the_version_and_each_kernel() -> None:
    res = runner.invoke(app, ["--version"])
    assert res.exit_code == 0
    assert res.output.startswith("hilnav ")
    for kernel in first_run.KERNEL_FILES:
        assert f"{kernel}: " in res.output


def test_the_kernels_of_this_install_are_found() -> None:
    """The editable install of the test environment built every kernel."""
    assert first_run.missing_kernels() == []


def test_an_unbuilt_kernel_is_said_once_per_version(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    notice = first_run.kernel_notice(["sim._simkernel"])
    assert notice is not None
    assert "sim._simkernel" in notice and "gcc" in notice
    assert "pip install --force-reinstall --no-deps -e ." in notice
    assert first_run.kernel_notice(["sim._simkernel"]) is None
    assert first_run.kernel_notice([]) is None


def test_an_unwritable_cache_never_fails(tmp_path: Path, monkeypatch: pytest.MonkeyPatch
                                         ) -> None:
    blocked = tmp_path / "cache"
    blocked.write_text("a file where the folder should be")
    monkeypatch.delenv("XDG_CACHE_HOME", raising=False)
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    os.makedirs(tmp_path / "home")
    os.chmod(tmp_path / "home", 0o500)
    try:
        assert first_run.kernel_notice(["fusion._update"]) is not None
        monkeypatch.setenv("XDG_CACHE_HOME", str(blocked))
        assert first_run.kernel_notice(["fusion._update"]) is not None
    finally:
        os.chmod(tmp_path / "home", 0o700)


# --------------------------------------------------------------- autopilot's side hints
def test_the_autopilot_side_commands_are_ones_that_exist() -> None:
    from sim.flight_config import StartState

    start = StartState(lat_deg=46.5, lon_deg=7.25, heading_deg=90.0)
    command = ardupilot_command(start)
    assert "-l 46.5,7.25,0,90 " in command and "--home" not in command
    assert "--model JSON:127.0.0.1" in command and "--out udp:127.0.0.1:14550" in command
    assert ARDUPILOT_MAVLINK == "tcp:127.0.0.1:5762" and ARDUPILOT_MAVLINK in command
    assert "PX4_SYS_AUTOSTART=1030 PX4_SIM_MODEL=plane ./build/px4_sitl_default/bin/px4 -d" \
        in px4_command() and "none_" not in px4_command()


def test_up_warns_when_ardupilots_gnss_is_not_denied(tmp_path: Path) -> None:
    from scenarios.cli.up_autopilot import denial_warning
    from scenarios.cli.up_options import UpOptions

    base: dict[str, Any] = {"autopilot": "ardupilot", "gnss_off": ("10:5",), "out": tmp_path}
    warning = denial_warning(UpOptions(**base))
    assert warning is not None and "NOT denied" in warning and "--ardupilot-mavlink" in warning
    assert denial_warning(UpOptions(**base, ardupilot_mavlink=ARDUPILOT_MAVLINK)) is None
    assert denial_warning(UpOptions(autopilot="ardupilot", out=tmp_path)) is None


def test_side_by_side_does_not_claim_the_same_denial_when_it_was_not(
        capsys: pytest.CaptureFixture[str]) -> None:
    section = {"source": "ArduPilot", "outages_not_denied": [{"start_s": 10, "end_s": 15}]}
    output.print_autopilot({"autopilot": section})
    out = capsys.readouterr().out
    assert "same GNSS denial" not in out and "NOT denied" in out


@pytest.mark.parametrize(("args", "needle"), [
    (["--actuator-map", "m.yaml"], "--actuator-map is PX4's"),
    (["--ardupilot", "--actuator-map", "m.yaml"], "--actuator-map is PX4's"),
    (["--px4", "--servo-map", "m.yaml"], "--servo-map is ArduPilot's"),
    (["--ardupilot-mavlink", ARDUPILOT_MAVLINK], "--ardupilot-mavlink is ArduPilot's"),
])
def test_an_autopilot_option_without_its_autopilot_is_bad_input(
        tmp_path: Path, args: list[str], needle: str) -> None:
    res = runner.invoke(app, ["up", "--out", str(tmp_path), *args])
    assert res.exit_code == 2
    assert needle in res.output and "Traceback" not in res.output


# ----------------------------------------------------------------------- failures named
def test_run_prints_each_failure_and_exits_1_naming_them(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """GIVEN a run whose autopilot did not acknowledge the denial (its criteria passed), WHEN
    ``hilnav run`` ends, THEN it names that failure and exits 1."""
    import scenarios.runner
    from scenarios.runner import RunResult

    failure = "ArduPilot did not acknowledge SIM_GPS1_ENABLE=0 at 10.0 s on tcp:127.0.0.1:5762"

    def fake_run(scn: Any, out: Path, **_kw: Any) -> RunResult:
        summary = {"criteria": [{"name": "h_rmse", "ok": True, "value": 1.0, "limit": 5.0}],
                   "failures": [failure], "passed": False}
        return RunResult(summary, out, [])

    monkeypatch.setattr(scenarios.runner, "run_scenario", fake_run)
    scenario = Path(__file__).resolve().parents[2] / "scenarios" / "library" / "p1-5min-outage.yaml"
    res = runner.invoke(app, ["run", str(scenario), "--out", str(tmp_path), "--quiet"])
    assert res.exit_code == 1
    assert res.output.count(failure) == 2  # its own line, and the exit line naming it
    assert "criteria failed" not in res.output


def test_demo_writes_the_report_with_what_it_flew(tmp_path: Path) -> None:
    """GIVEN a short demo, WHEN it ends, THEN report.html is there like a run's, and its
    scorecard says what was flown (aircraft, plan, sensor presets, air)."""
    import json

    res = runner.invoke(app, ["demo", "--duration", "40", "--outage", "20:5", "--out",
                              str(tmp_path), "--imu", "tactical", "--quiet"])
    assert res.exit_code == 0, res.output
    assert "flying:" not in res.output
    setup = json.loads((tmp_path / "summary.json").read_text())["setup"]
    assert setup["aircraft"] == "c172x" and setup["plan"] == "racetrack"
    assert setup["sensors"]["imu"] == "tactical" and setup["turbulence"] == 0.0
    html = (tmp_path / "report.html").read_text()
    assert "c172x" in html and "tactical" in html
    assert html.count("data:image/png;base64,") == len(list(tmp_path.glob("*.png"))) >= 3


def test_compare_counts_every_seeds_flight_in_one_progress(tmp_path: Path) -> None:
    """GIVEN two seeds of a 20 s scenario with a GNSS outage, WHEN ``compare`` flies them,
    THEN one progress runs over both flights (40 s) and names the outage in each."""
    scenario = tmp_path / "s.yaml"
    scenario.write_text("name: cmp\nduration_s: 20\nsim_rate_hz: 100\nseed: 4\nevents:\n"
                        "  - {type: gnss_outage, at: 10, duration: 5}\n")
    res = runner.invoke(app, ["compare", str(scenario), "--out", str(tmp_path / "out"),
                              "--methods", "none", "--seeds", "2"])
    assert res.exit_code == 0, res.output
    lines = [ln for ln in res.output.splitlines() if ln.startswith("flying: ")]
    assert len(lines) == 10 and lines[-1].startswith("flying: 40/40 s simulated (100 %)")
    assert [ln for ln in lines if "gnss outage" in ln] == [lines[2], lines[7]]  # 12 s, 32 s
    quiet = runner.invoke(app, ["compare", str(scenario), "--out", str(tmp_path / "q"),
                                "--methods", "none", "--seeds", "1", "--quiet"])
    assert quiet.exit_code == 0 and "flying" not in quiet.output
