"""``hilnav sim``'s four modes as subcommands, and the flag spelling that still works.

GIVEN a user at the shell, WHEN they run ``hilnav sim record FILE`` / ``live URL`` / ``px4 URL``
/ ``ardupilot URL``, THEN each mode takes its own options plus the shared flight and sensor
options; the flag spelling (``hilnav sim --record FILE`` ...) gives the same result with one
deprecation line naming the new spelling, and ``hilnav sim`` without a mode is bad input.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from typer.testing import CliRunner

from scenarios.cli import legacy_sim
from scenarios.cli.app import app, main

MODES_LINE = "record FILE, live URL, px4 URL or ardupilot URL"


def _main(capsys: pytest.CaptureFixture[str], *args: str) -> tuple[int, str, str]:
    """``hilnav ARGS`` through the console entry (where the flag spelling is rewritten)."""
    with pytest.raises(SystemExit) as exited:
        main(list(args))
    captured = capsys.readouterr()
    code = exited.value.code
    return (code if isinstance(code, int) else 1), captured.out, captured.err


def _lines(text: str) -> list[str]:
    """The lines said, without the progress lines of a flight (a line every 10 %)."""
    return [ln for ln in text.splitlines() if ln.strip() and not ln.startswith("flying: ")]


def test_sim_without_a_mode_is_one_line_listing_the_modes(
        capsys: pytest.CaptureFixture[str]) -> None:
    result = CliRunner().invoke(app, ["sim"])
    assert result.exit_code == 2
    assert _lines(result.output) == [f"error: hilnav sim needs a mode: {MODES_LINE} "
                                     "(see hilnav sim --help)"]
    # options without a mode, in the flag spelling: the same line
    code, _, err = _main(capsys, "sim", "--duration", "5")
    assert code == 2 and _lines(err) == _lines(result.output)


@pytest.mark.parametrize(("mode", "has", "lacks"), [
    ("record", (), ("--record", "--speed", "--zenoh", "--lockstep", "--actuator-map",
                    "--servo-map", "--tls-ca")),
    ("live", ("--record", "--speed", "--zenoh", "--lockstep", "--wait-peer", "--zenoh-user",
              "--tls-ca", "--zenoh-key-file", "--signing-key-file"),
     ("--actuator-map", "--servo-map", "--stall-timeout")),
    ("px4", ("--actuator-map", "--record", "--speed", "--stall-timeout", "--connect-timeout"),
     ("--servo-map", "--zenoh", "--lockstep", "--tls-ca")),
    ("ardupilot", ("--servo-map", "--ardupilot-mavlink", "--record", "--stall-timeout"),
     ("--actuator-map", "--speed", "--zenoh", "--lockstep", "--tls-ca")),
])
def test_each_mode_shows_its_own_options_and_the_flight_options(
        mode: str, has: tuple[str, ...], lacks: tuple[str, ...]) -> None:
    result = CliRunner().invoke(app, ["sim", mode, "--help"], env={"COLUMNS": "200"})
    assert result.exit_code == 0, result.output
    words = set(result.output.split())
    flight = ("--plan", "--aircraft", "--duration", "--seed", "--imu", "--gnss-off", "--wind")
    assert set(flight) <= words and set(has) <= words, result.output
    assert not set(lacks) & words, set(lacks) & words


@pytest.mark.parametrize(("old", "new"), [
    (["sim", "--record", "a.tlog", "--seed", "3"], ["sim", "record", "a.tlog", "--seed", "3"]),
    (["sim", "--seed", "3", "--record=a.tlog"], ["sim", "record", "a.tlog", "--seed", "3"]),
    (["sim", "--live", "udpout:h:1", "--record", "a.tlog", "--lockstep"],
     ["sim", "live", "udpout:h:1", "--record", "a.tlog", "--lockstep"]),
    (["sim", "--record", "a.tlog", "--px4", "tcpin:h:4560", "--actuator-map", "m.yaml"],
     ["sim", "px4", "tcpin:h:4560", "--record", "a.tlog", "--actuator-map", "m.yaml"]),
    (["sim", "--ardupilot", "udpin:h:9002", "--servo-map", "s.yaml"],
     ["sim", "ardupilot", "udpin:h:9002", "--servo-map", "s.yaml"]),
    # options the flag spelling accepted and ignored in that mode are dropped
    (["sim", "--record", "a.tlog", "--speed", "5", "--zenoh-user=u", "--no-lockstep",
      "--vehicle", "v", "--seed", "3"], ["sim", "record", "a.tlog", "--seed", "3"]),
    (["sim", "--px4", "tcpin:h:4560", "--zenoh", "tcp/h:7447", "--speed", "2"],
     ["sim", "px4", "tcpin:h:4560", "--speed", "2"]),
])
def test_the_flag_spelling_becomes_the_subcommand(old: list[str], new: list[str]) -> None:
    args, note = legacy_sim.rewrite(old)
    assert args == new
    mode, metavar = new[1], "FILE" if new[1] == "record" else "URL"
    assert note is not None and f"hilnav sim {mode} {metavar}" in note and "deprecated" in note


@pytest.mark.parametrize("args", [
    ["sim", "record", "a.tlog"], ["sim", "--help"], ["sim"], ["run", "--record", "x"], [],
])
def test_the_subcommand_spelling_is_left_alone(args: list[str]) -> None:
    assert legacy_sim.rewrite(args) == (args, None)


def test_the_flag_spelling_records_the_same_bytes_and_says_it_is_deprecated(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    old, new = tmp_path / "old.tlog", tmp_path / "new.tlog"
    code, _, err = _main(capsys, "sim", "--record", str(old), "--duration", "5", "--seed", "4")
    assert code == 0, err
    assert _lines(err) == ["warning: `hilnav sim --record FILE` is deprecated; use "
                           "`hilnav sim record FILE`"]
    code, _, err = _main(capsys, "sim", "record", str(new), "--duration", "5", "--seed", "4")
    assert code == 0 and _lines(err) == []
    assert old.read_bytes() == new.read_bytes()


@pytest.mark.parametrize(("flag", "target", "extra", "needle"), [
    ("--live", "udpout:127.0.0.1:9", ["--speed", "0"], "speed"),
    ("--px4", "tcp:127.0.0.1:4560", [], "tcpin:HOST:PORT"),
    ("--ardupilot", "tcp:127.0.0.1:9002", [], "expected udpin:HOST:PORT"),
])
def test_the_flag_spelling_of_a_mode_gives_the_same_result(
        capsys: pytest.CaptureFixture[str], flag: str, target: str, extra: list[str],
        needle: str) -> None:
    """The same (bad-input) result as the subcommand, plus the one deprecation line."""
    mode = flag.removeprefix("--")
    code_new, out_new, err_new = _main(capsys, "sim", mode, target, "--duration", "5", *extra)
    code_old, out_old, err_old = _main(capsys, "sim", flag, target, "--duration", "5", *extra)
    assert code_new == code_old == 2 and needle in err_new
    assert out_old == out_new
    assert _lines(err_old) == [
        f"warning: `hilnav sim {flag} URL` is deprecated; use `hilnav sim {mode} URL`",
        *_lines(err_new)]


@pytest.mark.parametrize(("args", "needle"), [
    (["--px4", "tcpin:h:1", "--live", "udpout:h:2"], "--px4 and --live are two ways to fly"),
    (["--live", "udpout:h:2", "--ardupilot", "udpin:h:1"],
     "--ardupilot and --live are two ways to fly"),
    (["--px4", "tcpin:h:1", "--ardupilot", "udpin:h:1"], "two autopilots: give one"),
    (["--record", "a.tlog", "--actuator-map", "m.yaml"], "it needs --px4 URL"),
    (["--live"], "--live needs a value"),
])
def test_conflicting_flags_are_one_line_and_exit_2(
        capsys: pytest.CaptureFixture[str], args: list[str], needle: str) -> None:
    code, out, err = _main(capsys, "sim", *args)
    assert code == 2 and out == ""
    assert len(_lines(err)) == 1 and needle in err
