"""Starting ``hilnav`` as a child process in tests (real processes, stopped by PID)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path


def hilnav_process(*args: str, log: Path) -> subprocess.Popen[bytes]:
    """``hilnav ARGS`` with this interpreter, output to ``log``, in its own session (so a test
    stops it by PID with ``scenarios.cli.up.stop_process``, never by name)."""
    return subprocess.Popen(
        [sys.executable, "-m", "scenarios.cli", *args], stdout=log.open("wb"),
        stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL, start_new_session=True,
        env={**os.environ, "COLUMNS": "200"},
    )
