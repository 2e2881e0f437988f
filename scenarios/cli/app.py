"""The ``hilnav`` command line: a thin typed layer over the pipeline, the scorer and the services.

This module holds the Typer application and the console entry :func:`main`; the commands live
in one module per group (:mod:`~scenarios.cli.commands_sim`,
:mod:`~scenarios.cli.commands_fusion`, :mod:`~scenarios.cli.commands_live`,
:mod:`~scenarios.cli.commands_run`), the exit codes in :mod:`scenarios.cli.errors`. Importing
it loads no heavy library: each command imports what it runs, so ``--help`` stays fast.
"""

from __future__ import annotations

import sys
from typing import Annotated, Any

import typer
from typer.core import TyperGroup

from scenarios.cli import legacy_sim
from scenarios.cli.commands_fusion import fusion
from scenarios.cli.commands_live import check, monitor, router, up
from scenarios.cli.commands_run import campaign, compare, demo, list_choices, replay, run, schema
from scenarios.cli.commands_sim import sim_app
from scenarios.cli.errors import bad_input
from scenarios.cli.first_run import kernel_notice
from scenarios.cli.output import console, err_console
from scenarios.cli.quick_exit import QUICK_EXIT_COMMANDS, command_of, freeze_for_exit

__all__ = ["app", "main"]


class _SimFirst(TyperGroup):
    """Lists ``sim`` first in ``hilnav --help``, as the flight everything else uses (Typer
    lists groups after commands)."""

    def list_commands(self, ctx: Any) -> list[str]:
        names = super().list_commands(ctx)
        return sorted(names, key=lambda name: name != "sim")


app = typer.Typer(
    name="hilnav",
    cls=_SimFirst,
    help="Hardware-in-the-loop navigation: fly JSBSim, stream MAVLink sensors, fuse, score.",
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    add_completion=False,
)


def _print_version(value: bool) -> None:
    """``--version``: hilnav's version, the libraries its numbers depend on and each compiled
    kernel's state (:func:`hil.build_info.build_info`)."""
    if not value:
        return
    from hil.build_info import build_info

    info = build_info()
    kernels = info.pop("kernels")
    console.print(f"hilnav {info.pop('hilnav')} ("
                  + ", ".join(f"{name} {v}" for name, v in info.items()) + ")",
                  highlight=False, markup=False)
    for name, state in dict(kernels).items():  # type: ignore[call-overload]
        console.print(f"  {name}: {state}", highlight=False, markup=False)
    raise typer.Exit()


@app.callback()
def _options(
    version: Annotated[bool, typer.Option(
        "--version", is_eager=True, callback=_print_version,
        help="Print hilnav's version and its compiled kernels' state, and exit.")] = False,
) -> None:
    """Hardware-in-the-loop navigation: fly JSBSim, stream MAVLink sensors, fuse, score."""


app.add_typer(sim_app)
app.command()(fusion)
app.command()(monitor)
app.command()(router)
app.command()(check)
app.command()(up)
app.command()(replay)
app.command()(demo)
app.command("list")(list_choices)
app.command()(run)
app.command()(compare)
app.command()(schema)
app.command()(campaign)


def main(argv: list[str] | None = None) -> None:
    """The ``hilnav`` console entry: rewrite the flag spelling of ``hilnav sim``'s modes
    (:mod:`scenarios.cli.legacy_sim`), run the command (typer exits with its code), then, for
    an offline command with every file closed, skip the interpreter's final teardown
    collections (:mod:`scenarios.cli.quick_exit`)."""
    args = sys.argv[1:] if argv is None else list(argv)
    try:
        args, deprecation = legacy_sim.rewrite(args)
    except ValueError as exc:
        raise SystemExit(bad_input(str(exc)).exit_code) from None
    if deprecation is not None:
        err_console.print(deprecation, highlight=False, markup=False)
    notice = kernel_notice()
    if notice is not None:
        err_console.print(f"[yellow]note:[/] {notice}", highlight=False)
    try:
        app(args)
    finally:
        if command_of(args) in QUICK_EXIT_COMMANDS:
            freeze_for_exit()


if __name__ == "__main__":
    main()
