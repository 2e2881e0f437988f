"""``hilnav run SCENARIO --autopilot-binary PATH`` (and ``autopilot.binary``): hilnav starts the
autopilot's SITL itself, flies the scenario with it and stops it by PID.

GIVEN fake ``arduplane`` / ``px4`` binaries (tests/helpers/fake_sitl.py) that honour the real
command line and run the protocol peers on the ports it implies, WHEN the user runs the
scenario with the binary, THEN both estimates are scored, the summary says which binary
(version, instance, ports) flew, and the process is gone afterwards; a binary that is not an
autopilot is one line and exit 2, one that never connects exit 1, and a crash, Ctrl-C or
exception never leaves the process behind.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from typer.testing import CliRunner

from hil.autopilot.launch import LaunchError
from scenarios.cli.app import app
from scenarios.cli.children import stop_process, wait_gone
from scenarios.runner import run_scenario, sim_setup
from scenarios.schema import load_scenario
from tests.helpers.ardupilot_peer import trimmed_controls
from tests.helpers.fake_sitl import (
    ARDUPLANE,
    EXITS_AT_ONCE,
    IGNORES_SIGTERM_LISTENING,
    NEVER_CONNECTS,
    PX4,
    px4_build,
    write_fake,
)

STANDARD_PLANE = Path(__file__).resolve().parents[2] / "docs/autopilot/px4-standard-plane.yaml"


def _scenario(folder: Path, kind: str, *, binary: str | None = None, duration_s: float = 30.0,
              connect_timeout_s: float = 30.0) -> Path:
    path = folder / f"{kind}.yaml"
    extra = f"actuator_map: {STANDARD_PLANE}" if kind == "px4" else ""
    path.write_text(f"""
name: {kind}-binary
duration_s: {duration_s}
sim_rate_hz: 50
seed: 3
sensors:
  imu: {{preset: industrial-mems, rate_hz: 50}}
start: {{lat_deg: 47.0, lon_deg: 8.0, alt_msl_m: 1000, heading_deg: 0, airspeed_mps: 50}}
autopilot:
  kind: {kind}
  {f"binary: {binary}" if binary else ""}
  link: tcpin:127.0.0.1:4560
  telemetry: udpin:127.0.0.1:14550
  {extra}
  connect_timeout_s: {connect_timeout_s}
  stall_timeout_s: 10
events:
  - {{type: gnss_outage, at: 15, duration: 8}}
""".replace("tcpin:127.0.0.1:4560", "udpin:127.0.0.1:9002" if kind == "ardupilot" else
            "tcpin:127.0.0.1:4560"))
    return path


def _run(*args: str) -> tuple[int, str]:
    res = CliRunner().invoke(app, ["run", *args, "--quiet"])
    return res.exit_code, res.output


@pytest.fixture
def fake_env(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.setenv("FAKE_SITL_REPORT", str(tmp_path))
    return tmp_path


def _fake_pid(folder: Path) -> int:
    return int(json.loads((folder / "fake.json").read_text())["pid"])


def test_arduplane_started_by_hilnav_flies_the_scenario(fake_env: Path,
                                                         monkeypatch: pytest.MonkeyPatch) -> None:
    # the scenario names the binary relative to itself; its own link and telemetry URLs are
    # replaced by the started instance's ports
    binary = write_fake(fake_env, "arduplane", ARDUPLANE)
    scn = _scenario(fake_env, "ardupilot", binary="arduplane")
    trim = trimmed_controls(sim_setup(load_scenario(scn)))
    monkeypatch.setenv("FAKE_SITL_TRIM", ",".join(f"{x:.6f}" for x in trim))
    s = run_scenario(load_scenario(scn), fake_env / "out", reports=False).summary
    ap = s["autopilot"]
    process = ap["process"]
    n = process["instance"]
    assert process["binary"] == str(binary) and process["kind"] == "ardupilot"
    assert process["version"] == "ArduPlane V4.7.0-dev"
    assert process["ports"]["serial0_tcp"] == 5760 + 10 * n
    assert process["home"] == "47,8,0,0"
    assert process["stopped_by"] == "SIGTERM"
    assert ap["link"]["simulator"] == f"udpin:127.0.0.1:{9002 + 10 * n}"
    assert ap["link"]["telemetry"] == f"tcp:127.0.0.1:{5760 + 10 * n}"
    # it flew, its estimate arrived on SERIAL0 and its GNSS was denied over SERIAL1
    assert ap["connected"] and ap["stalled"] is None
    assert ap["counters"]["telemetry_position_reports"] > 100
    assert ap["counters"]["params_sent"] == ap["counters"]["params_acked"] >= 3
    assert ap["outages_not_denied"] == []
    assert "failures" not in s, s["failures"]
    assert wait_gone([_fake_pid(fake_env)])
    assert "ArduPlane V4.7.0-dev" in (fake_env / "out" / "autopilot.log").read_text()


def test_px4_started_by_hilnav_flies_the_scenario(fake_env: Path) -> None:
    binary = px4_build(fake_env, PX4)
    scn = _scenario(fake_env, "px4")
    code, out = _run(str(scn), "--out", str(fake_env / "out"), "--autopilot-binary", str(binary))
    assert code == 0, out
    ap = json.loads((fake_env / "out" / "summary.json").read_text())["autopilot"]
    n = ap["process"]["instance"]
    assert ap["process"]["binary"] == str(binary)
    assert ap["link"] == {"simulator": f"tcpin:127.0.0.1:{4560 + n}",
                          "telemetry": f"udpout:127.0.0.1:{18570 + n}"}
    assert ap["connected"] and ap["counters"]["telemetry_position_reports"] > 100
    assert wait_gone([_fake_pid(fake_env)])


def test_a_binary_that_exits_at_once_is_bad_input(fake_env: Path) -> None:
    binary = write_fake(fake_env, "arduplane", EXITS_AT_ONCE)
    code, out = _run(str(_scenario(fake_env, "ardupilot")), "--out", str(fake_env / "out"),
                     "--autopilot-binary", str(binary))
    assert code == 2, out
    line = out.strip().splitlines()[-1]
    assert line.startswith(f"error: autopilot binary {binary} exited with code 3")
    assert "unrecognized option '--model'" in " ".join(out.split())
    assert "Traceback" not in out


def test_a_missing_binary_is_bad_input(fake_env: Path) -> None:
    code, out = _run(str(_scenario(fake_env, "px4")), "--out", str(fake_env / "out"),
                     "--autopilot-binary", str(fake_env / "nowhere" / "px4"))
    assert code == 2 and "no such file" in out and "Traceback" not in out


def test_a_binary_needs_an_autopilot_scenario(fake_env: Path) -> None:
    scn = fake_env / "none.yaml"
    scn.write_text("name: plain\nduration_s: 30\n")
    code, out = _run(str(scn), "--out", str(fake_env / "out"),
                     "--autopilot-binary", str(write_fake(fake_env, "arduplane", ARDUPLANE)))
    assert code == 2 and "autopilot: px4 or ardupilot" in out


def test_an_autopilot_that_never_connects_fails_the_run(fake_env: Path) -> None:
    binary = write_fake(fake_env, "arduplane", NEVER_CONNECTS)
    code, out = _run(str(_scenario(fake_env, "ardupilot", connect_timeout_s=2.0)),
                     "--out", str(fake_env / "out"), "--autopilot-binary", str(binary))
    assert code == 1, out
    text = " ".join(out.split())
    assert f"SITL {binary} (instance" in text and "did not get ready within 2 s" in text
    assert "Waiting for connection" in text
    assert wait_gone([_fake_pid(fake_env)])


def test_an_autopilot_that_crashes_in_flight_fails_the_run(fake_env: Path,
                                                            monkeypatch: pytest.MonkeyPatch
                                                            ) -> None:
    monkeypatch.setenv("FAKE_SITL_EXIT_AFTER_S", "3")
    binary = write_fake(fake_env, "arduplane", ARDUPLANE)
    scn = load_scenario(_scenario(fake_env, "ardupilot", binary=str(binary), duration_s=300.0))
    s = run_scenario(scn, fake_env / "out", reports=False).summary
    assert s["passed"] is False
    (failure,) = [f for f in s["failures"] if "autopilot process" in f]
    assert f"{binary} exited with code 4: " in failure and "PANIC: fake crash" in failure
    assert s["autopilot"]["process"]["stopped_by"] == "exited"


@pytest.mark.parametrize("interrupt", [KeyboardInterrupt, RuntimeError])
def test_the_process_is_stopped_whatever_ends_the_flight(fake_env: Path,
                                                          monkeypatch: pytest.MonkeyPatch,
                                                          interrupt: type[BaseException]
                                                          ) -> None:
    import hil.autopilot

    def broken(*_args: object, **_kwargs: object) -> None:
        assert (fake_env / "fake.json").is_file() or _wait_report(fake_env)
        raise interrupt("in the middle of the flight")

    monkeypatch.setattr(hil.autopilot, "fly_with_autopilot", broken)
    binary = write_fake(fake_env, "arduplane", ARDUPLANE)
    scn = load_scenario(_scenario(fake_env, "ardupilot", binary=str(binary)))
    with pytest.raises(interrupt):
        run_scenario(scn, fake_env / "out", reports=False)
    assert wait_gone([_fake_pid(fake_env)])


def _wait_report(folder: Path) -> bool:
    import time

    deadline = time.monotonic() + 10.0
    while time.monotonic() < deadline:
        if (folder / "fake.json").is_file():
            return True
        time.sleep(0.05)
    return False


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_stopping_hilnav_stops_the_autopilot_it_started(fake_env: Path,
                                                         sig: signal.Signals) -> None:
    # Ctrl-C (SIGINT) or a SIGTERM to `hilnav run` in the middle of the flight
    binary = write_fake(fake_env, "arduplane", IGNORES_SIGTERM_LISTENING)
    proc = subprocess.Popen(
        [sys.executable, "-m", "scenarios.cli", "run",
         str(_scenario(fake_env, "ardupilot", duration_s=300.0)), "--out",
         str(fake_env / "out"), "--autopilot-binary", str(binary), "--quiet"],
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, start_new_session=True,
        env={**os.environ, "COLUMNS": "200"})
    try:
        assert _wait_report(fake_env), "the fake never started"
        time.sleep(1.0)  # hilnav is waiting for it to connect
        proc.send_signal(sig)
        text, _ = proc.communicate(timeout=60)
    finally:
        stop_process(proc)
    assert proc.returncode != 0
    assert wait_gone([_fake_pid(fake_env)]), text


def test_a_px4_binary_that_exits_while_awaited_is_bad_input(fake_env: Path) -> None:
    # PX4 dials hilnav: its exit is seen while the flight waits for it (which it stops)
    binary = px4_build(fake_env, EXITS_AT_ONCE)
    scn = load_scenario(_scenario(fake_env, "px4", binary=str(binary), connect_timeout_s=30))
    with pytest.raises(LaunchError, match=r"exited with code 3: .*unrecognized option.*before "
                                          r"it connected"):
        run_scenario(scn, fake_env / "out", reports=False)
