"""What build of hilnav is running: its version, the versions of the libraries its numbers
depend on, and, for each compiled kernel, whether the compiled code or its Python reference
runs (and why). ``hilnav --version`` prints it and every ``summary.json`` records it, so a
scorecard says what produced it."""

from __future__ import annotations

import importlib.util
import platform
from importlib.metadata import PackageNotFoundError, version
from typing import Final

KERNEL_MODULES: Final = ("fusion._strapdown", "fusion._update", "sim._simkernel")
"""The compiled kernels (C sources beside them), built by ``pip install`` with a C compiler."""

COMPILED: Final = "compiled"
FORCED: Final = "python (HILNAV_KERNEL=python)"
NOT_BUILT: Final = "python (not built: no C compiler at install)"


def _version(dist: str) -> str:
    try:
        return version(dist)
    except PackageNotFoundError:
        return "not installed"


def kernel_states() -> dict[str, str]:
    """Each compiled kernel's state: :data:`COMPILED`, :data:`FORCED` or :data:`NOT_BUILT`."""
    from fusion import error_model, strapdown
    from sim import kernel as sim_kernel

    running = {"fusion._strapdown": strapdown.KERNEL, "fusion._update": error_model.KERNEL,
               "sim._simkernel": sim_kernel.KERNEL}
    out = {}
    for name in KERNEL_MODULES:
        if running[name] == "c":
            out[name] = COMPILED
        elif importlib.util.find_spec(name) is not None:
            out[name] = FORCED
        else:
            out[name] = NOT_BUILT
    return out


def build_info() -> dict[str, object]:
    """``{hilnav, python, numpy, scipy, jsbsim, pymavlink, kernels}``: versions as installed
    and :func:`kernel_states`."""
    return {
        "hilnav": _version("hilnav"),
        "python": platform.python_version(),
        "numpy": _version("numpy"),
        "scipy": _version("scipy"),
        "jsbsim": _version("jsbsim"),
        "pymavlink": _version("pymavlink"),
        "kernels": kernel_states(),
    }
