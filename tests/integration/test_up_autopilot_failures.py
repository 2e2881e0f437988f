"""``hilnav up`` with an autopilot that did not take the scenario's GNSS denial: the live
scorecard names it in ``failures`` and ``up`` exits 1 naming it.

The autopilot is the in-process test double of tests/scenarios/test_run_autopilot.py (a roll
loop on the truth it is sent, its estimate as MAVLink telemetry over loopback), given to
:func:`scenarios.cli.up.run_up` as its backend; the fusion service is a real child process.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import pytest
from typer.testing import CliRunner

from hil.autopilot import DenialStep
from scenarios.cli.app import app
from scenarios.cli.up import UpOptions, free_udp_port, run_up
from scenarios.cli.up_options import FUSION_IDLE_EXIT_S, fusion_idle_exit_s
from tests.scenarios.test_run_autopilot import _Autopilot


def test_an_unacknowledged_denial_is_a_failure_of_the_live_scorecard(tmp_path: Path) -> None:
    # GIVEN an autopilot that never acknowledged the step switching its GNSS off at 70 s
    port = free_udp_port()
    denial = (DenialStep(70.0, "SIM_GPS1_ENABLE", 0.0, "unacknowledged"),
              DenialStep(90.0, "SIM_GPS1_ENABLE", 1.0, "unacknowledged"))
    autopilot = _Autopilot(f"udpout:127.0.0.1:{port}", denial=denial)
    options = UpOptions(autopilot="px4", duration_s=120.0, gnss_off=("70:20",), monitor=False,
                        autopilot_telemetry=f"udpin:127.0.0.1:{port}", connect_timeout_s=5.0,
                        stall_timeout_s=5.0, out=tmp_path / "up")
    said: list[str] = []
    progress: list[float] = []
    # WHEN up flies with it
    summary = run_up(options, log=said.append, backend=autopilot,
                     progress=lambda t_s, _info: progress.append(t_s))
    # THEN the scorecard failed, naming the parameter, and the flight's progress was told
    assert summary is not None and not summary["passed"]
    assert any("SIM_GPS1_ENABLE = 0" in f for f in summary["failures"])
    assert progress and max(progress) >= 100.0
    assert any(line.startswith("now start     PX4 SITL") for line in said)
    # AND the fusion scored the whole flight (it waits out the autopilot's pauses)
    assert not [line for line in said if "the live scorecard covers" in line], said
    assert summary["sim_duration_s"] > 115.0


def test_up_prints_each_failure_and_exits_1(tmp_path: Path,
                                            monkeypatch: pytest.MonkeyPatch) -> None:
    import scenarios.cli.up

    failure = "SIM_GPS1_ENABLE = 0 not acknowledged on tcp:127.0.0.1:5762"

    def fake_run_up(options: UpOptions, **_kw: Any) -> dict[str, Any]:
        return {"passed": False, "failures": [failure],
                "autopilot": {"source": "ArduPilot", "connected": True, "stalled": None}}

    monkeypatch.setattr(scenarios.cli.up, "run_up", fake_run_up)
    res = CliRunner().invoke(app, ["up", "--ardupilot", "--duration", "30", "--out",
                                   str(tmp_path), "--quiet"])
    assert res.exit_code == 1
    assert res.output.count(failure) == 2  # its own line and the exit line


class _PausingAutopilot(_Autopilot):
    """Stops sending controls once, at 30 s of its clock, for ``pause_s`` wall seconds (shorter
    than the stall timeout: as ArduPilot does while it reboots a parameter or arms)."""

    def __init__(self, telemetry_url: str, pause_s: float) -> None:
        super().__init__(telemetry_url)
        self.pause_s = pause_s
        self.paused = False

    def controls(self, timeout_s: float) -> Sequence[float] | None:
        if not self.paused and self.time_s >= 30.0:
            self.paused = True
            time.sleep(self.pause_s)
        return super().controls(timeout_s)


def test_a_pause_of_the_autopilot_does_not_cut_the_live_scorecard(tmp_path: Path) -> None:
    # GIVEN an autopilot pausing longer than the fusion's idle exit of a run without one
    port = free_udp_port()
    autopilot = _PausingAutopilot(f"udpout:127.0.0.1:{port}", FUSION_IDLE_EXIT_S + 1.5)
    options = UpOptions(autopilot="px4", duration_s=60.0, monitor=False,
                        autopilot_telemetry=f"udpin:127.0.0.1:{port}", connect_timeout_s=5.0,
                        stall_timeout_s=8.0, out=tmp_path / "up")
    # WHEN up flies the whole duration with it
    summary = run_up(options, log=lambda _line: None, backend=autopilot)
    # THEN the live scorecard covers the flight after the pause too
    assert autopilot.paused and summary is not None
    assert summary["sim_duration_s"] > 55.0


def test_the_fusion_waits_for_the_autopilot_as_long_as_the_simulator_does(
        tmp_path: Path) -> None:
    """A pause of the autopilot shorter than the stall timeout must not end the fusion's live
    scorecard (it would be cut short of the duration)."""
    assert fusion_idle_exit_s(UpOptions(out=tmp_path)) == FUSION_IDLE_EXIT_S
    with_autopilot = UpOptions(autopilot="ardupilot", stall_timeout_s=10.0, out=tmp_path)
    assert fusion_idle_exit_s(with_autopilot) > with_autopilot.stall_timeout_s
