"""What ``hilnav`` prints: the consoles, the progress bar and the scorecard's lines.

Results go to stdout (:data:`console`); progress, warnings and errors to stderr
(:data:`err_console`), so a command's output can be piped.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterator
from typing import Any

from rich.console import Console
from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn

__all__ = [
    "console", "err_console", "fmt", "print_autopilot", "print_live", "print_summary",
    "progress_bar", "say_waiting_for_autopilot", "warn_input",
]

err_console = Console(stderr=True, soft_wrap=True)
console = Console(soft_wrap=True)


@contextlib.contextmanager
def progress_bar(total_s: float, label: str) -> Iterator[Callable[[float], None]]:
    """A transient bar on stderr over ``total_s`` simulated seconds (hidden when stderr is not
    a terminal); yields the ``progress(t_s)`` callback the runners take."""
    bar = Progress(
        TextColumn(f"[bold]{label}"),
        BarColumn(),
        TextColumn("{task.completed:>7.0f}/{task.total:.0f} s"),
        TimeRemainingColumn(),
        console=err_console,
        transient=True,
        disable=not err_console.is_terminal,
    )
    with bar:
        task = bar.add_task(label, total=total_s)
        yield lambda t: bar.update(task, completed=t)


def fmt(v: Any, spec: str = ".2f") -> str:
    """``v`` formatted with ``spec``; ``n/a`` for None and NaN."""
    return "n/a" if v is None or (isinstance(v, float) and v != v) else format(v, spec)


def print_summary(s: dict[str, Any]) -> None:
    """The scorecard's headline: GNSS-on errors, each outage, NEES."""
    on = s.get("gnss_on", {})
    console.print(
        f"GNSS on: horizontal RMSE {fmt(on.get('horizontal_rmse_m'))} m, vertical "
        f"{fmt(on.get('vertical_rmse_m'))} m, roll/pitch/yaw "
        f"{fmt(on.get('roll_rmse_deg'), '.3f')}/{fmt(on.get('pitch_rmse_deg'), '.3f')}/"
        f"{fmt(on.get('yaw_rmse_deg'), '.3f')} deg"
    )
    for o in s.get("outages", []):
        at = o["horizontal_error_m_at"]
        console.print(
            f"outage {o['start_s']:.0f}-{o['end_s']:.0f} s: horizontal RMSE "
            f"{fmt(o['horizontal_rmse_m'])} m, max {fmt(o['horizontal_max_m'])} m, at 10/30/60 s "
            f"{fmt(at.get('10'), '.1f')}/{fmt(at.get('30'), '.1f')}/{fmt(at.get('60'), '.1f')} m"
        )
    nees = s.get("nees", {})
    if nees:
        console.print(f"NEES (9 dof, GNSS on): {fmt(nees.get('nees_mean'))}")


def print_live(s: dict[str, Any]) -> None:
    """The live run's link line: frames lost and the realtime factor."""
    live = s.get("live", {})
    console.print(f"live: lost frames {live.get('lost_frames')}, "
                  f"realtime factor {fmt(s.get('realtime_factor'))}")


def warn_input(s: dict[str, Any]) -> None:
    """Say on stderr when the log was damaged or cut (the scorecard has it in ``input``), when
    the settling time was shortened to fit the log (``settling``) and what the reference
    lacks (``reference``)."""
    for section in ("settling", "reference", "alignment"):
        warning = s.get(section, {}).get("warning")
        if warning:
            err_console.print(f"[yellow]warning:[/] {warning}", highlight=False)
    inp = s.get("input", {})
    if inp.get("corrupt"):
        err_console.print("[yellow]warning:[/] the ULog is damaged: pyulog skipped a corrupt "
                          "stretch; scored what was readable", highlight=False)
    if inp.get("logger_dropouts"):
        err_console.print(f"[yellow]warning:[/] the vehicle's logger dropped data "
                          f"{inp['logger_dropouts']} times ({inp['logger_dropout_ms']} ms in "
                          "all): samples are missing there", highlight=False)
    if inp.get("truncated") or inp.get("bad_frames") or inp.get("skipped_bytes"):
        err_console.print(
            f"[yellow]warning:[/] the log is damaged: {inp.get('bad_frames', 0)} bad frames, "
            f"{inp.get('skipped_bytes', 0)} bytes skipped"
            + (", the last record is truncated" if inp.get("truncated") else "")
            + f"; scored over {s.get('sim_duration_s', 0):.0f} s", highlight=False)


def say_waiting_for_autopilot(scn: Any) -> None:
    """Where a scenario with an autopilot at the controls waits for it."""
    ap = scn.autopilot
    err_console.print(
        f"waiting up to {ap.connect_timeout_s:g} s for {ap.kind} on "
        f"{ap.link or 'its default link'}; its estimate is recorded from "
        f"{ap.telemetry or 'nowhere (telemetry: null)'}", highlight=False)


def print_autopilot(s: dict[str, Any]) -> None:
    """The side-by-side lines of a run with an autopilot in the loop (nothing without one)."""
    from scenarios.html import side_by_side_rows

    ap = s.get("autopilot")
    if not ap:
        return
    console.print(f"[bold]hilnav vs {ap['source']}[/] (same truth, same GNSS denial)",
                  highlight=False)
    for name, mine, theirs in side_by_side_rows(s):
        if mine is None and theirs is None:
            continue
        console.print(f"  {name}: hilnav {fmt(mine)} | {ap['source']} {fmt(theirs)}",
                      highlight=False)
    if ap.get("problem"):
        err_console.print(f"[yellow]warning:[/] {ap['source']}'s estimate not scored: "
                          f"{ap['problem']}", highlight=False)
    for t in (ap.get("health") or {}).get("failsafes") or []:
        console.print(f"  {ap['source']} at {t['time_s']:.1f} s: {t['text']}", highlight=False)
