"""A Dask cluster of real ``dask scheduler`` / ``dask worker`` processes on loopback, as the
recipe of docs/scenarios.md ("On a Dask cluster") starts one on other hosts (free ports,
stopped by PID)."""

from __future__ import annotations

import contextlib
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path


def _dask(*args: str, log: Path) -> subprocess.Popen[bytes]:
    return subprocess.Popen(
        [sys.executable, "-m", "dask", *args], stdout=log.open("wb"), stderr=subprocess.STDOUT,
        stdin=subprocess.DEVNULL, start_new_session=True)


@contextlib.contextmanager
def dask_cli_cluster(n_workers: int, log_dir: Path, *, timeout_s: float = 90.0
                     ) -> Iterator[str]:
    """``dask scheduler`` on a free 127.0.0.1 port and ``n_workers`` single-threaded ``dask
    worker`` processes connected to it; yields the ``tcp://127.0.0.1:PORT`` address once every
    worker has joined. Logs in ``log_dir``; every process is stopped by PID at exit."""
    from dask.distributed import Client

    from hil.router import free_tcp_port
    from scenarios.cli.up import stop_process

    port = free_tcp_port()
    address = f"tcp://127.0.0.1:{port}"
    log_dir.mkdir(parents=True, exist_ok=True)
    procs = [_dask("scheduler", "--host", "127.0.0.1", "--port", str(port), "--no-dashboard",
                   log=log_dir / "dask-scheduler.log")]
    try:
        for i in range(n_workers):
            procs.append(_dask("worker", address, "--nthreads", "1", "--nworkers", "1",
                               "--host", "127.0.0.1", "--no-dashboard", "--name", f"w{i}",
                               "--local-directory", str(log_dir / f"w{i}"),
                               log=log_dir / f"dask-worker-{i}.log"))
        with Client(address, timeout=f"{timeout_s}s") as client:
            client.wait_for_workers(n_workers, timeout=timeout_s)
        yield address
    finally:
        for p in reversed(procs):  # workers first: they leave the scheduler cleanly
            stop_process(p)
