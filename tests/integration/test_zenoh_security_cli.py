"""The Zenoh security options of the CLI, end to end with real processes.

GIVEN a router with usrpwd and access control and a real ``hilnav fusion`` process that logs in
as ``fusion`` and tags its samples with the shared key, WHEN ``hilnav check --alive`` asks THEN
exit 0; WHEN the fusion is stopped (by PID) and an attacker with a valid login declares the
``alive`` token THEN the router refuses the token; WHEN the attacker reaches an open router
instead THEN ``check`` without the key is fooled and ``check`` with the key exits 1.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest
from typer.testing import CliRunner

from hil.bus import KEY_ENV, PASSWORD_ENV, Topic, key
from hil.bus.security import RouterSecurity
from hil.router import ZenohRouter, free_tcp_port
from scenarios.cli.app import app
from scenarios.cli.up import free_udp_port, stop_process
from tests.helpers.processes import hilnav_process

from ..hil.test_bus import wait_for
from ..hil.test_bus_security import login, raw_client

KEY_HEX = "11" * 32


@pytest.fixture()
def env(monkeypatch: pytest.MonkeyPatch) -> Iterator[None]:
    monkeypatch.setenv(KEY_ENV, KEY_HEX)
    monkeypatch.setenv(PASSWORD_ENV, "fusion-pw")
    yield


def _check(endpoint: str, *extra: str, user: str = "viewer", password: str = "viewer-pw",
           key_env: str | None = KEY_HEX) -> tuple[int, str]:
    env = {PASSWORD_ENV: password, KEY_ENV: key_env or ""}
    result = CliRunner().invoke(app, ["check", "--connect", endpoint, "--vehicle", "sec",
                                      "--alive", "--timeout", "3", "--zenoh-user", user,
                                      *extra], env=env)
    return result.exit_code, result.output


def _fusion(endpoint: str, log: Path, *, user: str | None) -> object:
    args = ["fusion", "--mavlink", f"udpin:127.0.0.1:{free_udp_port()}", "--zenoh", endpoint,
            "--vehicle", "sec", "--duration", "60"]
    if user is not None:
        args += ["--zenoh-user", user]
    return hilnav_process(*args, log=log)


def test_secured_fusion_is_verified_and_a_fake_token_is_refused(
    tmp_path: Path, env: None
) -> None:
    users = tmp_path / "users.txt"
    users.write_text("fusion:fusion-pw\nviewer:viewer-pw\nmallory:mallory-pw\n")
    with ZenohRouter(security=RouterSecurity(users_file=users, acl=True)) as router:
        ep = router.endpoint
        fusion = _fusion(ep, tmp_path / "fusion.log", user="fusion")
        try:
            assert wait_for(lambda: _check(ep)[0] == 0, timeout_s=60.0), (
                (tmp_path / "fusion.log").read_text())
            code, out = _check(ep, password="wrong")
            assert code == 1 and "no router" in out
        finally:
            stop_process(fusion)  # type: ignore[arg-type]
        assert wait_for(lambda: _check(ep)[0] == 1)
        mallory = raw_client(ep, login("mallory", "mallory-pw"))
        try:
            token = mallory.liveliness().declare_token(key("sec", Topic.ALIVE))
            code, out = _check(ep, key_env=None)  # even without the key: refused by the ACL
            assert code == 1 and "no hilnav/sec/fusion/alive token" in out
            del token
        finally:
            mallory.close()


def test_without_acl_the_key_still_flags_a_fake_token(tmp_path: Path, env: None) -> None:
    users = tmp_path / "users.txt"
    users.write_text("fusion:fusion-pw\nviewer:viewer-pw\n")
    with ZenohRouter(security=RouterSecurity(users_file=users)) as router:
        ep = router.endpoint
        mallory = raw_client(ep, login("viewer", "viewer-pw"))
        try:
            token = mallory.liveliness().declare_token(key("sec", Topic.ALIVE))
            assert wait_for(lambda: _check(ep, key_env=None)[0] == 0)  # fooled without key
            code, out = _check(ep)
            assert code == 1 and "forged token?" in out
            del token
        finally:
            mallory.close()


def test_bad_security_options_exit_2_with_one_line(tmp_path: Path) -> None:
    users = tmp_path / "users.txt"
    users.write_text("a:b\n")
    cases = [
        (["router", "--listen", f"tcp/0.0.0.0:{free_tcp_port()}", "--duration", "1"],
         "beyond loopback"),
        (["router", "--acl", "--duration", "1"], "--acl needs"),
        (["router", "--users-file", str(tmp_path / "nope"), "--duration", "1"],
         "not a readable file"),
        (["check", "--zenoh-user", "fusion"], "password"),
        (["check", "--tls-ca", str(users)], "tls/ endpoints"),
        (["monitor", "--tls-cert", str(users), "--tls-key", str(users)], "--tls-ca"),
        (["fusion", "--zenoh", "tcp/127.0.0.1:1", "--zenoh-key-file", str(users)], "key"),
        (["fusion", "--zenoh-user", "fusion"], "needs --zenoh ENDPOINT"),
    ]
    for args, needle in cases:
        result = CliRunner().invoke(app, args, env={PASSWORD_ENV: "", KEY_ENV: ""})
        assert result.exit_code == 2, (args, result.output)
        assert needle in result.output and "Traceback" not in result.output, (args, result.output)
        assert len(result.output.strip().splitlines()) == 1, result.output



def test_up_with_users_runs_every_child_logged_in_under_access_control(tmp_path: Path) -> None:
    """GIVEN `up --users-file` and the shared key WHEN it flies 20 s THEN the fusion, sim and
    monitor log in with up's generated passwords, the ACL lets each do its job (the monitor
    records tagged estimates, nothing is rejected) and no password is on a command line."""
    users = tmp_path / "users.txt"
    users.write_text("viewer:viewer-pw\n")
    out = tmp_path / "up"
    proc = subprocess.run(
        [sys.executable, "-m", "scenarios.cli", "up", "--duration", "20", "--speed", "20",
         "--out", str(out), "--users-file", str(users)],
        capture_output=True, text=True, timeout=150, check=False,
        env={**os.environ, "PYTHONUNBUFFERED": "1", "COLUMNS": "200", KEY_ENV: KEY_HEX},
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "usrpwd + access control" in proc.stdout
    assert "--zenoh-password-file" not in proc.stdout  # the children's secrets stay private
    monitor_log = (out / "monitor.log").read_text()
    assert "REJECTED" not in monitor_log and "mode=gnss" in monitor_log, monitor_log[-2000:]
    assert json.loads((out / "summary.json").read_text())["live"]["lost_frames"] == 0


def test_up_refuses_an_exposed_router_without_users(tmp_path: Path) -> None:
    result = CliRunner().invoke(app, ["up", "--duration", "5", "--out", str(tmp_path / "o"),
                                      "--zenoh-host", "0.0.0.0"])
    assert result.exit_code == 2 and "beyond loopback" in result.output
    assert len(result.output.strip().splitlines()) == 1
