"""What build is running: versions and the state of each compiled kernel."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from importlib.metadata import version

from hil.build_info import COMPILED, FORCED, KERNEL_MODULES, NOT_BUILT, build_info


def test_build_info_names_the_versions_and_every_kernel() -> None:
    info = build_info()
    assert info["hilnav"] == version("hilnav") and info["numpy"] == version("numpy")
    assert info["jsbsim"] == version("jsbsim")
    kernels = info["kernels"]
    assert isinstance(kernels, dict) and set(kernels) == set(KERNEL_MODULES)
    assert set(kernels.values()) <= {COMPILED, FORCED, NOT_BUILT}


def test_forcing_the_python_references_is_reported_as_such() -> None:
    """GIVEN ``HILNAV_KERNEL=python`` WHEN a process reports its build THEN no kernel says
    compiled: each is forced (built but not used) or not built at all."""
    out = subprocess.run(
        [sys.executable, "-c", "import json; from hil.build_info import kernel_states; "
                               "print(json.dumps(kernel_states()))"],
        env={**os.environ, "HILNAV_KERNEL": "python"}, capture_output=True, text=True,
        check=True)
    states = json.loads(out.stdout)
    assert set(states) == set(KERNEL_MODULES)
    assert set(states.values()) <= {FORCED, NOT_BUILT}
