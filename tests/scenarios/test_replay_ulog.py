"""``hilnav replay`` of PX4 ULog files: scored against the autopilot's own estimate (EKF2),
GNSS cut from a real flight, settling fitted to a short log, and bad logs named in one line.

Logs: PX4's public sample logs in ``../shared/logs/px4/`` (pyulog's test data, read-only) and
files crafted from them by dropping topics or cutting time (:mod:`tests.helpers.ulog_bytes`).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest
from typer.testing import CliRunner

from scenarios.cli.app import app
from tests.helpers.ulog_bytes import filter_ulog

LOGS = Path(__file__).resolve().parents[2].parent / "shared" / "logs" / "px4"
EVENTS = LOGS / "sample_px4_events.ulg"
SMALL = LOGS / "sample_log_small.ulg"
TAGGED = LOGS / "sample_logging_tagged_and_default_params.ulg"

Replayed = tuple[dict[str, Any], str]  # summary.json, stderr

pytestmark = pytest.mark.skipif(not EVENTS.is_file(), reason=f"sample logs not found in {LOGS}")


def _replay(log: Path, out: Path, *args: str) -> tuple[int, str, str]:
    res = CliRunner().invoke(app, ["replay", str(log), "--out", str(out), *args])
    return res.exit_code, res.stdout, res.stderr


def _one_line(text: str) -> str:
    lines = [ln for ln in text.splitlines() if ln.strip()]
    assert len(lines) == 1, text
    assert "Traceback" not in text
    return lines[0]


@pytest.fixture(scope="module")
def events_cut(tmp_path_factory: pytest.TempPathFactory) -> Replayed:
    """The SITL hop (31 s) replayed with GNSS cut for 8 s from 18 s and the default settle."""
    out = tmp_path_factory.mktemp("events")
    code, stdout, stderr = _replay(EVENTS, out, "--gnss-off", "18:8")
    assert code == 0, stdout + stderr
    return json.loads((out / "summary.json").read_text()), stderr


def test_ulog_is_scored_against_the_autopilots_estimate(events_cut: Replayed) -> None:
    """GIVEN a PX4 log at rest then hopping WHEN replayed THEN the filter aligns at rest (WMM
    heading) and the scorecard compares it with EKF2, labelled as a reference, not truth."""
    s, _ = events_cut
    ref = s["reference"]
    assert ref["source"] == "PX4 EKF2" and "truth" not in json.dumps(ref)
    assert ref["position"] and ref["height"] and ref["velocity"] and ref["attitude"]
    assert s["alignment"]["method"] == "static_mag" and s["alignment"]["date_known"]
    assert s["alignment"]["decimal_year"] == pytest.approx(2024.21, abs=0.01)  # 2024-03-18
    assert "warning" not in s["alignment"]  # SITL's magnetometer agrees with the WMM
    on = s["gnss_on"]
    # SITL sensors are clean: both filters sit on the same fixes to decimetres, level to a
    # fraction of a degree; yaw within the WMM's declination uncertainty (~0.5 deg) and more
    assert on["horizontal_rmse_m"] < 0.5
    assert on["vertical_rmse_m"] < 2.0
    assert on["roll_rmse_deg"] < 0.5 and on["pitch_rmse_deg"] < 0.5
    assert on["yaw_rmse_deg"] < 2.0
    assert s["input"]["format"] == "ulog" and s["input"]["ignored_topics"] > 0


def test_gnss_off_scores_an_outage_against_the_reference(events_cut: Replayed) -> None:
    s, _ = events_cut
    assert s["gnss_off"]["fixes_removed"] > 100  # ~19 Hz receiver, 8 s
    [outage] = s["outages"]
    assert outage["start_s"] == pytest.approx(18.0, abs=0.2)
    assert outage["end_s"] == pytest.approx(26.0, abs=0.2)
    assert 0.0 < outage["horizontal_max_m"] < 10.0


def test_settle_longer_than_the_log_is_fitted_and_said(events_cut: Replayed) -> None:
    s, stderr = events_cut
    st = s["settling"]
    assert st["requested_s"] == 60.0 and 0.0 < st["applied_s"] < 60.0
    assert st["scored_s"] > 0.0 and st["warning"]
    assert "--settle 60 s is longer than the log allows" in stderr
    assert all(v is not None for v in s["gnss_on"].values())


def test_a_reference_without_global_position_is_said(tmp_path: Path) -> None:
    """GIVEN a hardware log whose EKF2 never had a global position WHEN replayed THEN it scores
    attitude, says the position metrics are null and why, and flags the magnetometer that
    disagrees with the WMM."""
    code, stdout, stderr = _replay(SMALL, tmp_path, "--settle", "1")
    assert code == 0, stdout + stderr
    s = json.loads((tmp_path / "summary.json").read_text())
    assert not s["reference"]["position"] and "no global position" in s["reference"]["warning"]
    assert s["gnss_on"]["horizontal_rmse_m"] is None
    assert s["gnss_on"]["roll_rmse_deg"] is not None
    assert s["settling"]["warning"] is None and s["settling"]["applied_s"] == 1.0
    assert "magnetometer disagrees" in s["alignment"]["warning"]
    assert "no global position" in stderr and "magnetometer disagrees" in stderr
    assert s["input"]["logger_dropouts"] == 1 and "logger dropped data 1 times" in stderr


def test_gnss_only_at_the_very_end_is_scored_over_what_there_is(tmp_path: Path) -> None:
    """GIVEN PX4's 11 s SITL log whose receiver reaches a 3-D fix only in its last 1.5 s and
    whose EKF2 has a height but no horizontal position yet WHEN replayed THEN the filter,
    aligned at rest before the fix, is scored over the ~1 s of overlap: height and attitude,
    with the settling shortened and said."""
    code, stdout, stderr = _replay(TAGGED, tmp_path)
    assert code == 0, stdout + stderr
    s = json.loads((tmp_path / "summary.json").read_text())
    ref = s["reference"]
    assert ref["height"] and not ref["position"] and not ref["velocity"]
    assert s["gnss_on"]["horizontal_rmse_m"] is None
    assert s["gnss_on"]["vertical_rmse_m"] < 1.0
    assert s["gnss_on"]["roll_rmse_deg"] < 0.5 and s["gnss_on"]["pitch_rmse_deg"] < 0.5
    assert 0.0 < s["settling"]["span_s"] < 2.0 and s["settling"]["warning"]
    assert "longer than the log allows" in stderr


def test_a_forced_alignment_that_cannot_happen_says_why(tmp_path: Path) -> None:
    """GIVEN the tagged log (3-D fix only in its last 1.5 s, single SITL gyro spikes) WHEN
    replayed with --align static THEN the 2-s static window never completes after the fix:
    exit 2, one line with the fixes' span and the way out."""
    code, stdout, stderr = _replay(TAGGED, tmp_path, "--align", "static")
    assert code == 2
    line = _one_line(stdout + stderr)
    assert "alignment not reached (3-D fixes from 9.3 to 10.8 s" in line
    assert "try --align auto" in line


@pytest.mark.parametrize(
    ("crafted", "needle"),
    [
        ({"drop_topics": {"sensor_combined"}}, "no IMU messages"),
        ({"drop_topics": {"vehicle_gps_position", "sensor_gps"}}, "no position source"),
        ({"until_s": 9.0}, "GNSS never valid (146 x fix type 0, 11 x fix type 2"),
        ({"drop_topics": {"vehicle_magnetometer"}},
         "alignment not reached: the vehicle never moved"),
        ({"drop_topics": {"vehicle_attitude"}}, "no reference"),
    ],
)
def test_a_log_that_lacks_something_says_what(tmp_path: Path, crafted: dict[str, Any],
                                              needle: str) -> None:
    log = filter_ulog(EVENTS, tmp_path / "crafted.ulg", **crafted)
    code, stdout, stderr = _replay(log, tmp_path / "out")
    assert code == 2
    assert needle in _one_line(stdout + stderr)


def test_not_a_ulog_is_one_line(tmp_path: Path) -> None:
    bad = tmp_path / "flight.ulg"
    bad.write_bytes(b"not a log at all" * 20)
    code, stdout, stderr = _replay(bad, tmp_path / "out")
    assert code == 2
    assert "not a PX4 ULog" in _one_line(stdout + stderr)
    magic_only = tmp_path / "header.ulg"
    magic_only.write_bytes(EVENTS.read_bytes()[:200])  # the header and nothing else
    code, stdout, stderr = _replay(magic_only, tmp_path / "out2")
    assert code == 2
    assert "a damaged ULog with no readable sensor data" in _one_line(stdout + stderr)


@pytest.mark.parametrize(("args", "needle"), [
    (["--gnss-off", "soon"], "START:DURATION"),
    (["--gnss-off", "10:0"], "duration > 0"),
    (["--settle", "-1"], "--settle must be >= 0"),
])
def test_bad_options_are_one_line(tmp_path: Path, args: list[str], needle: str) -> None:
    code, stdout, stderr = _replay(EVENTS, tmp_path, *args)
    assert code == 2
    assert needle in _one_line(stdout + stderr)
