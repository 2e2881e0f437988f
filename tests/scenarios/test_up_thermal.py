"""``hilnav up``'s IMU thermal options: the simulated part and the fusion's strategy.

GIVEN a user who rehearses a warm-up outage on the live chain, WHEN they give ``up`` the
thermal options of ``hilnav fusion`` (and the simulator's part), THEN the fusion and sim
children get them as options those commands accept, and a bad choice is one line, exit 2,
before anything starts.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
import typer
from typer.testing import CliRunner

from scenarios.cli.app import app
from scenarios.cli.up import UpOptions, filter_args

runner = CliRunner()


def _parsed(command: str, args: list[str]) -> dict[str, Any]:
    """What ``hilnav COMMAND ARGS`` parses to (no command runs)."""
    cmd: Any = typer.main.get_command(app)
    for name in command.split():
        cmd = cmd.get_command(cmd.make_context("hilnav", [name, "--help"],
                                               resilient_parsing=True), name)
        assert cmd is not None, name
    return dict(cmd.make_context(command, list(args)).params)


def test_up_hands_its_thermal_options_to_the_fusion_and_the_sim(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import scenarios.cli.up

    seen: list[UpOptions] = []

    def fake_run_up(options: UpOptions, **_kw: Any) -> None:
        seen.append(options)

    monkeypatch.setattr(scenarios.cli.up, "run_up", fake_run_up)
    cal = tmp_path / "unit.params"
    res = runner.invoke(app, ["up", "--out", str(tmp_path), "--quiet", "--imu-thermal",
                              "icm20948", "--thermal-cal", str(cal), "--thermal-part",
                              "icm20948"])
    assert res.exit_code == 0, res.output
    opts = seen[0]
    assert (opts.imu_thermal, opts.thermal, opts.thermal_cal, opts.thermal_part) == (
        "icm20948", "off", cal, "icm20948")
    # the fusion child parses what up passes it, to the same values
    fusion = _parsed("fusion", filter_args(opts))
    assert fusion["thermal_cal"] == cal.resolve()
    assert (fusion["thermal"], fusion["thermal_part"]) == ("off", "icm20948")
    assert (fusion["imu"], fusion["bridge"]) == (opts.imu, opts.bridge)
    # and the simulator child takes the part
    sim = _parsed("sim live", ["udpout:127.0.0.1:9", "--imu-thermal", opts.imu_thermal])
    assert sim["imu_thermal"] == "icm20948"


@pytest.mark.parametrize(("args", "needle"), [
    (["--thermal", "cal"], "--thermal cal needs --thermal-cal FILE"),
    (["--thermal", "warm"], "unknown thermal mode 'warm'"),
    (["--thermal", "blind", "--thermal-part", "bmi089"], "preset 'bmi089'; valid"),
    (["--imu-thermal", "bmi089"], "preset 'bmi089'; valid"),
])
def test_a_bad_thermal_choice_of_up_is_one_line_exit_2(
        tmp_path: Path, args: list[str], needle: str) -> None:
    res = runner.invoke(app, ["up", "--out", str(tmp_path), "--quiet", *args])
    assert res.exit_code == 2
    assert needle in res.output and "Traceback" not in res.output
    assert len([ln for ln in res.output.splitlines() if ln.strip()]) == 1
    assert not (tmp_path / "fusion.log").exists()  # nothing started
