"""``hilnav sim ardupilot URL``: the command, its bad input and a whole flight with the
ArduPilot-side protocol peer (a real hilnav process, stopped by PID)."""

from __future__ import annotations

import re
import time
from pathlib import Path

import pytest
from typer.testing import CliRunner

from hil.codec import mavlink2
from hil.pipeline import SimSetup
from hil.tlog import read_tlog
from scenarios.cli.app import app, main
from scenarios.cli.up import stop_process
from tests.helpers.ardupilot_peer import ArduPilotPeer, trimmed_controls
from tests.helpers.processes import hilnav_process


@pytest.mark.parametrize(("args", "needle"), [
    (["tcp:127.0.0.1:9002"], "expected udpin:HOST:PORT"),
    (["udpin:127.0.0.1:0", "--servo-map", "missing.yaml"], "servo map"),
    (["udpin:127.0.0.1:0", "--ardupilot-mavlink", "bogus:1"], "link URL"),
    (["udpin:127.0.0.1:0", "--stall-timeout", "0"], "stall timeout"),
])
def test_bad_autopilot_options_are_one_line_and_exit_2(args: list[str], needle: str) -> None:
    result = CliRunner().invoke(app, ["sim", "ardupilot", *args, "--duration", "5"])
    assert result.exit_code == 2, result.output
    assert needle in result.output and "Traceback" not in result.output
    assert len([ln for ln in result.output.splitlines() if ln.strip()]) == 1


@pytest.mark.parametrize(("args", "needle"), [
    (["--record", "x.tlog", "--servo-map", "s.yaml"], "need --ardupilot URL"),
    (["--record", "x.tlog", "--ardupilot-mavlink", "tcp:127.0.0.1:5760"], "need --ardupilot URL"),
    (["--ardupilot", "udpin:127.0.0.1:0", "--live", "udpout:127.0.0.1:9"], "give one"),
])
def test_the_flag_spelling_still_names_the_ardupilot_mistakes(
    capsys: pytest.CaptureFixture[str], args: list[str], needle: str
) -> None:
    """GIVEN the deprecated flag spelling (``hilnav sim --ardupilot URL``) with options that
    need another mode THEN exit 2 with one line saying which."""
    with pytest.raises(SystemExit) as exited:
        main(["sim", *args, "--duration", "5"])
    err = capsys.readouterr().err
    assert exited.value.code == 2 and needle in err
    assert len([ln for ln in err.splitlines() if ln.strip()]) == 1


def test_no_ardupilot_within_the_connect_timeout_exits_1(tmp_path: Path) -> None:
    result = CliRunner().invoke(app, ["sim", "ardupilot", "udpin:127.0.0.1:0", "--duration",
                                      "5", "--connect-timeout", "0.3"])
    assert result.exit_code == 1
    assert "no ArduPilot servo packet within 0.3 s" in result.output


def test_sim_flies_with_the_ardupilot_peer_and_records_every_frame(tmp_path: Path) -> None:
    # GIVEN the peer's MAVLink port, and hilnav sim serving the JSON interface on a free port
    setup = SimSetup.build(duration_s=30.0, rate_hz=100.0, seed=5, gnss_off=["10:10"])
    peer = ArduPilotPeer(trim=trimmed_controls(setup), mavlink=True)
    log, tlog = tmp_path / "sim.log", tmp_path / "run.tlog"
    proc = hilnav_process(
        "sim", "ardupilot", "udpin:127.0.0.1:0", "--ardupilot-mavlink", peer.mavlink_url,
        "--duration", "30", "--rate", "100", "--seed", "5", "--gnss-off", "10:10",
        "--record", str(tlog), log=log)
    try:
        port = None
        deadline = time.monotonic() + 60.0
        while port is None and time.monotonic() < deadline and proc.poll() is None:
            m = re.search(r"servo packets on udp 127\.0\.0\.1:(\d+)", log.read_text())
            port = int(m.group(1)) if m else None
            time.sleep(0.05)
        assert port is not None, log.read_text()
        # WHEN the peer connects and flies
        with peer.start(f"udp:127.0.0.1:{port}"):
            code = proc.wait(timeout=120)
    finally:
        stop_process(proc)
    out = log.read_text()
    # THEN the run succeeded, the denial went out as parameters and every frame was recorded
    assert code == 0, out
    assert "flew 30.0 s simulated with ArduPilot" in out and "3000 steps" in out
    assert "SIM_* parameters sent 3, acknowledged 3" in out
    assert [v for _, n, v in peer.param_log if n == "SIM_GPS1_ENABLE"] == [1.0, 0.0, 1.0]
    gps = [t for t, frame in read_tlog(tlog)
           if frame[7] | frame[8] << 8 | frame[9] << 16 == mavlink2.MAVLINK_MSG_ID_HIL_GPS]
    assert gps and not [t for t in gps if 10e6 <= t < 20e6]
    assert max(gps) > 29e6


def test_a_denial_ardupilot_did_not_take_exits_1_naming_it(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """GIVEN a flight whose SIM_GPS1_ENABLE step ArduPilot never acknowledged, WHEN ``sim
    ardupilot`` ends, THEN it exits 1 with that sentence (the flight itself went well)."""
    import scenarios.cli.ardupilot
    from hil.autopilot import AutopilotFlown

    problem = "SIM_GPS1_ENABLE = 0 at 10.0 s not acknowledged on tcp:127.0.0.1:5762"

    def fake_fly(*_args: object, **_kw: object) -> AutopilotFlown:
        return AutopilotFlown("ArduPilot", True, 30.0, 1.0, 3000, 9000, None, None, False, 0,
                              problems=(problem,))

    monkeypatch.setattr(scenarios.cli.ardupilot, "fly_ardupilot", fake_fly)
    result = CliRunner().invoke(app, ["sim", "ardupilot", "udpin:127.0.0.1:0", "--duration",
                                      "30", "--gnss-off", "10:10"])
    assert result.exit_code == 1
    assert result.output.count(problem) == 2  # its own line and the exit line
