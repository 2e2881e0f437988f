"""Shared helpers of the live-latency bench: clocks, statistics, child processes, a base tree.

``bench/live_latency.py`` (the parts that run) and ``bench/_live_children.py`` (the child
processes it starts) both use these.
"""

from __future__ import annotations

import contextlib
import os
import subprocess
import sys
import tempfile
from collections.abc import Iterator
from pathlib import Path

import numpy as np

HIL_SENSOR_ID = 107
START_TIMEOUT_S = 90.0
ROOT = Path(__file__).resolve().parent.parent
_CLK_TCK = os.sysconf("SC_CLK_TCK")
_SCRIPT = Path(__file__).resolve().with_name("live_latency.py")


def cpu_s(pid: int | str = "self") -> float:
    """User + system CPU seconds of a process from ``/proc/<pid>/stat``."""
    text = Path(f"/proc/{pid}/stat").read_text()
    fields = text[text.rindex(")") + 2 :].split()
    # fields[0] is the state (field 3 of stat); utime and stime are fields 14 and 15
    return (int(fields[11]) + int(fields[12])) / _CLK_TCK


def load() -> list[float]:
    """1, 5 and 15 minute load averages."""
    return [round(x, 2) for x in os.getloadavg()]


def stats_ms(values_ns: list[int]) -> dict[str, float]:
    """Median, p90, p99, max and count of latencies given in ns, in ms."""
    a = np.asarray(values_ns, dtype=float) * 1e-6
    if a.size == 0:
        return {"n": 0}
    return {
        "n": int(a.size),
        "median_ms": round(float(np.median(a)), 4),
        "p90_ms": round(float(np.percentile(a, 90)), 4),
        "p99_ms": round(float(np.percentile(a, 99)), 4),
        "max_ms": round(float(a.max()), 4),
        "min_ms": round(float(a.min()), 4),
    }


def hilnav(*args: str, log: Path) -> subprocess.Popen[bytes]:
    return subprocess.Popen(
        [sys.executable, "-m", "scenarios.cli", *args], stdout=log.open("wb"),
        stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL, start_new_session=True,
        env={**os.environ, "COLUMNS": "200"})


def this_script(*args: str, log: Path, code: Path | None = None) -> subprocess.Popen[bytes]:
    """``bench/live_latency.py`` as a child; ``code``: import hilnav from that tree instead of
    this one."""
    env = None if code is None else {**os.environ, "PYTHONPATH": str(code)}
    return subprocess.Popen(
        [sys.executable, str(_SCRIPT), *args], stdout=log.open("wb"),
        stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL, start_new_session=True, env=env)


@contextlib.contextmanager
def base_tree(rev: str | None) -> Iterator[Path | None]:
    """The repository's tree at ``rev`` in a temporary directory (None: no base; a directory:
    that tree as it is)."""
    if rev is None or Path(rev).is_dir():
        yield None if rev is None else Path(rev).resolve()
        return
    with tempfile.TemporaryDirectory(prefix="hilnav_base_") as tmp:
        archive = subprocess.run(["git", "archive", rev], cwd=ROOT, check=True,
                                 capture_output=True).stdout
        subprocess.run(["tar", "-x", "-C", tmp], input=archive, check=True)
        yield Path(tmp)


@contextlib.contextmanager
def children() -> Iterator[list[subprocess.Popen[bytes]]]:
    from scenarios.cli.up import stop_process

    procs: list[subprocess.Popen[bytes]] = []
    try:
        yield procs
    finally:
        for p in procs:
            stop_process(p)


def free_port() -> int:
    from scenarios.cli.up import free_udp_port

    return free_udp_port()


def free_tcp_port() -> int:
    from hil.router import free_tcp_port as free

    return free()
