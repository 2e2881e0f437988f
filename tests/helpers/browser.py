"""A real headless Chromium for tests of pages hilnav writes: lay a local file out and read
values from its DOM over the DevTools protocol (a WebSocket), without any page script of
ours. Skips where no Chromium is installed (Debian: ``apt-get install chromium``)."""

from __future__ import annotations

import asyncio
import json
import os
import shutil
import signal
import subprocess
import time
from pathlib import Path
from typing import Any

import pytest

_CANDIDATES = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")


def chromium_or_skip() -> str:
    """Path of a Chromium binary, or skip the test saying how to get one."""
    env = os.environ.get("HILNAV_CHROMIUM")
    found = env or next((p for p in map(shutil.which, _CANDIDATES) if p), None)
    if not found:
        pytest.skip("no Chromium on this machine (apt-get install chromium, or set "
                    "HILNAV_CHROMIUM): the real-browser check of the report is skipped")
    return found


def layout_of(chromium: str, page: Path, profile: Path, expression: str,
              *, width: int = 1400, height: int = 900, timeout_s: float = 60.0) -> Any:
    """Open ``page`` in headless ``chromium`` at ``width`` x ``height``, wait for it to load,
    and return the value of the JavaScript ``expression`` evaluated in it (by value)."""
    import websockets

    profile.mkdir(parents=True, exist_ok=True)
    proc = subprocess.Popen(
        [chromium, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic",
         "--no-first-run", "--disable-background-networking", "--disable-component-update",
         "--disable-sync", f"--user-data-dir={profile}", "--remote-debugging-address=127.0.0.1",
         "--remote-debugging-port=0", f"--window-size={width},{height}", "about:blank"],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, stdin=subprocess.DEVNULL,
        start_new_session=True)
    try:
        port_file = profile / "DevToolsActivePort"
        deadline = time.monotonic() + timeout_s
        while not (port_file.exists() and port_file.read_text().count("\n") >= 1):
            if proc.poll() is not None or time.monotonic() > deadline:
                raise AssertionError(f"Chromium did not start (exit {proc.poll()})")
            time.sleep(0.05)
        port = int(port_file.read_text().split("\n")[0])

        async def drive() -> Any:
            import urllib.request

            with urllib.request.urlopen(f"http://127.0.0.1:{port}/json/list") as r:
                targets = json.load(r)
            url = next(t["webSocketDebuggerUrl"] for t in targets if t["type"] == "page")
            async with websockets.connect(url, max_size=None) as ws:
                ids = iter(range(1, 1_000_000))

                async def call(method: str, **params: Any) -> Any:
                    n = next(ids)
                    await ws.send(json.dumps({"id": n, "method": method, "params": params}))
                    while True:
                        msg = json.loads(await ws.recv())
                        if msg.get("id") == n:
                            if "error" in msg:
                                raise AssertionError(f"{method}: {msg['error']}")
                            return msg["result"]

                await call("Page.enable")
                await call("Page.navigate", url=page.resolve().as_uri())
                for _ in range(int(timeout_s * 20)):
                    state = await call("Runtime.evaluate", expression="document.readyState",
                                       returnByValue=True)
                    if state["result"].get("value") == "complete":
                        break
                    await asyncio.sleep(0.05)
                result = await call("Runtime.evaluate", expression=expression,
                                    returnByValue=True)
                return result["result"].get("value")

        return asyncio.run(asyncio.wait_for(drive(), timeout_s))
    finally:
        # Chromium runs in its own session: its renderer and GPU children go with it
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
        proc.wait(10)
