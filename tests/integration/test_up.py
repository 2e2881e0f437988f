"""``hilnav up``: router + fusion + sim + monitor on loopback, stopped cleanly by PID."""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

from scenarios.cli.up import stop_process, wait_gone

_PID = re.compile(r"^(fusion|monitor|sim)\s+pid (\d+):", re.M)


def _env() -> dict[str, str]:
    return {**os.environ, "PYTHONUNBUFFERED": "1", "COLUMNS": "200"}


def test_up_with_duration_finishes_by_itself_and_prints_a_scorecard(tmp_path: Path) -> None:
    out = tmp_path / "up"
    proc = subprocess.run(
        [sys.executable, "-m", "scenarios.cli", "up", "--duration", "30", "--speed", "20",
         "--out", str(out)],
        capture_output=True, text=True, timeout=150, env=_env(), check=False,
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    pids = {name: int(pid) for name, pid in _PID.findall(proc.stdout)}
    assert set(pids) == {"fusion", "monitor", "sim"}, proc.stdout
    assert wait_gone(list(pids.values())), "a child outlived `hilnav up`"
    assert "scorecard of the live run" in proc.stdout
    assert "GNSS on: horizontal RMSE" in proc.stdout
    summary = json.loads((out / "summary.json").read_text())
    assert summary["live"]["lost_frames"] == 0
    assert summary["gnss_on"]["horizontal_rmse_m"] is not None
    assert (out / "run.tlog").stat().st_size > 0
    assert "sim finished (exit 0)" in proc.stdout
    # the sim child's progress (a line every 10 % of the flight in its log) and its result
    assert "flying: " in proc.stderr and "s simulated (" in proc.stderr
    assert "sim           sent " in proc.stdout and "x real time" in proc.stdout


def test_up_signs_every_link_with_the_key_from_the_environment(tmp_path: Path) -> None:
    # GIVEN a signing key in HILNAV_MAVLINK_KEY (as docs/live.md, "MAVLink signing", shows)
    out = tmp_path / "up"
    env = {**_env(), "HILNAV_MAVLINK_KEY": "5a" * 32}
    proc = subprocess.run(
        [sys.executable, "-m", "scenarios.cli", "up", "--duration", "20", "--speed", "20",
         "--out", str(out)],
        capture_output=True, text=True, timeout=150, env=env, check=False,
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    # THEN the fusion's link ran signed (it accepts only correctly signed frames: an unsigned
    # one would be dropped and counted), accepted the simulator's stream and lost nothing
    live = json.loads((out / "summary.json").read_text())["live"]
    mav = live["links"]["mavlink"]
    assert live["signed"] is True and live["lost_frames"] == 0
    assert mav["accepted"] > 1000 and mav["unsigned"] == 0 and mav["bad_signature"] == 0


def _default_sigint() -> None:
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def test_up_stops_every_child_on_sigint(tmp_path: Path) -> None:
    proc = subprocess.Popen(
        [sys.executable, "-m", "scenarios.cli", "up", "--speed", "1",
         "--out", str(tmp_path / "up")],
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=_env(),
        start_new_session=True,
        # as from a terminal: a shell starts background jobs (pytest under `cmd &`) with SIGINT
        # ignored, children inherit that, and Python then installs no KeyboardInterrupt handler
        preexec_fn=_default_sigint,
    )
    lines: list[str] = []
    try:
        assert proc.stdout is not None
        deadline = time.monotonic() + 60.0
        while time.monotonic() < deadline:
            line = proc.stdout.readline()
            if not line:
                break
            lines.append(line)
            if line.startswith("subscribe:"):
                break
        text = "".join(lines)
        pids = [int(p) for _name, p in _PID.findall(text)]
        assert len(pids) == 3, text
        time.sleep(2.0)  # let the children get going
        os.kill(proc.pid, signal.SIGINT)
        rest, _ = proc.communicate(timeout=60)
    finally:
        stop_process(proc)
    assert proc.returncode == 0, text + rest
    assert "stopping" in rest
    assert wait_gone(pids), "a child outlived `hilnav up`"
