"""The switch between the compiled kernels and their Python references, for ``fusion``
(``fusion/_strapdown.c``, ``fusion/_update.c``) and ``sim`` (``sim/_simkernel.c``), which never
import each other: one variable name, one rule. No I/O here: the caller hands in the
environment."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Final

KERNEL_ENV: Final = "HILNAV_KERNEL"
"""Environment variable that makes every compiled kernel's module use its Python reference,
when set to ``python`` (case and surrounding blanks ignored)."""


def python_forced(environ: Mapping[str, str]) -> bool:
    """True when ``environ`` (e.g. ``os.environ``) asks for the Python references."""
    return environ.get(KERNEL_ENV, "").strip().lower() == "python"
