"""What ``hilnav`` prints: the consoles, the progress bar and the scorecard's lines.

Results go to stdout (:data:`console`); progress, warnings and errors to stderr
(:data:`err_console`), so a command's output can be piped.
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from rich.console import Console
from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn

__all__ = [
    "FLYING", "FlightProgress", "console", "err_console", "fmt", "print_autopilot", "print_live",
    "print_summary", "progress_bar", "progress_line", "say_waiting_for_autopilot", "say_warning",
    "scripted_events", "speed_sentence", "warn_input",
]

err_console = Console(stderr=True, soft_wrap=True)
console = Console(soft_wrap=True)


FLYING = "flying"
"""The label of a flight's progress (``up`` reads the sim child's lines by it)."""

ScriptedEvent = tuple[float, float | None, str]
"""A scripted event for the progress line: start and end (None: to the end), simulated s, and
its name."""


def scripted_events(setup: Any) -> list[ScriptedEvent]:
    """The scripted events of a :class:`hil.pipeline.SimSetup` (GNSS windows and faults), for
    the progress line."""
    events: list[ScriptedEvent] = [
        (w.start_s, w.start_s + w.duration_s, "GNSS off") for w in setup.gnss_off]
    for f in setup.faults or ():
        events.append((f.start_s, f.end_s, str(f.type).replace("_", " ")))
    return events


def _event_at(events: list[ScriptedEvent], t_s: float) -> str:
    return ", ".join(name for start, end, name in events
                     if start <= t_s and (end is None or t_s < end))


class FlightProgress:
    """Simulated time against wall time: a rich bar on a terminal, a plain line every 10 % of
    the flight otherwise (CI logs). The real-time factor counts from the first call (a wait
    for an autopilot or a peer is not flight)."""

    _STEPS = 10

    def __init__(self, total_s: float, label: str, events: list[ScriptedEvent],
                 bar: Progress | None, *, quiet: bool = False) -> None:
        self.quiet = quiet
        self.total_s = total_s
        self.label = label
        self.events = events
        self.bar = bar
        self.task = bar.add_task(label, total=total_s, info="") if bar is not None else None
        self.first: tuple[float, float] | None = None
        self.next_step = 1

    def __call__(self, t_s: float, info: str | None = None, *,
                 event_time_s: float | None = None) -> None:
        """Tell the flight is at ``t_s`` simulated seconds; ``info`` (the real-time factor
        and event as another process measured them) replaces this one's own;
        ``event_time_s``: the time in the flight's own timeline, when ``t_s`` counts over
        several flights."""
        if self.quiet:
            return
        if info is None:
            info = self._info(t_s, t_s if event_time_s is None else event_time_s)
        if self.bar is not None and self.task is not None:
            self.bar.update(self.task, completed=t_s, info=info)
            return
        if self.total_s <= 0 or t_s < self.next_step * self.total_s / self._STEPS:
            return
        while t_s >= self.next_step * self.total_s / self._STEPS:
            self.next_step += 1
        err_console.print(progress_line(self.label, t_s, self.total_s, info),
                          highlight=False, markup=False)

    def restart_clock(self) -> None:
        """Count the real-time factor from the next call (a new flight begins)."""
        self.first = None

    def _info(self, t_s: float, event_time_s: float) -> str:
        now = time.monotonic()
        if self.first is None:
            self.first = (t_s, now)
        t0_s, wall0 = self.first
        rtf = f"{(t_s - t0_s) / (now - wall0):.1f}x real time" \
            if now > wall0 and t_s > t0_s else ""
        return ", ".join(x for x in (rtf, _event_at(self.events, event_time_s)) if x)


def progress_line(label: str, t_s: float, total_s: float, info: str = "") -> str:
    """The plain progress line: ``LABEL: T/TOTAL s simulated (P %), INFO``."""
    pct = 100.0 * t_s / total_s if total_s > 0 else 0.0
    return f"{label}: {t_s:.0f}/{total_s:.0f} s simulated ({pct:.0f} %)" + (
        f", {info}" if info else "")


@contextlib.contextmanager
def progress_bar(total_s: float, label: str, *, quiet: bool = False,
                 events: list[ScriptedEvent] | None = None
                 ) -> Iterator[FlightProgress]:
    """Progress over ``total_s`` simulated seconds on stderr: a transient bar on a terminal, a
    plain line every 10 % of the flight otherwise, nothing with ``quiet``; each shows the
    real-time factor and the scripted event under way (``events``). Yields the
    ``progress(t_s)`` callback the runners take (``progress(t_s, info)`` with another
    process's own real-time factor and event)."""
    if quiet or not err_console.is_terminal:
        yield FlightProgress(total_s, label, list(events or ()), None, quiet=quiet)
        return
    bar = Progress(
        TextColumn(f"[bold]{label}"),
        BarColumn(),
        TextColumn("{task.completed:>7.0f}/{task.total:.0f} s"),
        TimeRemainingColumn(),
        TextColumn("{task.fields[info]}"),
        console=err_console,
        transient=True,
    )
    with bar:
        yield FlightProgress(total_s, label, list(events or ()), bar)


def say_warning(text: str) -> None:
    """One warning line on stderr."""
    err_console.print(f"[yellow]warning:[/] {text}", highlight=False)


def speed_sentence(realtime_factor: float, target: float) -> tuple[str, bool]:
    """``N.NNx real time`` against the ``target`` speed, and whether the target was missed
    (by more than 5 %: the pacing's own jitter is not a miss)."""
    if realtime_factor < 0.95 * target:
        return (f"{realtime_factor:.2f}x real time: missed the {target:g}x target (the machine "
                "was too slow)", True)
    return f"{realtime_factor:.2f}x real time, target {target:g}x", False


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


def say_waiting_for_autopilot(scn: Any, out: Path | None = None) -> None:
    """Where a scenario with an autopilot at the controls waits for it (or, with
    ``autopilot.binary``, which binary hilnav starts and where its output goes)."""
    ap = scn.autopilot
    if ap.binary is not None:
        log = "autopilot.log" if out is None else out / "autopilot.log"
        err_console.print(
            f"starting {scn.autopilot_path(ap.binary)} ({ap.kind} SITL) on free loopback ports; "
            f"waiting up to {ap.connect_timeout_s:g} s for it; its output -> {log}",
            highlight=False, markup=False)
        return
    err_console.print(
        f"waiting up to {ap.connect_timeout_s:g} s for {ap.kind} on "
        f"{ap.link or 'its default link'}; its estimate is recorded from "
        f"{ap.telemetry or 'nowhere (telemetry: null)'}", highlight=False)
    from scenarios.cli.autopilot_hints import ardupilot_command, px4_command

    side = px4_command() if ap.kind == "px4" else ardupilot_command(
        scn.start_state(), given_as="autopilot.mavlink")
    err_console.print(f"start {side}", highlight=False, markup=False)
    err_console.print("(or give --autopilot-binary PATH: hilnav starts the SITL binary itself)",
                      highlight=False, markup=False)


def print_autopilot(s: dict[str, Any]) -> None:
    """The side-by-side lines of a run with an autopilot in the loop (nothing without one)."""
    from scenarios.html import side_by_side_rows

    ap = s.get("autopilot")
    if not ap:
        return
    not_denied = ap.get("outages_not_denied") or []
    console.print(f"[bold]hilnav vs {ap['source']}[/] (same truth, "
                  + ("same GNSS denial)" if not not_denied else
                     f"but {len(not_denied)} GNSS outage(s) of hilnav's NOT denied to "
                     f"{ap['source']})"), highlight=False)
    for name, mine, theirs in side_by_side_rows(s):
        if mine is None and theirs is None:
            continue
        console.print(f"  {name}: hilnav {fmt(mine)} | {ap['source']} {fmt(theirs)}",
                      highlight=False)
    _print_aided_unaided(s)
    script = ap.get("script")
    if script:
        times = [(what, ap.get(key)) for what, key in (
            ("armed", "armed_s"), (f"in {script.get('mode')}", "mode_reached_s"),
            ("flying its controls (trim released)", "trim_released_s"))]
        done = ", ".join(f"{what} at {t:.1f} s" for what, t in times if t is not None)
        console.print(f"  scripted: {done or 'never armed'}", highlight=False)
    if ap.get("problem"):
        err_console.print(f"[yellow]warning:[/] {ap['source']}'s estimate not scored: "
                          f"{ap['problem']}", highlight=False)
    for t in (ap.get("health") or {}).get("failsafes") or []:
        console.print(f"  {ap['source']} at {t['time_s']:.1f} s: {t['text']}", highlight=False)


def _print_aided_unaided(s: dict[str, Any]) -> None:
    """The aided-vs-unaided lines of a run flown with its unaided baseline (nothing without
    one)."""
    from scenarios.html import aided_unaided_rows

    ap = s["autopilot"]
    card = ap.get("aided_vs_unaided")
    if not card:
        return
    run = (ap.get("unaided") or {}).get("run") or {}
    source = ap["source"]
    console.print(f"[bold]hilnav vs {source} aided by hilnav vs {source} unaided[/] (unaided: a "
                  f"second flight of the same seed, {run.get('folder') or 'not flown'})",
                  highlight=False)
    for row in aided_unaided_rows(s):
        if row.values is None:
            verdict = "" if row.met is None else (" met" if row.met else " MISSED")
            console.print(f"  {row.name}: {fmt(row.ratio)} (target <= {fmt(row.target)})"
                          f"{verdict}", highlight=False)
            continue
        hilnav, aided, unaided, again = row.values
        console.print(f"  {row.name}: hilnav {fmt(hilnav)} | aided {fmt(aided)} | unaided "
                      f"{fmt(unaided)} (hilnav in that flight {fmt(again)})", highlight=False)
    if card.get("problem"):
        err_console.print(f"[yellow]warning:[/] unaided baseline not compared: "
                          f"{card['problem']}", highlight=False)
    for failure in run.get("failures") or []:
        err_console.print(f"[yellow]warning:[/] the unaided flight: {failure}", highlight=False)
