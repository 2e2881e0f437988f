"""The autopilot's estimate recorded from its telemetry (hil.autopilot.telemetry) and scored
with hilnav's scorer (scenarios.autopilot_summary): real MAVLink 2 bytes over loopback UDP,
the estimate being a real JSBSim flight's truth with a known error."""

from __future__ import annotations

import math
import time

import numpy as np
import pytest

from hil.autopilot.telemetry import AutopilotTelemetry
from hil.codec import mavlink2
from hil.link import LinkRole, MavlinkLink
from hil.pipeline import SimChain, SimSetup
from hil.tracks import Track, truth_track
from scenarios.autopilot_summary import autopilot_section
from scenarios.metrics import Window
from sim.samples import Truth
from tests.helpers.autopilot_telemetry import LONG_TEXT_CHUNKS, EstimateSender

OUTAGE = (20.0, 40.0)
OFFSET_M = 30.0
YAW_DEG = 2.0


@pytest.fixture(scope="module")
def truths() -> list[Truth]:
    setup = SimSetup.build(duration_s=60.0, rate_hz=100.0, seed=5)
    with SimChain(setup) as chain:
        return [step.truth for step in chain.steps()]


def _wait(cond: object, timeout_s: float = 10.0) -> None:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if cond():  # type: ignore[operator]
            return
        time.sleep(0.02)


@pytest.fixture(scope="module")
def recorded(truths: list[Truth]) -> AutopilotTelemetry:
    tel = AutopilotTelemetry("udpin:127.0.0.1:0", rate_hz=10.0).start()
    port = tel.local_address[1]
    sender = EstimateSender(f"udpout:127.0.0.1:{port}", offset_north_m=OFFSET_M,
                            windows=[OUTAGE], yaw_offset_deg=YAW_DEG)
    try:
        for k, truth in enumerate(truths):
            sender.send_truth(truth)
            if k % 50 == 0:
                time.sleep(0.002)  # let the receiver drain: loopback UDP, not a queue
        _wait(lambda: tel.snapshot()["positions"] >= sender.sent)
        _wait(lambda: tel.counters()["interval_acks_ok"] >= 5, 3.0)
    finally:
        tel.stop()
        sender.close()
    assert sender.sent == 600
    return tel


def test_the_recorder_keeps_every_report_on_the_simulated_time_axis(
        recorded: AutopilotTelemetry, truths: list[Truth]) -> None:
    c = recorded.counters()
    assert c["position_reports"] == c["attitude_reports"] == c["estimator_status"] == 600
    assert c["rejected_reports"] == 0 and c["heartbeats"] >= 1
    # SET_MESSAGE_INTERVAL asked once per message once the heartbeat was heard, all acked
    assert c["interval_requests"] == 5 == c["interval_acks_ok"]
    track = recorded.estimate_track()
    # time_boot_ms * 1000 is the time_us of the truth each report was made from (10 Hz)
    truth_us = {t.time_us for t in truths}
    assert all(round(t * 1e6) in truth_us for t in track.time_s)
    assert track.time_s.size == 600
    assert np.diff(track.time_s) == pytest.approx(np.full(599, 0.1), abs=1e-9)


def test_the_scorecard_measures_the_known_error_of_the_autopilot_estimate(
        recorded: AutopilotTelemetry, truths: list[Truth]) -> None:
    truth = truth_track(truths)
    scored = autopilot_section(
        "PX4", recorded.estimate_track(), truth, [Window(*OUTAGE)],
        link={"telemetry": recorded.url}, counters=recorded.counters(), stalled=None,
        connected=True, health=recorded.health(), settle_s=5.0)
    s = scored.section
    assert s["source"] == "PX4" and s["nees"] is None
    (outage,) = s["outages"]
    # the estimate was 30 m north of the truth through the outage: every figure says 30 m
    # (degE7 and mm on the wire: ~1 cm)
    assert outage["horizontal_rmse_m"] == pytest.approx(OFFSET_M, abs=0.02)
    assert outage["horizontal_max_m"] == pytest.approx(OFFSET_M, abs=0.02)
    assert outage["horizontal_error_m_at"]["10"] == pytest.approx(OFFSET_M, abs=0.02)
    assert outage["cep50_m"] == pytest.approx(OFFSET_M, abs=0.02)
    assert outage["vertical_rmse_m"] < 0.01
    on = s["gnss_on"]
    assert on["horizontal_rmse_m"] < 0.02 and on["vertical_rmse_m"] < 0.01
    # ATTITUDE is float32 rad: the 2 deg yaw offset comes back to 1e-4 deg
    assert on["yaw_rmse_deg"] == pytest.approx(YAW_DEG, abs=1e-4)
    assert on["roll_rmse_deg"] < 1e-4 and on["pitch_rmse_deg"] < 1e-4


def test_the_health_records_mode_failsafe_and_the_lost_position(
        recorded: AutopilotTelemetry) -> None:
    h = recorded.health()
    assert h["autopilot_type"] == int(mavlink2.MAV_AUTOPILOT_PX4) and h["armed_ever"]
    assert h["modes"][0]["custom_mode"] == 4 << 16
    assert h["failsafes"][0]["text"] == "Failsafe enabled: no global position"
    assert h["failsafes"][0]["time_s"] == pytest.approx(OUTAGE[0], abs=0.11)
    est = h["estimator"]
    assert est["pos_horiz_abs_lost_s"] == [pytest.approx(OUTAGE[0], abs=0.11)]
    assert est["pos_horiz_abs_regained_s"] == [pytest.approx(OUTAGE[1], abs=0.11)]
    assert est["max"]["pos_horiz_accuracy_m"] == pytest.approx(1.5)
    # AND the mission item flown at each change, on the autopilot's time
    assert [m["seq"] for m in h["mission_current"]] == [1, 2, 3]
    assert [m["time_s"] for m in h["mission_current"][1:]] == [
        pytest.approx(t, abs=0.11) for t in OUTAGE]


def test_px4_is_asked_only_for_what_it_streams_and_refuses_nothing(
        recorded: AutopilotTelemetry) -> None:
    # GIVEN a PX4 that refuses a message interval for EKF_STATUS_REPORT (it has none)
    c = recorded.counters()
    # THEN it was asked for its estimate, ESTIMATOR_STATUS and its mission item, never for
    # EKF_STATUS_REPORT
    assert c["interval_requests"] == 5 == c["interval_acks_ok"]
    assert c["interval_acks_refused"] == 0


def test_a_chunked_statustext_is_one_text_at_an_exact_time(
        recorded: AutopilotTelemetry) -> None:
    # GIVEN a long STATUSTEXT in two MAVLink 2 chunks, "failsafe" split between them
    h = recorded.health()
    texts = [t["text"] for t in h["statustext"]]
    # THEN it is one text, and a failsafe
    assert "".join(LONG_TEXT_CHUNKS) in texts
    assert not set(LONG_TEXT_CHUNKS) & set(texts)
    assert "".join(LONG_TEXT_CHUNKS) in [t["text"] for t in h["failsafes"]]
    # AND every time is the autopilot's millisecond as the nearest float, not float noise
    times = [t["time_s"] for t in h["statustext"] + h["modes"]]
    times += [f["time_s"] for f in h["estimator"]["flags_changes"]]
    assert times and all(t == round(t, 3) for t in times)


def test_positions_before_the_autopilots_first_fix_are_not_its_estimate(
        truths: list[Truth]) -> None:
    # GIVEN an autopilot that reports lat/lon 0/0 at -1000 m for its first 2 s (no fix yet)
    tel = AutopilotTelemetry("udpin:127.0.0.1:0", rate_hz=None).start()
    sender = EstimateSender(f"udpout:127.0.0.1:{tel.local_address[1]}", no_fix_before_s=2.0)
    try:
        for truth in truths[:500]:
            sender.send_truth(truth)
        _wait(lambda: tel.counters()["position_reports"]
              + tel.counters()["positions_before_fix"] >= sender.sent)
    finally:
        tel.stop()
        sender.close()
    track = tel.estimate_track()
    # THEN its track starts at its first position and holds no 0/0, no -1000 m
    assert tel.estimate_from_s == pytest.approx(2.0, abs=0.11) == track.time_s[0]
    assert np.all(np.degrees(track.lat_rad) > 40.0) and np.all(track.alt_m > 0.0)
    # (the report at 2.0 s may still follow a status without a position: one more dropped)
    assert 20 <= tel.counters()["positions_before_fix"] <= 21


def test_bad_reports_are_counted_and_an_empty_recording_scores_nothing() -> None:
    tel = AutopilotTelemetry("udpin:127.0.0.1:0", rate_hz=None).start()
    role = LinkRole(system_id=7, component_id=1, mav_type=1,
                    autopilot=int(mavlink2.MAV_AUTOPILOT_ARDUPILOTMEGA))
    with MavlinkLink(f"udpout:127.0.0.1:{tel.local_address[1]}", role) as link:
        link.send_message(mavlink2.MAVLink_attitude_message(1000, math.nan, 0, 0, 0, 0, 0))
        link.send_message(mavlink2.MAVLink_global_position_int_message(
            1000, 91 * 10**7, 0, 0, 0, 0, 0, 0, 0))
        _wait(lambda: tel.counters()["rejected_reports"] >= 2, 5.0)
    tel.stop()
    assert tel.counters()["rejected_reports"] == 2
    with pytest.raises(ValueError, match="nothing to score"):
        tel.estimate_track()
    scored = autopilot_section("ArduPilot", None, _empty_truth(), [], link={}, counters={},
                               stalled="ArduPilot sent no controls", connected=True,
                               problem="no reports")
    assert scored.section["outages"] is None and scored.errors is None
    assert scored.section["stalled"] == "ArduPilot sent no controls"


def _empty_truth() -> Track:
    z = np.zeros(2)
    return Track(np.array([0.0, 1.0]), z, z, z, np.zeros((2, 3)), np.zeros((2, 3)))
