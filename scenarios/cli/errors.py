"""Exit codes of ``hilnav``: bad input -> 2 with one line, a failed run -> 1.

Exit codes (docs/architecture.md): 0 success / pass, 1 run failed (criteria failed, aircraft
crashed), 2 bad input (one line on stderr naming what is wrong, never a traceback). The input
checks here raise ValueError, which :func:`cli_errors` turns into that one line.
"""

from __future__ import annotations

import functools
import sys
from collections.abc import Callable
from pathlib import Path
from typing import ParamSpec, TypeVar

import typer

from scenarios.cli.output import err_console

__all__ = ["RunFailed", "check_choice", "cli_errors", "out_dir", "out_file"]

P = ParamSpec("P")
R = TypeVar("R")


class RunFailed(Exception):
    """The run happened but did not succeed (exit code 1)."""


def _bad_input_message(exc: ValueError) -> str:
    """One line for a bad value: pydantic's first validation error as ``where: what``."""
    pydantic = sys.modules.get("pydantic")  # not imported: exc cannot be a ValidationError
    if pydantic is None or not isinstance(exc, pydantic.ValidationError):
        return str(exc)
    e = exc.errors()[0]
    loc = ".".join(str(p) for p in e["loc"]) or exc.title
    return f"{loc}: {e['msg']}"


def bad_input(message: str) -> typer.Exit:
    """Say ``message`` as the one line of bad input; the caller raises the returned exit 2."""
    err_console.print(f"[red]error:[/] {message}", highlight=False)
    return typer.Exit(2)


def cli_errors(func: Callable[P, R]) -> Callable[P, R]:
    """Turn bad input into a one-line message and exit code 2; failed runs into exit 1."""

    @functools.wraps(func)
    def wrapper(*args: P.args, **kwargs: P.kwargs) -> R:
        try:
            return func(*args, **kwargs)
        except ValueError as exc:  # pydantic's ValidationError included
            raise bad_input(_bad_input_message(exc)) from None
        except FileNotFoundError as exc:
            raise bad_input(str(exc)) from None
        except OSError as exc:  # a path the user named cannot be written or read
            where = f": {exc.filename}" if exc.filename else ""
            raise bad_input(f"{exc.strerror or exc}{where}") from None
        except RunFailed as exc:
            err_console.print(f"[red]failed:[/] {exc}", highlight=False)
            raise typer.Exit(1) from None

    return wrapper


def out_dir(path: Path, option: str = "--out") -> Path:
    """``path`` can be (or become) a folder: not a file, no file on the way to it."""
    for p in (path, *path.parents):
        if p.exists():
            if not p.is_dir():
                what = "is a file" if p == path else f"lies under the file {p}"
                raise ValueError(f"{option} {path} {what}; give a folder")
            break
    return path


def out_file(path: Path, option: str) -> Path:
    """``path`` can be (or become) a file: not a folder, no file on the way to it."""
    if path.is_dir():
        raise ValueError(f"{option} {path} is a folder; give a file name")
    out_dir(path.parent, f"{option}'s folder")
    return path


def check_choice(name: str, value: str, valid: tuple[str, ...] | list[str]) -> str:
    """``value`` if it is one of ``valid``; ValueError naming the choices otherwise."""
    if value not in valid:
        raise ValueError(f"unknown {name} {value!r}; valid choices: {', '.join(valid)}")
    return value
