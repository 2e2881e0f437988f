"""Said once per installed version, at the first run: the compiled kernels were not built.

``pip install`` builds three C kernels (:data:`hil.build_info.KERNEL_MODULES`) when a C
compiler is there; without one hilnav runs their Python references, correct but several times
slower, and the install only printed a warning the user may never have seen. The first command
says so with the fix, and leaves a marker file under ``$XDG_CACHE_HOME/hilnav`` (default
``~/.cache/hilnav``) named after the version so it is said once; a folder that cannot be
written only means it is said again.

The check looks for the kernels' files beside their packages without importing anything
heavy (the command line's start-up stays light); ``hilnav --version`` says what really runs.
"""

from __future__ import annotations

import contextlib
import importlib.machinery
import importlib.util
import os
from pathlib import Path

__all__ = ["KERNEL_FILES", "cache_dir", "kernel_notice", "missing_kernels"]

KERNEL_FILES = ("fusion._strapdown", "fusion._update", "sim._simkernel")
"""The compiled kernels, as :data:`hil.build_info.KERNEL_MODULES` names them (not imported
here: ``hil`` is heavy)."""


def missing_kernels() -> list[str]:
    """The kernels whose compiled file is not beside its package's sources."""
    missing = []
    for name in KERNEL_FILES:
        package, module = name.split(".")
        spec = importlib.util.find_spec(package)  # a top-level spec imports nothing
        folders = list(spec.submodule_search_locations or ()) if spec is not None else []
        if not any((Path(folder) / f"{module}{suffix}").is_file() for folder in folders
                   for suffix in importlib.machinery.EXTENSION_SUFFIXES):
            missing.append(name)
    return missing


def cache_dir() -> Path:
    """``$XDG_CACHE_HOME/hilnav``, else ``~/.cache/hilnav``."""
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "hilnav"


def kernel_notice(missing: list[str] | None = None) -> str | None:
    """The notice when a kernel was not built and this version has not said it yet (the
    marker is written here); None otherwise. Never raises for an unwritable cache."""
    missing = missing_kernels() if missing is None else missing
    if not missing:
        return None
    from importlib.metadata import PackageNotFoundError, version

    try:
        installed = version("hilnav")
    except PackageNotFoundError:
        installed = "unknown"
    marker = cache_dir() / f"kernels-not-built-{installed}"
    with contextlib.suppress(OSError):
        if marker.exists():
            return None
    with contextlib.suppress(OSError):
        marker.parent.mkdir(parents=True, exist_ok=True)
        marker.write_text(", ".join(missing) + "\n")
    return (f"the compiled kernels {', '.join(missing)} were not built (no C compiler when "
            "hilnav was installed): their Python references run instead, the same numbers "
            "several times slower. To build them, install a C compiler (e.g. `sudo apt-get "
            "install gcc`), then reinstall: `pip install --force-reinstall --no-deps -e .` in "
            "the source folder (`pip install --force-reinstall --no-deps hilnav` for an "
            "install from a package). Said once; `hilnav --version` shows the kernels' state.")
