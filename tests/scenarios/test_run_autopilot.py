"""``hilnav run`` with an autopilot in the loop (scenarios.runner): the one autopilot loop
flies, hilnav's fusion takes every frame, the autopilot's estimate arrives as real MAVLink 2 over
loopback UDP and both are scored side by side.

The backend here is an in-process test double of an autopilot (a wings-level roll loop on the
truth it is sent; the other controls hold the trim), whose telemetry is the truth plus a known
30 m north error inside the GNSS outage (tests.helpers.autopilot_telemetry): the protocol
backends and their peers are tested on their own branches; this tests the run's wiring and the
scorecard numbers.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Sequence
from pathlib import Path

import pytest

from hil.autopilot import DenialStep
from hil.pipeline import SimStep
from scenarios.cli.up import free_udp_port
from scenarios.runner import AutopilotAbsent, run_scenario
from scenarios.schema import load_scenario
from tests.helpers.autopilot_telemetry import EstimateSender

OUTAGE = (70.0, 90.0)
OFFSET_M = 30.0


class _Autopilot:
    name = "PX4"

    def __init__(self, telemetry_url: str, *, silent_after_s: float | None = None,
                 connects: bool = True, dive_after_s: float | None = None,
                 denial: tuple[DenialStep, ...] | None = None) -> None:
        self.dive_after_s = dive_after_s
        self._denial = denial
        self.sender = EstimateSender(telemetry_url, offset_north_m=OFFSET_M, windows=[OUTAGE])
        self.silent_after_s = silent_after_s
        self.connects = connects
        self.time_s = 0.0
        self.roll_rad = self.p_rps = self.integral = 0.0
        self.closed = False

    def wait_connected(self, timeout_s: float, stop: threading.Event) -> bool:
        return self.connects

    def controls(self, timeout_s: float) -> Sequence[float] | None:
        if self.silent_after_s is not None and self.time_s >= self.silent_after_s:
            return None
        if self.dive_after_s is not None and self.time_s >= self.dive_after_s:
            return [0.0, -1.0, 0.0, 0.0]  # full nose down, engine off: into the ground
        self.integral += self.roll_rad * 0.01
        return [max(-0.3, min(0.3, -0.8 * self.roll_rad - 0.3 * self.p_rps
                              - 0.8 * self.integral))]

    def send(self, step: SimStep) -> None:
        t = step.truth
        self.time_s = t.time_us * 1e-6
        w, x, y, z = (float(v) for v in t.q_nb)
        self.roll_rad = math.atan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
        self.p_rps = float(t.omega_b_rps[0])
        self.sender.send_truth(t)

    def counters(self) -> dict[str, int]:
        return {"telemetry_sent": self.sender.sent}

    def problems(self) -> list[str]:
        return [f"{d.name} = {d.value:g} not acknowledged on tcp:127.0.0.1:5760"
                for d in self._denial or () if not d.took]

    def denial(self) -> list[DenialStep] | None:
        return None if self._denial is None else list(self._denial)

    def close(self) -> None:
        self.closed = True
        self.sender.close()


def _scenario(tmp_path: Path, port: int, *, stall_timeout_s: float = 5.0) -> Path:
    path = tmp_path / "ap.yaml"
    path.write_text(f"""
name: ap-test
duration_s: 200
sim_rate_hz: 100
seed: 4
autopilot:
  kind: px4
  telemetry: udpin:127.0.0.1:{port}
  connect_timeout_s: 5
  stall_timeout_s: {stall_timeout_s}
events:
  - {{type: gnss_outage, at: {OUTAGE[0]}, duration: {OUTAGE[1] - OUTAGE[0]}}}
""")
    return path


def test_run_scores_the_autopilot_estimate_beside_hilnavs(tmp_path: Path) -> None:
    port = free_udp_port()
    scn = load_scenario(_scenario(tmp_path, port))
    autopilot = _Autopilot(f"udpout:127.0.0.1:{port}")
    result = run_scenario(scn, tmp_path / "out", backend=autopilot)
    s = result.summary
    ap = s["autopilot"]
    assert autopilot.closed
    assert ap["source"] == "PX4" and ap["connected"] and ap["stalled"] is None
    assert ap["problem"] is None and ap["nees"] is None
    # both scored over the same outage, found from the gaps of the one sensor stream
    (mine,) = s["outages"]
    (theirs,) = ap["outages"]
    assert (theirs["start_s"], theirs["end_s"]) == (mine["start_s"], mine["end_s"])
    # the autopilot's estimate was 30 m north through the outage (degE7 / mm on the wire)
    assert theirs["horizontal_max_m"] == pytest.approx(OFFSET_M, abs=0.02)
    assert theirs["horizontal_error_m_at"]["10"] == pytest.approx(OFFSET_M, abs=0.02)
    assert ap["gnss_on"]["horizontal_rmse_m"] < 0.02
    assert ap["counters"]["telemetry_position_reports"] == autopilot.sender.sent
    assert ap["counters"]["steps"] == 20000
    assert ap["health"]["estimator"]["pos_horiz_abs_lost_s"] == [
        pytest.approx(OUTAGE[0], abs=0.11)]
    # hilnav's own figures are there as in any run; the report shows both
    assert s["gnss_on"]["horizontal_rmse_m"] > 0 and s["passed"]
    assert "Both estimates on one scorecard" in (tmp_path / "out" / "report.html").read_text()
    assert (tmp_path / "out" / "autopilot_side_by_side.png").stat().st_size > 10_000
    assert (tmp_path / "out" / "run.tlog").stat().st_size > 0


def test_a_stalled_autopilot_fails_the_run_and_the_scorecard_says_so(tmp_path: Path) -> None:
    port = free_udp_port()
    scn = load_scenario(_scenario(tmp_path, port, stall_timeout_s=0.2))
    autopilot = _Autopilot(f"udpout:127.0.0.1:{port}", silent_after_s=100.0)
    result = run_scenario(scn, tmp_path / "out", backend=autopilot, reports=False)
    ap = result.summary["autopilot"]
    assert ap["stalled"] is not None and "100.00 s" in ap["stalled"]
    assert not result.summary["passed"]
    assert result.summary["sim_duration_s"] == pytest.approx(100.0, abs=0.02)


def test_an_autopilot_that_never_connects_ends_the_run(tmp_path: Path) -> None:
    port = free_udp_port()
    scn = load_scenario(_scenario(tmp_path, port))
    autopilot = _Autopilot(f"udpout:127.0.0.1:{port}", connects=False)
    with pytest.raises(AutopilotAbsent, match="PX4 did not connect within 5 s"):
        run_scenario(scn, tmp_path / "out", backend=autopilot, reports=False)
    assert autopilot.closed


def test_a_flight_that_ends_early_is_scored_as_far_as_it_flew(tmp_path: Path) -> None:
    # GIVEN an autopilot that dives into the ground from 20 s, before the outage at 70 s
    port = free_udp_port()
    path = _scenario(tmp_path, port)
    path.write_text(path.read_text() + "  - {type: baro_glitch, at: 10, duration: 150, "
                    "offset_hpa: 2}\n")
    scn = load_scenario(path)
    autopilot = _Autopilot(f"udpout:127.0.0.1:{port}", dive_after_s=20.0)
    # WHEN the run is scored, with its reports
    result = run_scenario(scn, tmp_path / "out", backend=autopilot)
    s = result.summary
    end = s["sim_duration_s"]
    assert end < OUTAGE[0]
    # THEN it failed, saying why, and its summary was written
    assert not s["passed"] and (tmp_path / "out" / "summary.json").is_file()
    assert len(s["failures"]) == 1 and s["failures"][0].startswith("the flight ended early")
    # AND the outage that never began is listed as not reached
    assert [(e["type"], e["start_s"]) for e in s["events_not_reached"]] == [
        ("gnss_outage", OUTAGE[0])]
    # AND the glitch it cut short is scored up to the end, and marked so
    (glitch,) = s["events"]
    assert glitch["type"] == "baro_glitch" and glitch["clipped"]
    assert glitch["planned_end_s"] == 160.0 and glitch["end_s"] <= end
    assert s["autopilot"]["events_not_reached"] == s["events_not_reached"]
    assert (tmp_path / "out" / "report.html").is_file()


def test_a_denial_the_autopilot_did_not_take_fails_the_run_and_is_no_outage(
        tmp_path: Path) -> None:
    # GIVEN an autopilot that simulates its own GNSS and never acknowledged the step that
    # would have switched it off at the outage
    port = free_udp_port()
    scn = load_scenario(_scenario(tmp_path, port))
    denial = (DenialStep(OUTAGE[0], "SIM_GPS1_ENABLE", 0.0, "unacknowledged"),
              DenialStep(OUTAGE[1], "SIM_GPS1_ENABLE", 1.0, "unacknowledged"))
    autopilot = _Autopilot(f"udpout:127.0.0.1:{port}", denial=denial)
    result = run_scenario(scn, tmp_path / "out", reports=False, backend=autopilot)
    s = result.summary
    # THEN the run failed with a sentence naming the parameter and the port
    assert not s["passed"]
    assert any("SIM_GPS1_ENABLE = 0" in f and "tcp:127.0.0.1:5760" in f for f in s["failures"])
    # AND the window is hilnav's outage, but not one of the autopilot's
    (mine,) = s["outages"]
    ap = s["autopilot"]
    assert ap["outages"] == []
    assert ap["outages_not_denied"] == [{"start_s": mine["start_s"], "end_s": mine["end_s"]}]
    assert [d["status"] for d in ap["denial"]] == ["unacknowledged", "unacknowledged"]


def test_the_px4_library_scenario_flies_the_standard_planes_actuator_map() -> None:
    # GIVEN the library's PX4 scenario, read from where the installed package keeps it
    from importlib.resources import files

    from hil.autopilot.actuators import ActuatorMap

    library = Path(str(files("scenarios") / "library"))
    scn = load_scenario(library / "px4-fixed-wing-gnss-outage.yaml")
    path = scn.autopilot_path(scn.autopilot.actuator_map)
    # THEN its actuator map is PX4's standard plane, shipped in the library's package data
    assert path is not None and path.is_file()
    assert path.resolve().parent == (library / "autopilot").resolve()
    standard = ActuatorMap.load(path)
    assert standard.channels != ActuatorMap.default().channels
    # AND the docs' copy is that same file, not a second definition
    docs = Path(__file__).resolve().parents[2] / "docs" / "autopilot" / "px4-standard-plane.yaml"
    assert docs.resolve() == path.resolve()
