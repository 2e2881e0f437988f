"""hilnav starts the autopilot's SITL binary (hil/autopilot/launch.py): the command line,
environment and working folder it gives ArduPlane and PX4, the instance whose ports are free,
the checks of the binary, and the stop by PID whatever happens (SIGTERM to the process group,
SIGKILL after the grace period for a binary that ignores SIGTERM, as arduplane does).

GIVEN a fake binary written by the test (tests/helpers/fake_sitl.py), WHEN the launcher starts
it, THEN it sees what the real binary would, and no process outlives the launcher."""

from __future__ import annotations

import json
import os
import random
import socket
import sys
import threading
import time
from pathlib import Path

import pytest

from hil.autopilot.launch import (
    _AP_MAX_INSTANCE,
    AutopilotProcess,
    Home,
    LaunchError,
    LaunchPlan,
    launched,
    plan_launch,
)
from scenarios.cli.children import wait_gone
from tests.helpers.fake_sitl import (
    EXITS_AT_ONCE,
    IGNORES_SIGTERM,
    IGNORES_SIGTERM_LISTENING,
    NEVER_CONNECTS,
    PANICS,
    px4_build,
    write_fake,
)


class _StartAt(random.Random):
    def __init__(self, first: int) -> None:
        super().__init__(0)
        self.first = first

    def randrange(self, *_args: object, **_kwargs: object) -> int:  # type: ignore[override]
        return self.first


def _report(folder: Path, timeout_s: float = 10.0) -> dict[str, object]:
    path = folder / "fake.json"
    deadline = time.monotonic() + timeout_s
    while not path.is_file() or not path.read_text():
        assert time.monotonic() < deadline, "the fake never reported"
        time.sleep(0.05)
    time.sleep(0.05)
    data: dict[str, object] = json.loads(path.read_text())
    return data


def test_ardupilot_ports_follow_its_instance_by_tens() -> None:
    # SITL_cmdline.cpp: base port 5760, JSON out 9002, RC in 5501, IRLock 9005, each + 10 x
    # instance (a byte: at most 255)
    plan = LaunchPlan("ardupilot", Path("/x/arduplane"), 7,
                      home=Home(47.0, 8.0, 0.0, 90.0))
    assert plan.ports["serial0_tcp"] == 5830 and plan.ports["serial1_tcp"] == 5832
    assert plan.ports["json_udp"] == 9072 and plan.ports["rcin_udp"] == 5571
    assert plan.ports["irlock_udp"] == 9075
    for _ in range(20):
        assert plan_launch("ardupilot", Path(sys.executable)).instance <= 255
    assert plan.link == "udpin:127.0.0.1:9072"
    assert plan.telemetry_url == "tcp:127.0.0.1:5830"
    assert plan.mavlink_url == "tcp:127.0.0.1:5832"
    assert plan.argv(Path("/tmp/w")) == [
        "/x/arduplane", "--model", "JSON:127.0.0.1", "--speedup", "1", "-I", "7",
        "--serial0", "tcp:0", "--home", "47,8,0,90"]


def test_px4_ports_follow_its_instance_by_ones() -> None:
    # px4-rc.simulator: TCP 4560 + instance; px4-rc.mavlink: GCS link UDP 18570 + instance
    plan = LaunchPlan("px4", Path("/b/build/bin/px4"), 3)
    assert plan.link == "tcpin:127.0.0.1:4563"
    assert plan.telemetry_url == "udpout:127.0.0.1:18573"
    assert plan.mavlink_url is None
    assert plan.argv(Path("/tmp/w")) == [
        "/b/build/bin/px4", "-i", "3", "-d", "-s", "etc/init.d-posix/rcS", "-w", "/tmp/w",
        "/b/build/etc"]
    env = plan.env()
    assert env["PX4_SYS_AUTOSTART"] == "1030" and "PX4_SIM_HOSTNAME" not in env


def test_an_instance_with_a_taken_port_is_skipped(tmp_path: Path) -> None:
    binary = write_fake(tmp_path, "arduplane", NEVER_CONNECTS)
    first = plan_launch("ardupilot", binary, instance=None)
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as taken:
        taken.bind(("127.0.0.1", first.ports["json_udp"]))
        with pytest.raises(LaunchError, match=f"instance {first.instance}: a port"):
            plan_launch("ardupilot", binary, instance=first.instance)
        # the search starts at the taken instance and moves on to the next free one
        again = plan_launch("ardupilot", binary, rng=_StartAt(first.instance))
        assert again.instance == first.instance % (_AP_MAX_INSTANCE - 1) + 1  # wrapping


@pytest.mark.parametrize("case", ["missing", "folder", "not executable", "px4 without etc"])
def test_a_binary_that_cannot_be_an_autopilot_is_named(tmp_path: Path, case: str) -> None:
    kind, path = "ardupilot", tmp_path / "arduplane"
    if case == "folder":
        path.mkdir()
    elif case == "not executable":
        path.write_text("#!/bin/sh\n")
    elif case == "px4 without etc":
        kind, path = "px4", write_fake(tmp_path, "px4", NEVER_CONNECTS)
    with pytest.raises(LaunchError) as err:
        plan_launch(kind, path)
    message = str(err.value)
    assert str(path) in message and "\n" not in message
    assert {"missing": "no such file", "folder": "not a file",
            "not executable": "not executable", "px4 without etc": "rcS"}[case] in message


def test_arduplane_is_started_in_a_fresh_folder_with_its_home(tmp_path: Path,
                                                               monkeypatch: pytest.MonkeyPatch
                                                               ) -> None:
    monkeypatch.setenv("FAKE_SITL_REPORT", str(tmp_path))
    binary = write_fake(tmp_path, "arduplane", NEVER_CONNECTS)
    plan = plan_launch("ardupilot", binary, home=Home(47.5, 8.25, 0.0, 270.0), telemetry=False)
    with launched(plan, tmp_path / "out" / "autopilot.log", grace_s=2.0) as process:
        seen = _report(tmp_path)
        workdir = process.workdir
        assert workdir is not None and Path(str(seen["cwd"])) == workdir.resolve()
        assert seen["argv"] == [str(binary), *plan.argv(workdir)[1:]]
        argv = list(seen["argv"])  # type: ignore[call-overload]
        assert argv[argv.index("--home") + 1] == "47.5,8.25,0,270"
        assert argv[argv.index("-I") + 1] == str(plan.instance)
        # SERIAL0 must not block the boot waiting for a client
        assert argv[argv.index("--serial0") + 1] == "tcp:0"
    assert process.stopped_by == "SIGTERM"
    assert wait_gone([int(str(seen["pid"]))])
    assert not workdir.exists()
    assert (tmp_path / "out" / "autopilot.log").read_text().startswith(f"$ {binary} --model")


def test_px4_gets_its_airframe_and_build_folder(tmp_path: Path,
                                                monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("FAKE_SITL_REPORT", str(tmp_path))
    monkeypatch.setenv("PX4_SIM_HOSTNAME", "elsewhere")  # the simulator is here, whatever
    binary = px4_build(tmp_path, NEVER_CONNECTS)
    plan = plan_launch("px4", binary)
    with launched(plan, tmp_path / "autopilot.log") as process:
        seen = _report(tmp_path)
        assert seen["env"] == {"PX4_SYS_AUTOSTART": "1030",
                               "PX4_SIM_MODEL": "gazebo-classic_plane"}
        assert seen["argv"] == [str(binary), *plan.argv(process.workdir or Path())[1:]]
        assert list(seen["argv"])[-1] == str(tmp_path / "build" / "etc")  # type: ignore[call-overload]


def test_a_binary_that_ignores_sigterm_is_killed_by_pid_after_the_grace(tmp_path: Path,
                                                                        monkeypatch:
                                                                        pytest.MonkeyPatch
                                                                        ) -> None:
    monkeypatch.setenv("FAKE_SITL_REPORT", str(tmp_path))
    binary = write_fake(tmp_path, "arduplane", IGNORES_SIGTERM)
    plan = plan_launch("ardupilot", binary)
    process = AutopilotProcess(plan, tmp_path / "autopilot.log", grace_s=0.5).start()
    pid = int(str(_report(tmp_path)["pid"]))
    assert process.pid == pid
    code = process.stop()
    assert process.stopped_by == "SIGKILL" and code == -9
    assert wait_gone([pid])


def test_every_started_process_is_stopped_when_the_block_raises(tmp_path: Path,
                                                                monkeypatch: pytest.MonkeyPatch
                                                                ) -> None:
    monkeypatch.setenv("FAKE_SITL_REPORT", str(tmp_path))
    binary = write_fake(tmp_path, "arduplane", IGNORES_SIGTERM)
    plan = plan_launch("ardupilot", binary)
    pid = None
    with pytest.raises(KeyboardInterrupt), launched(plan, tmp_path / "a.log", grace_s=0.3):
        pid = int(str(_report(tmp_path)["pid"]))
        raise KeyboardInterrupt  # Ctrl-C in the middle of the flight
    assert pid is not None and wait_gone([pid])


def test_a_binary_that_exits_at_once_is_seen_and_quoted(tmp_path: Path) -> None:
    binary = write_fake(tmp_path, "arduplane", EXITS_AT_ONCE)
    exited = threading.Event()
    with launched(plan_launch("ardupilot", binary), tmp_path / "autopilot.log",
                  on_exit=exited) as process:
        assert exited.wait(10.0)
    assert process.stopped_by == "exited" and process.exit_code == 3
    sentence = process.describe_exit()
    assert sentence.startswith(f"{binary} exited with code 3: ")
    assert "unrecognized option '--model'" in sentence and "starting" in sentence
    assert process.version() is None


def test_a_relative_defaults_file_reaches_arduplane_as_an_absolute_path(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    # the binary runs in a fresh folder of its own: a path relative to the user's folder
    # would not be found there (ArduPilot PANICs: "Failed to load defaults")
    binary = write_fake(tmp_path, "arduplane", NEVER_CONNECTS)
    (tmp_path / "c172.parm").write_text("ARSPD_SKIP_CAL 1\n")
    monkeypatch.chdir(tmp_path)
    plan = plan_launch("ardupilot", binary, defaults=[Path("c172.parm")])
    assert plan.defaults == ((tmp_path / "c172.parm").resolve(),)


def test_an_arduplane_that_panics_is_a_launch_error_at_once(tmp_path: Path) -> None:
    # ArduPilot's SITL does not exit on PANIC (it hangs in its core-dump helper): the
    # launcher must not wait out the connect timeout for it
    binary = write_fake(tmp_path, "arduplane", PANICS)
    t0 = time.monotonic()
    with launched(plan_launch("ardupilot", binary), tmp_path / "autopilot.log",
                  grace_s=0.3) as process, pytest.raises(LaunchError) as caught:
        process.wait_ready(60.0)
    assert time.monotonic() - t0 < 30.0
    assert "PANIC: Failed to load defaults from nowhere.parm" in str(caught.value)


def test_the_version_is_read_from_its_output_or_its_texts(tmp_path: Path) -> None:
    log = tmp_path / "autopilot.log"
    log.write_text("$ arduplane --model JSON\nInit ArduPlane V4.7.0-dev (2598e9d4)\nready\n")
    process = AutopilotProcess(LaunchPlan("ardupilot", Path("arduplane"), 1), log)
    assert process.version() == "ArduPlane V4.7.0-dev (2598e9d4)"
    log.write_text("$ px4 -i 1\nINFO  [px4] instance: 1\n")
    assert process.version(["PX4 v1.15.0-alpha1"]) == "PX4 v1.15.0-alpha1"
    assert os.path.basename(process.record()["log"]) == "autopilot.log"


def test_px4s_version_comes_from_its_build_folder(tmp_path: Path) -> None:
    # PX4 prints no version: the header its build generated names the git tag and hash
    binary = px4_build(tmp_path, NEVER_CONNECTS)
    process = AutopilotProcess(plan_launch("px4", binary), tmp_path / "autopilot.log")
    assert process.version() is None  # no header, no output, no texts
    header = tmp_path / "build" / "src" / "lib" / "version" / "build_git_version.h"
    header.parent.mkdir(parents=True)
    header.write_text('#define PX4_GIT_VERSION_STR "3fb0c7ee2f508b8c6b90aaa6a841b71e46331e29"\n'
                      '#define PX4_GIT_TAG_STR "v1.13.0-beta1-2834-g3fb0c7ee2f"\n')
    assert process.version() == "PX4 v1.13.0-beta1-2834-g3fb0c7ee2f (3fb0c7ee2f)"


def test_arduplane_is_ready_when_its_serial0_listens(tmp_path: Path) -> None:
    import hil.autopilot.launch as launch

    binary = write_fake(tmp_path, "arduplane", IGNORES_SIGTERM_LISTENING)
    with launched(plan_launch("ardupilot", binary), tmp_path / "a.log", grace_s=0.3) as p:
        assert p.wait_ready(30.0)
        assert launch._tcp_listening(p.plan.ports["serial0_tcp"])
    # a binary whose SERIAL0 never listens is not ready
    never = write_fake(tmp_path, "never", NEVER_CONNECTS)
    with launched(plan_launch("ardupilot", never), tmp_path / "b.log") as p:
        assert not p.wait_ready(0.5)


def test_arduplanes_version_is_read_from_the_binary_when_not_printed(tmp_path: Path) -> None:
    # ArduPlane SITL prints no version on its console; its firmware string is in the binary
    binary = write_fake(tmp_path, "arduplane", NEVER_CONNECTS)
    with binary.open("ab") as f:
        f.write(b"\n# \x00ArduPlane V4.7.0-dev\x00junk\x00ArduPlane V4.7.0-dev (2598e9d4)\x00")
    process = AutopilotProcess(plan_launch("ardupilot", binary), tmp_path / "autopilot.log")
    assert process.version() == "ArduPlane V4.7.0-dev (2598e9d4)"
