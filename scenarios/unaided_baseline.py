"""The unaided baseline of a run in which hilnav navigates the autopilot: three estimates and
the unaided autopilot on one scorecard.

With ``autopilot.aiding: hilnav`` and ``unaided_baseline: true`` (or ``hilnav run
--unaided-baseline``) the scenario is flown twice, one after the other
(:func:`run_with_unaided_baseline`):

1. the **unaided baseline**: the same scenario and seed with ``aiding: disabled`` (nothing is
   sent to the autopilot and the script sets its aiding parameters off), a complete run folder
   of its own in ``unaided/`` of the run's folder;
2. the **aided run** into the run's folder, scored as any run with an autopilot, plus the
   baseline: ``summary.json``'s ``autopilot.unaided`` (the baseline's autopilot section, with
   its run's verdict and hilnav's outage errors in that run) and ``autopilot.aided_vs_unaided``
   (:func:`aided_vs_unaided`): per GNSS outage the rows ``hilnav``, ``aided`` and ``unaided``
   (horizontal RMSE, max, error at 30 and 60 s) and the ratios ``aided_over_hilnav`` and
   ``aided_over_unaided`` of the horizontal RMSEs against their targets (1.5 and 0.5).

The simulator is deterministic: the same scenario and seed give the same sensor error
sequences, wind, turbulence and fault timeline in both flights. The autopilot is not (its
scheduling, and on other navigation it steers another path), so the aircraft's path differs
between the two flights; each estimate is scored against the truth of its own flight, and the
unaided row is a second sample of the autopilot, not a replay.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import AbstractContextManager, contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Final

if TYPE_CHECKING:
    from hil.tracks import Track
    from scenarios.autopilot_summary import ScoredAutopilot
    from scenarios.metrics import Errors
    from scenarios.runner import ProgressFn, RunResult
    from scenarios.schema import Scenario

__all__ = ["AIDED_OVER_HILNAV_TARGET", "AIDED_OVER_UNAIDED_TARGET", "UNAIDED_DIR",
           "UnaidedBaseline", "aided_vs_unaided", "run_with_unaided_baseline",
           "unaided_scenario"]

UNAIDED_DIR: Final = "unaided"
"""The baseline's run folder, inside the aided run's."""
AIDED_OVER_HILNAV_TARGET: Final = 1.5
"""The aided autopilot's horizontal RMSE in an outage at most this many times hilnav's."""
AIDED_OVER_UNAIDED_TARGET: Final = 0.5
"""... and at most this many times the unaided autopilot's."""
#: Seconds within which outages of the two flights are the same window (their gaps start at
#: the last fix before the denial, the same sample in both).
_SAME_WINDOW_S: Final = 1.0
_ROW_KEYS: Final = ("horizontal_rmse_m", "horizontal_max_m")
_AT_S: Final = ("30", "60")

NOTE: Final = (
    "The unaided row is a second flight of the same scenario and seed (aiding disabled): the same "
    "sensor errors, wind and fault timeline, but the autopilot is not deterministic and flies "
    "another path on other navigation, so each estimate is scored against its own flight's "
    "truth.")

RunHook = Callable[[str, "Scenario"], AbstractContextManager["ProgressFn | None"]]
"""Entered around each flight with its role (``"unaided"``, ``"aided"``) and scenario; yields
the flight's progress callback (the CLI: a message and a progress bar; a test: the autopilot
peer that flight meets)."""


def unaided_scenario(scenario: Scenario) -> Scenario:
    """``scenario`` as its unaided baseline: ``aiding: disabled``, no baseline of its own."""
    ap = scenario.autopilot.model_copy(update={"aiding": "disabled", "unaided_baseline": False})
    return scenario.model_copy(update={"autopilot": ap})


@dataclass(frozen=True)
class UnaidedFlight:
    """What the baseline's scoring left for the aided run's scorecard."""

    summary: dict[str, Any]
    """The baseline run's ``summary.json``."""
    truth: Track
    """Its flight's truth."""
    track: Track | None
    """The unaided autopilot's estimate (None: nothing scored, its section says why)."""
    errors: Errors | None


class UnaidedBaseline:
    """The unaided flight, recorded by the baseline run's scoring (:meth:`record`, or
    :meth:`absent` when it never flew) and added to the aided run's (:meth:`add_to`)."""

    def __init__(self, folder: Path) -> None:
        self.folder = folder
        self.flight: UnaidedFlight | None = None
        self.problem: str | None = None
        """Why there is no unaided flight to compare with (set by :meth:`absent`)."""

    def record(self, summary: dict[str, Any], truth: Track, side: ScoredAutopilot) -> None:
        """The baseline run was scored: keep its summary, truth and the autopilot's track."""
        self.flight = UnaidedFlight(summary, truth, side.track, side.errors)

    def absent(self, why: str) -> None:
        """The baseline run ended before anything was scored (``why``: its sentence)."""
        self.problem = why

    def add_to(self, summary: dict[str, Any]) -> str | None:
        """Put ``autopilot.unaided`` and ``autopilot.aided_vs_unaided`` into the aided run's
        ``summary`` (which has its ``autopilot`` section). Returns the failure sentence when
        there is no unaided outage to compare with, else None."""
        ap = summary["autopilot"]
        flight = self.flight
        base = None if flight is None else flight.summary
        unaided = None if base is None else dict(base.get("autopilot") or {})
        if unaided is not None and base is not None:
            unaided["run"] = {
                "folder": str(self.folder), "seed": base.get("seed"),
                "passed": base.get("passed"), "failures": base.get("failures") or [],
                "sim_duration_s": base.get("sim_duration_s"),
            }
        ap["unaided"] = unaided
        card = aided_vs_unaided(summary, ap, unaided, base,
                                problem=self.problem if unaided is None else None)
        ap["aided_vs_unaided"] = card
        rows = card["outages"]
        if rows and all(r["unaided"] is None for r in rows):
            why = card.get("problem") or "no GNSS outage of the unaided flight was scored"
            return f"the unaided baseline ({self.folder}) has nothing to compare: {why}"
        return None


def _row(outage: Mapping[str, Any] | None) -> dict[str, Any] | None:
    if outage is None:
        return None
    at = outage.get("horizontal_error_m_at") or {}
    row = {k: outage.get(k) for k in _ROW_KEYS}
    row["horizontal_error_m_at"] = {s: at.get(s) for s in _AT_S}
    return row


def _match(outages: Sequence[Mapping[str, Any]] | None,
           start_s: float) -> Mapping[str, Any] | None:
    return next((o for o in outages or () if abs(float(o["start_s"]) - start_s)
                 <= _SAME_WINDOW_S), None)


def _ratio(num: Mapping[str, Any] | None, den: Mapping[str, Any] | None) -> float | None:
    a = None if num is None else num.get("horizontal_rmse_m")
    b = None if den is None else den.get("horizontal_rmse_m")
    if a is None or b is None or not b > 0.0:
        return None
    return float(a) / float(b)


def aided_vs_unaided(
    summary: Mapping[str, Any],
    aided: Mapping[str, Any],
    unaided: Mapping[str, Any] | None,
    unaided_summary: Mapping[str, Any] | None,
    *,
    problem: str | None = None,
) -> dict[str, Any]:
    """The card of hilnav, the autopilot aided by it and the unaided autopilot.

    Parameters
    ----------
    summary : the aided run's summary (hilnav's ``outages``, scored against its truth).
    aided : its ``autopilot`` section (the autopilot aided by hilnav, same truth).
    unaided : the baseline's ``autopilot`` section (None: no baseline flight was scored).
    unaided_summary : the baseline run's summary (hilnav in that flight).
    problem : why there is no baseline flight.

    Returns
    -------
    dict
        ``{note, targets, problem, outages}``; per outage of hilnav's (matched by start, within
        1 s, with the autopilots' denied outages), ``start_s``, ``end_s``, the rows ``hilnav``,
        ``aided``, ``unaided`` and ``hilnav_unaided_flight`` (each ``{horizontal_rmse_m,
        horizontal_max_m, horizontal_error_m_at: {"30", "60"}}`` or None when that estimate has
        no such outage scored), ``aided_over_hilnav`` and ``aided_over_unaided`` (ratios of
        horizontal RMSE, None without both) and ``meets`` (each ratio against its target, None
        without the ratio).
    """
    rows = []
    for o in summary.get("outages") or []:
        start = float(o["start_s"])
        mine = _row(o)
        theirs = _row(_match(aided.get("outages"), start))
        alone = None if unaided is None else _row(_match(unaided.get("outages"), start))
        again = None if unaided_summary is None else _row(
            _match(unaided_summary.get("outages"), start))
        over_hilnav, over_unaided = _ratio(theirs, mine), _ratio(theirs, alone)
        rows.append({
            "start_s": start, "end_s": o.get("end_s"),
            "hilnav": mine, "aided": theirs, "unaided": alone, "hilnav_unaided_flight": again,
            "aided_over_hilnav": over_hilnav, "aided_over_unaided": over_unaided,
            "meets": {
                "aided_over_hilnav": None if over_hilnav is None
                else over_hilnav <= AIDED_OVER_HILNAV_TARGET,
                "aided_over_unaided": None if over_unaided is None
                else over_unaided <= AIDED_OVER_UNAIDED_TARGET,
            },
        })
    if problem is None and unaided is not None and unaided.get("problem"):
        problem = f"its estimate was not scored: {unaided['problem']}"
    return {
        "note": NOTE,
        "targets": {"aided_over_hilnav": AIDED_OVER_HILNAV_TARGET,
                    "aided_over_unaided": AIDED_OVER_UNAIDED_TARGET},
        "problem": problem,
        "outages": rows,
    }


@contextmanager
def _no_hook(_role: str, _scenario: Scenario) -> Iterator[ProgressFn | None]:
    yield None


def run_with_unaided_baseline(
    scenario: Scenario,
    out_dir: Path,
    *,
    bridge: str | None = None,
    altitude: str | None = None,
    tlog: bool = True,
    reports: bool = True,
    each_run: RunHook | None = None,
) -> RunResult:
    """Fly the unaided baseline of ``scenario`` (into ``out_dir / unaided``), then
    ``scenario`` aided by hilnav (into ``out_dir``) scored beside it (see the module
    docstring).

    A baseline that never flew (:class:`~scenarios.runner.AutopilotAbsent`) leaves the aided
    run to fly, which then fails naming why; any other error stops both.
    """
    from scenarios.runner import AutopilotAbsent, run_scenario

    if scenario.autopilot.aiding != "hilnav":
        raise ValueError("an unaided baseline compares the autopilot aided by hilnav with it "
                         f"unaided: set autopilot.aiding to hilnav (it is "
                         f"{scenario.autopilot.aiding!r})")
    hook = each_run or _no_hook
    folder = out_dir / UNAIDED_DIR
    baseline = UnaidedBaseline(folder)
    base = unaided_scenario(scenario)
    with hook("unaided", base) as progress:
        try:
            first = run_scenario(base, folder, bridge=bridge, altitude=altitude,
                                 progress=progress, tlog=tlog, reports=reports,
                                 baseline=baseline)
        except AutopilotAbsent as exc:
            baseline.absent(str(exc))
            first = None
    with hook("aided", scenario) as progress:
        result = run_scenario(scenario, out_dir, bridge=bridge, altitude=altitude,
                              progress=progress, tlog=tlog, reports=reports,
                              baseline=baseline)
    if first is not None:
        result.files.append(first.out_dir / "summary.json")
    return result
