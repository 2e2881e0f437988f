"""Build of the optional compiled kernels: the INS (``fusion._strapdown``), the covariance time
update's Phi fill and process noise (``fusion._update``) and the simulator's (``sim._simkernel``);
everything else about the distribution is in pyproject.toml.

The kernels must give CPython's bits (docs/development.md, "Compiled kernels"), hence the flags:
``-O2`` without ``-ffast-math`` or ``-march=native``, ``-ffp-contract=off`` (gcc would fuse
``a * b + c`` into one FMA instruction where the target has one, e.g. aarch64 or ``-march`` with
FMA, and the fused result is rounded once instead of twice), and no builtin ``sin`` / ``cos``
(gcc would merge ``sin(x)`` and ``cos(x)`` into one ``sincos`` call, whose bits libm does not
promise to equal the two calls CPython's ``math`` makes). ``optional=True``: without a C compiler
``pip install`` still succeeds and ``fusion.strapdown`` / ``sim.imu`` run their Python references
(same numbers, slower)."""

import platform
import sys

from setuptools import Extension, setup

if sys.platform == "win32":
    # MSVC: precise floating point, which does not contract a * b + c (VS 2022 and later)
    _FLAGS = ["/O2", "/fp:precise"]
else:
    _FLAGS = ["-O2", "-ffp-contract=off", "-fno-fast-math", "-fno-builtin-sin", "-fno-builtin-cos"]
    if platform.machine().lower() in {"i386", "i486", "i586", "i686", "x86"}:
        # 32-bit x86 computes in the x87's 80-bit registers: round every operation to double as
        # CPython does (it stores each result in a float object) instead of keeping 80 bits
        _FLAGS.append("-fexcess-precision=standard")

setup(
    ext_modules=[
        Extension(
            "fusion._strapdown",
            sources=["fusion/_strapdown.c"],
            extra_compile_args=_FLAGS,
            optional=True,
        ),
        # the covariance time update's Phi fill (fusion.error_model), the same discipline
        Extension(
            "fusion._update",
            sources=["fusion/_update.c"],
            extra_compile_args=_FLAGS,
            optional=True,
        ),
        Extension(
            "sim._simkernel",
            sources=["sim/_simkernel.c"],
            extra_compile_args=_FLAGS,
            optional=True,
        ),
    ]
)
