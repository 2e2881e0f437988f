"""The hilnav command line: recording, replay scorecard, exit codes, bad input.

GIVEN a user at the shell, WHEN they run a subcommand, THEN they get the files of the output
contract (docs/architecture.md) and exit 0 / 1 / 2 with one readable line on failure.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
from typer.testing import CliRunner

from hil.tlog import read_tlog
from scenarios.cli.app import app

runner = CliRunner()


def _run(*args: str) -> tuple[int, str]:
    res = runner.invoke(app, list(args))
    return res.exit_code, res.output


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (["--plan", "loop-the-loop"], "climb-descent, cruise, manoeuvre"),
        (["--aircraft", "sopwith"], "c172x"),
        (["--imu", "gold-plated"], "industrial-mems"),
        (["--imu-thermal", "bmi089"], "adis1646x, bmi088"),
        (["--gnss", "galileo-prs"], "modern"),
        (["--duration", "-5"], "duration"),
        (["--rate", "1000"], "rate_hz"),
        (["--gnss-off", "abc"], "START:DURATION"),
        (["--wind", "1,2"], "N,E,D"),
    ],
)
def test_sim_bad_input_is_one_line_and_exit_2(tmp_path: Path, args: list[str], needle: str) -> None:
    code, out = _run("sim", "record", str(tmp_path / "x.tlog"), "--duration", "5", *args)
    assert code == 2
    assert needle in out
    assert "Traceback" not in out
    assert len([ln for ln in out.splitlines() if ln.strip()]) == 1


def test_replay_bad_input(tmp_path: Path, short_flight_log: Path) -> None:
    code, out = _run("replay", str(tmp_path / "missing.tlog"), "--out", str(tmp_path))
    assert code == 2 and "no such log file" in out
    code, out = _run("replay", str(short_flight_log), "--out", str(tmp_path), "--bridge", "magic")
    assert code == 2 and "valid choices: none" in out
    code, out = _run("replay", str(short_flight_log), "--out", str(tmp_path), "--align", "up")
    assert code == 2 and "valid choices: auto, static, in-flight" in out
    assert len(out.strip().splitlines()) == 1


def test_sim_records_a_log_mavlogdump_reads(tmp_path: Path) -> None:
    log = tmp_path / "run.tlog"
    code, out = _run("sim", "record", str(log), "--duration", "20", "--seed", "3")
    assert code == 0, out
    dump = subprocess.run(
        [sys.executable, "-m", "pymavlink.tools.mavlogdump", "--types",
         "HIL_SENSOR,HIL_GPS,HIL_STATE_QUATERNION", "--format", "json", str(log)],
        capture_output=True, text=True, timeout=120, check=True,
    )
    types: dict[str, int] = {}
    for line in dump.stdout.splitlines():
        if line.startswith("{"):
            name = json.loads(line)["meta"]["type"]
            types[name] = types.get(name, 0) + 1
    # 200 Hz IMU, 5 Hz GNSS, 50 Hz truth over 20 s (the first GNSS fix is 0.1 s late)
    assert types["HIL_SENSOR"] == pytest.approx(4000, abs=2)
    assert types["HIL_GPS"] == pytest.approx(100, abs=2)
    assert types["HIL_STATE_QUATERNION"] == pytest.approx(1000, abs=2)


def test_same_seed_gives_identical_bytes(tmp_path: Path) -> None:
    paths = [tmp_path / "a.tlog", tmp_path / "b.tlog", tmp_path / "c.tlog"]
    for p, seed in zip(paths, (5, 5, 6), strict=True):
        code, out = _run("sim", "record", str(p), "--duration", "10", "--seed", str(seed),
                         "--turbulence", "0.3")
        assert code == 0, out
    a, b, c = (p.read_bytes() for p in paths)
    assert a == b
    assert a != c


def test_crash_keeps_the_log_and_exits_1(tmp_path: Path) -> None:
    plan = tmp_path / "dive.yaml"
    plan.write_text(
        "name: dive\nlegs:\n  - {kind: heading, heading_deg: 0, duration_s: 900, alt_m: -2000,"
        " climb_rate_mps: 8}\n"
    )
    log = tmp_path / "dive.tlog"
    code, out = _run("sim", "record", str(log), "--plan", str(plan), "--alt", "300",
                     "--rate", "50", "--duration", "300")
    assert code == 1
    assert "ground" in out and "kept" in out
    records = list(read_tlog(log))
    assert len(records) > 1000  # everything flown before the impact is on disk


def test_replay_writes_the_contract(tmp_path: Path, short_flight_log: Path) -> None:
    """GIVEN a recorded flight with GNSS off 120-150 s WHEN replayed THEN the scorecard finds
    the outage from the gap in HIL_GPS and scores it against the logged truth."""
    out = tmp_path / "replay"
    code, text = _run("replay", str(short_flight_log), "--out", str(out), "--settle", "30")
    assert code == 0, text
    s = json.loads((out / "summary.json").read_text())
    for key in ("scenario", "seed", "sim_duration_s", "wall_s", "realtime_factor", "bridge",
                "altitude", "outages", "gnss_on", "nees", "criteria", "passed"):
        assert key in s
    assert s["sim_duration_s"] == pytest.approx(180.0, abs=0.5)
    assert len(s["outages"]) == 1
    o = s["outages"][0]
    assert o["start_s"] == pytest.approx(120.0, abs=0.5)
    assert o["end_s"] == pytest.approx(150.0, abs=0.5)
    assert set(o["rmse"]) >= {"lat_deg", "lon_deg", "h_m", "vn_mps", "ve_mps", "vd_mps"}
    assert o["horizontal_error_m_at"]["10"] is not None
    on = s["gnss_on"]
    # an industrial MEMS IMU with a 1.5 m GNSS: metre-level position, sub-degree attitude
    assert on["horizontal_rmse_m"] < 3.0
    assert on["roll_rmse_deg"] < 0.5 and on["pitch_rmse_deg"] < 0.5
    assert s["health"]["filter"]["gnss_fused"] > 500
    for png in ("ground_track.png", "errors.png", "horizontal_vertical.png"):
        assert (out / png).stat().st_size > 10_000
    assert s["reference"]["source"] == "truth"
    assert s["settling"] == {"requested_s": 30.0, "applied_s": 30.0,
                             "span_s": pytest.approx(s["settling"]["span_s"]),
                             "scored_s": pytest.approx(s["settling"]["scored_s"]),
                             "warning": None}


def test_replay_gnss_off_cuts_a_recorded_flight(tmp_path: Path, short_flight_log: Path) -> None:
    """GIVEN the recorded flight (its own outage 120-150 s) WHEN replayed with --gnss-off
    40:20 THEN the fixes of 40-60 s are removed and a second outage is scored against truth."""
    out = tmp_path / "cut"
    code, text = _run("replay", str(short_flight_log), "--out", str(out), "--settle", "20",
                      "--gnss-off", "40:20")
    assert code == 0, text
    s = json.loads((out / "summary.json").read_text())
    assert s["gnss_off"]["fixes_removed"] > 50
    first, second = s["outages"]
    assert first["start_s"] == pytest.approx(40.0, abs=0.5)
    assert first["end_s"] == pytest.approx(60.0, abs=0.5)
    assert second["start_s"] == pytest.approx(120.0, abs=0.5)
    assert first["horizontal_error_m_at"]["10"] is not None


def test_list_json() -> None:
    code, out = _run("list", "--json")
    assert code == 0
    choices = json.loads(out)
    assert "c172x" in choices["aircraft"] and "c310" in choices["aircraft"]
    assert set(choices["plans"]) == {"cruise", "racetrack", "climb-descent", "survey", "manoeuvre"}
    assert {"consumer-mems", "industrial-mems", "tactical", "paper-p2"} <= set(choices["imu"])
    assert choices["imu_thermal"] == ["adis1646x", "bmi088", "icm20948", "icm42688p", "off"]
    assert choices["align"] == ["auto", "static", "in-flight"]


def test_check_command_reports_the_deployment_health() -> None:
    """GIVEN a running router with no fusion service WHEN `hilnav check` asks for the router
    THEN exit 0, for the fusion's liveliness token THEN exit 1 with one line saying what is
    missing, and a bad endpoint exits 2."""
    from hil.router import zenoh_router

    with zenoh_router() as endpoint:
        ok = CliRunner().invoke(app, ["check", "--connect", endpoint, "--timeout", "3"])
        assert ok.exit_code == 0, ok.output
        missing = CliRunner().invoke(app, ["check", "--connect", endpoint, "--alive",
                                           "--vehicle", "nobody", "--timeout", "1"])
        assert missing.exit_code == 1
        assert "alive" in missing.output and len(missing.output.strip().splitlines()) == 1
        bad_key = CliRunner().invoke(app, ["check", "--connect", endpoint, "--key", "a//b"])
        assert bad_key.exit_code == 2 and "Traceback" not in bad_key.output
    bad = CliRunner().invoke(app, ["check", "--connect", "not-an-endpoint"])
    assert bad.exit_code == 2


@pytest.mark.parametrize(
    ("content", "needle"),
    [(b"", "is empty"), (b"hello world\n", "no MAVLink frame"),
     (bytes(range(256)) * 20, "no MAVLink frame"), (b"\x00" * 8, "no MAVLink frame")],
)
def test_replay_names_what_a_bad_log_lacks(tmp_path: Path, content: bytes, needle: str) -> None:
    log = tmp_path / "bad.tlog"
    log.write_bytes(content)
    result = CliRunner().invoke(app, ["replay", str(log), "--out", str(tmp_path / "o")])
    assert result.exit_code == 2 and needle in result.output
    assert "Traceback" not in result.output and len(result.output.strip().splitlines()) == 1


def test_bad_output_paths_are_bad_input(tmp_path: Path, short_flight_log: Path) -> None:
    """GIVEN --out naming a file, a path under a file, or --record naming a folder THEN exit 2
    with one line, before anything runs."""
    afile = tmp_path / "afile"
    afile.write_text("x")
    cases = [
        (["replay", str(short_flight_log), "--out", str(afile)], "is a file"),
        (["replay", str(short_flight_log), "--out", str(afile / "sub")], "under the file"),
        (["replay", str(tmp_path), "--out", str(tmp_path / "o")], "is a folder"),
        (["sim", "record", str(tmp_path), "--duration", "1"], "is a folder"),
        (["schema", "--out", str(tmp_path)], "is a folder"),
    ]
    for args, needle in cases:
        result = CliRunner().invoke(app, args)
        assert result.exit_code == 2, (args, result.output)
        assert needle in result.output and "Traceback" not in result.output, args


def test_a_truncated_log_is_scored_and_says_so(tmp_path: Path, short_flight_log: Path) -> None:
    """GIVEN the recording cut in the middle of a record WHEN replayed THEN it is scored (exit
    0), a warning says it is damaged, and summary.json's input section records the cut."""
    data = short_flight_log.read_bytes()
    cut = tmp_path / "cut.tlog"
    cut.write_bytes(data[: len(data) * 2 // 3 + 5])
    result = CliRunner().invoke(app, ["replay", str(cut), "--out", str(tmp_path / "o"),
                                      "--settle", "20"])
    assert result.exit_code == 0, result.output
    assert "truncated" in result.output
    s = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert s["input"]["truncated"] is True and s["input"]["frames"] > 10_000
    assert s["sim_duration_s"] < 130.0
    whole = CliRunner().invoke(app, ["replay", str(short_flight_log), "--out",
                                     str(tmp_path / "w"), "--settle", "20"])
    assert whole.exit_code == 0 and "warning" not in whole.output
    w = json.loads((tmp_path / "w" / "summary.json").read_text())
    assert w["input"] == {"format": "tlog", "records": w["input"]["records"],
                          "frames": w["input"]["frames"], "bad_frames": 0, "truncated": False,
                          "skipped_bytes": 0}


def test_a_bad_airspeed_choice_is_bad_input(tmp_path: Path, short_flight_log: Path) -> None:
    """GIVEN ``--airspeed`` with an unknown choice on a command that runs the filter THEN exit 2
    with one line naming the valid choices, before anything runs."""
    for args in (["replay", str(short_flight_log), "--out", str(tmp_path / "o")],
                 ["fusion", "--duration", "0.1"]):
        result = CliRunner().invoke(app, [*args, "--airspeed", "sometimes"])
        assert result.exit_code == 2, (args, result.output)
        assert "on, off, synthetic" in result.output and "Traceback" not in result.output
        assert len(result.output.strip().splitlines()) == 1
