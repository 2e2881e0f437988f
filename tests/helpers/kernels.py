"""The compiled kernels in tests: import one if it was built, and fail its tests with the reason
when it was not (the test command needs a C compiler: docs/development.md,
"Compiled kernels")."""

from __future__ import annotations

import importlib
from types import ModuleType
from typing import Any

import pytest


def compiled_kernel(name: str) -> Any:
    """The compiled module ``name`` (e.g. ``"fusion._strapdown"``), or None if it was not built.
    Typed ``Any``: the tests call its functions directly."""
    try:
        module: ModuleType = importlib.import_module(name)
    except ImportError:  # pragma: no cover - require_built says what to do
        return None
    return module


def require_built(kernel: ModuleType | None, name: str, what: str) -> None:
    """Fail the calling test, saying why, when the kernel ``name`` (``what`` it is) is missing."""
    if kernel is None:
        pytest.fail(
            f"{name} ({what}) is not importable: the test command needs a C compiler (gcc or "
            "clang) when the package is installed (pip install -e '.[test]'); without one pip "
            "silently installs the Python references only"
        )
