"""Starting ``hilnav`` as a child process in tests (real processes, stopped by PID)."""

from __future__ import annotations

import os
import subprocess
import sys
import threading
from pathlib import Path


def hilnav_process(*args: str, log: Path) -> subprocess.Popen[bytes]:
    """``hilnav ARGS`` with this interpreter, output to ``log``, in its own session (so a test
    stops it by PID with ``scenarios.cli.up.stop_process``, never by name)."""
    return subprocess.Popen(
        [sys.executable, "-m", "scenarios.cli", *args], stdout=log.open("wb"),
        stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL, start_new_session=True,
        env={**os.environ, "COLUMNS": "200"},
    )


def lockstep_chain(
    tmp_path: Path, port: int, *, speed: str, duration_s: str, seed: str, settle_s: str,
    fusion_args: tuple[str, ...] = (), sim_args: tuple[str, ...] = (),
) -> tuple[subprocess.Popen[bytes], subprocess.Popen[bytes]]:
    """A fusion service on ``udpin:127.0.0.1:PORT`` writing its live scorecard to
    ``tmp_path/live``, and a lockstep simulator streaming to it and recording
    ``tmp_path/run.tlog``; logs in ``fusion.log`` / ``sim.log``. The caller stops both by PID."""
    fusion = hilnav_process(
        "fusion", "--mavlink", f"udpin:127.0.0.1:{port}", "--out", str(tmp_path / "live"),
        "--idle-exit", "3", "--settle", settle_s, *fusion_args, log=tmp_path / "fusion.log")
    sim = hilnav_process(
        "sim", "live", f"udpout:127.0.0.1:{port}", "--speed", speed, "--lockstep",
        "--duration", duration_s, "--seed", seed, *sim_args,
        "--record", str(tmp_path / "run.tlog"), "--wait-peer", "30", log=tmp_path / "sim.log")
    return fusion, sim


def finish_lockstep_chain(
    tmp_path: Path, fusion: subprocess.Popen[bytes], sim: subprocess.Popen[bytes],
    stop: threading.Event, helper: threading.Thread,
) -> None:
    """Wait for a :func:`lockstep_chain` to fly to its end (both exit 0), then stop the test's
    ``helper`` thread (e.g. an attacker) through ``stop``; the processes are stopped by PID
    whatever happens."""
    from scenarios.cli.up import stop_process

    try:
        assert sim.wait(240) == 0, (tmp_path / "sim.log").read_text()
        stop.set()
        assert fusion.wait(60) == 0, (tmp_path / "fusion.log").read_text()
    finally:
        stop.set()
        for p in (sim, fusion):
            stop_process(p)
    helper.join(5.0)


def free_tcp_port(host: str = "127.0.0.1") -> int:
    """A TCP port that was free a moment ago."""
    import socket

    with socket.socket() as s:
        s.bind((host, 0))
        port: int = s.getsockname()[1]
        return port
