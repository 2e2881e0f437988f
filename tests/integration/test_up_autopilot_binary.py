"""``hilnav up --ardupilot --autopilot-binary PATH``: up starts the autopilot's SITL itself on
free ports (here a fake arduplane, tests/helpers/fake_sitl.py, running the ArduPilot protocol
peer on the ports of the command line it was given), points the simulator, telemetry and
denial links at it, and stops it by PID with every other child; a binary that exits at once is
one line and exit 2, with nothing left running."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

from scenarios.cli.up import stop_process, wait_gone
from tests.helpers.fake_sitl import ARDUPLANE, EXITS_AT_ONCE, write_fake

_PID = re.compile(r"^(fusion|autopilot)\s+pid (\d+):", re.M)


def _up(tmp_path: Path, *args: str) -> subprocess.CompletedProcess[str]:
    proc = subprocess.Popen(
        [sys.executable, "-m", "scenarios.cli", "up", "--ardupilot", *args, "--no-monitor",
         "--out", str(tmp_path / "up")],
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, start_new_session=True,
        env={**os.environ, "PYTHONUNBUFFERED": "1", "COLUMNS": "200",
             "FAKE_SITL_REPORT": str(tmp_path)})
    try:
        text, _ = proc.communicate(timeout=600)
    finally:
        stop_process(proc)
    return subprocess.CompletedProcess(proc.args, proc.returncode, text)


def test_up_starts_arduplane_and_denies_its_gnss(tmp_path: Path) -> None:
    binary = write_fake(tmp_path, "arduplane", ARDUPLANE)
    done = _up(tmp_path, "--autopilot-binary", str(binary), "--duration", "30",
               "--gnss-off", "15:8", "--connect-timeout", "60")
    text = done.stdout
    pids = [int(pid) for _, pid in _PID.findall(text)]
    assert len(pids) == 2 and wait_gone(pids), text
    fake_pid = json.loads((tmp_path / "fake.json").read_text())["pid"]
    assert fake_pid in pids
    assert done.returncode == 0, text
    assert "now start" not in text  # nothing for the user to start by hand
    s = json.loads((tmp_path / "up" / "summary.json").read_text())
    ap = s["autopilot"]
    process = ap["process"]
    assert process["binary"] == str(binary) and process["version"] == "ArduPlane V4.7.0-dev"
    assert process["stopped_by"] == "SIGTERM"
    n = process["instance"]
    assert ap["link"] == {"simulator": f"udpin:127.0.0.1:{9002 + 10 * n}",
                          "telemetry": f"tcp:127.0.0.1:{5760 + 10 * n}"}
    # the denial reached ArduPilot over SERIAL1 of the started instance
    assert ap["counters"]["params_sent"] == ap["counters"]["params_acked"] >= 3
    assert "NOT denied" not in text and "failures" not in s


def test_up_with_a_binary_that_exits_at_once_is_bad_input(tmp_path: Path) -> None:
    binary = write_fake(tmp_path, "arduplane", EXITS_AT_ONCE)
    done = _up(tmp_path, "--autopilot-binary", str(binary), "--duration", "30")
    assert done.returncode == 2, done.stdout
    line = done.stdout.strip().splitlines()[-1]
    assert line.startswith(f"error: autopilot binary {binary} exited with code 3")
    assert "Traceback" not in done.stdout
    pids = [int(pid) for _, pid in _PID.findall(done.stdout)]
    assert wait_gone(pids)
    assert not (tmp_path / "up" / "summary.json").exists()
