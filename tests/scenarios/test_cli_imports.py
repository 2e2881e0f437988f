"""The command line loads only what a command runs.

GIVEN a fresh interpreter, WHEN it imports the ``hilnav`` command line (what ``hilnav --help``
and every command pay before doing anything), THEN none of the heavy libraries is loaded: each
command imports the filter, the simulator, the plots or the bus itself.
"""

from __future__ import annotations

import json
import subprocess
import sys

HEAVY = ("numpy", "scipy", "pydantic", "matplotlib", "pymavlink", "zenoh", "dask", "jsbsim",
         "yaml", "mcap", "pyulog", "fusion.config", "hil", "sim")


def test_importing_the_command_line_loads_no_heavy_library() -> None:
    code = ("import json, sys\n"
            "import scenarios.cli.app\n"
            f"print(json.dumps(sorted(m for m in {HEAVY!r} if m in sys.modules)))\n")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          check=True, timeout=60)
    assert json.loads(proc.stdout) == []


def test_the_choices_in_the_help_are_the_ones_the_fusion_validates() -> None:
    from fusion import config
    from fusion.bridging import registry
    from fusion.choices import ALTITUDE_METHODS, BRIDGE_METHODS

    assert registry.BRIDGE_METHODS is BRIDGE_METHODS
    assert config.ALTITUDE_METHODS is ALTITUDE_METHODS
    assert set(ALTITUDE_METHODS) == set(config.AltitudeMethodName.__args__)  # type: ignore[attr-defined]


def test_the_filter_of_a_run_loads_no_optimizer() -> None:
    """GIVEN a fresh interpreter, WHEN it imports what a run's filter is built from (the
    configuration, the filter, the bridging registry with its neural comparators), THEN
    ``scipy.optimize`` is not loaded: only training a NARX network needs it (~0.1-0.2 s)."""
    code = ("import json, sys\n"
            "import fusion.bridging.registry, fusion.config, fusion.filter, fusion.regressors\n"
            "print(json.dumps('scipy.optimize' in sys.modules))\n")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          check=True, timeout=60)
    assert json.loads(proc.stdout) is False


def test_the_runner_loads_the_autopilot_modules_only_when_one_flies() -> None:
    """GIVEN a fresh interpreter, WHEN it imports the runner (``hilnav run``'s set-up), THEN
    the autopilot's backend, telemetry, link and scoring are not loaded: a flight without an
    autopilot never uses them (``AutopilotRun`` imports them when one flies)."""
    code = ("import json, sys\n"
            "import scenarios.runner\n"
            "print(json.dumps(sorted(m for m in sys.modules if m.startswith(\n"
            "    ('hil.autopilot', 'hil.link', 'scenarios.autopilot_summary')))))\n")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          check=True, timeout=60)
    assert json.loads(proc.stdout) == []
