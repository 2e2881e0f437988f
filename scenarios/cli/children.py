"""``hilnav up``'s child processes: started in their own sessions, output in a log file,
stopped by PID only (terminate, wait, kill) on a normal end, on Ctrl-C / SIGTERM and from an
``atexit`` hook, so no orphan survives ``up``."""

from __future__ import annotations

import atexit
import contextlib
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import IO, Any

__all__ = ["Child", "free_udp_port", "hilnav_argv", "running_children", "sigterm_interrupts",
           "stop_process", "wait_gone"]

_STOP_TIMEOUT_S = 5.0


def free_udp_port(host: str = "127.0.0.1") -> int:
    """A UDP port that was free a moment ago."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind((host, 0))
        port: int = s.getsockname()[1]
        return port


def hilnav_argv(*args: str) -> list[str]:
    """Command line running ``hilnav ARGS`` with this interpreter."""
    return [sys.executable, "-m", "scenarios.cli", *args]


def stop_process(proc: subprocess.Popen[Any], timeout_s: float = _STOP_TIMEOUT_S) -> int | None:
    """Stop one child by PID: SIGTERM, wait, SIGKILL; returns its exit code."""
    if proc.poll() is None:
        with contextlib.suppress(ProcessLookupError):
            proc.terminate()
        try:
            proc.wait(timeout_s)
        except subprocess.TimeoutExpired:
            with contextlib.suppress(ProcessLookupError):
                proc.kill()
            proc.wait(timeout_s)
    return proc.returncode


class Child:
    """A child process with its output in a log file."""

    def __init__(self, name: str, argv: list[str], log_path: Path) -> None:
        self.name = name
        self.log_path = log_path
        self._log: IO[bytes] = log_path.open("wb")
        self.proc: subprocess.Popen[bytes] = subprocess.Popen(
            argv, stdout=self._log, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
            start_new_session=True,  # Ctrl-C in the terminal reaches `up` only; up stops us
        )

    @property
    def pid(self) -> int:
        return self.proc.pid

    def stop(self) -> int | None:
        code = stop_process(self.proc)
        self._log.close()
        return code


@contextlib.contextmanager
def running_children() -> Iterator[list[Child]]:
    """The children started in this block (append them), all stopped when it ends."""
    children: list[Child] = []

    def stop_all() -> None:
        for child in reversed(children):
            child.stop()

    atexit.register(stop_all)
    try:
        with sigterm_interrupts():
            yield children
    finally:
        stop_all()
        atexit.unregister(stop_all)


@contextlib.contextmanager
def sigterm_interrupts() -> Iterator[None]:
    """In this block SIGTERM raises KeyboardInterrupt (as Ctrl-C does), so that the ``finally``
    blocks that stop child processes run (main thread only; elsewhere nothing changes)."""
    if not _is_main_thread():
        yield
        return
    previous = signal.getsignal(signal.SIGTERM)

    def on_term(_sig: int, _frame: Any) -> None:
        raise KeyboardInterrupt

    signal.signal(signal.SIGTERM, on_term)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def _is_main_thread() -> bool:
    import threading

    return threading.current_thread() is threading.main_thread()


def wait_gone(pids: list[int], timeout_s: float = 5.0) -> bool:
    """Whether every PID is gone (or a zombie) within ``timeout_s`` (for tests)."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if not any(_alive(p) for p in pids):
            return True
        time.sleep(0.05)
    return not any(_alive(p) for p in pids)


def _alive(pid: int) -> bool:
    try:
        status = Path(f"/proc/{pid}/stat").read_text().split()[2]
    except (FileNotFoundError, IndexError, ProcessLookupError):
        return False
    return status != "Z"
