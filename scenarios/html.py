"""A self-contained HTML page of a run, for a navigation engineer: the verdict and what was flown
(aircraft, sensors, air, seed), the criteria, the plots, the outage and event tables, and the
counters last, folded.

Everything is inside the one file (inline CSS, PNG plots as base64 ``data:`` URIs, no script,
no external link), so the page can be attached to a CI job or mailed and still opens offline.
"""

from __future__ import annotations

import base64
import html
import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, NamedTuple

_CSS = """
body { font-family: system-ui, -apple-system, "Segoe UI", sans-serif; margin: 1.5em 2em;
       color: #1d2330; }
h1 { margin-bottom: 0.2em; }
h2 { margin-top: 1.6em; border-bottom: 1px solid #ccd; padding-bottom: 0.2em; }
table { border-collapse: collapse; margin: 0.6em 0; font-size: 0.92em; }
th, td { border: 1px solid #ccd; padding: 0.25em 0.6em; text-align: right; }
th { background: #eef0f5; }
td.l, th.l { text-align: left; }
tr.pass td { background: #e3f6e5; }
tr.fail td { background: #fbe1e1; }
.badge { display: inline-block; padding: 0.2em 0.8em; border-radius: 0.3em; color: #fff;
         font-weight: bold; }
.badge.pass { background: #2e7d32; } .badge.fail { background: #c62828; }
.meta { color: #556; }
figure { margin: 1em 0; } figure img { max-width: 100%; border: 1px solid #dde; }
figcaption { color: #556; font-size: 0.9em; }
table.setup th { background: none; border: none; padding-right: 1.2em; }
table.setup td { border: none; }
details { margin: 0.6em 0; } summary { cursor: pointer; color: #335; }
"""


def _e(x: Any) -> str:
    return html.escape(str(x), quote=True)


def _num(v: Any, fmt: str = ".3g") -> str:
    if v is None:
        return "–"
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return format(v, fmt) if math.isfinite(v) else "–"
    return _e(v)


def _table(head: Sequence[str], rows: Sequence[Sequence[str]],
           classes: Sequence[str] | None = None, left: int = 1) -> str:
    """An HTML table; cell strings are already escaped. The first ``left`` columns align left."""
    th = "".join(f'<th class="l">{h}</th>' if i < left else f"<th>{h}</th>"
                 for i, h in enumerate(head))
    out = [f"<table><thead><tr>{th}</tr></thead><tbody>"]
    for k, row in enumerate(rows):
        cls = f' class="{classes[k]}"' if classes else ""
        tds = "".join(f'<td class="l">{c}</td>' if i < left else f"<td>{c}</td>"
                      for i, c in enumerate(row))
        out.append(f"<tr{cls}>{tds}</tr>")
    out.append("</tbody></table>")
    return "".join(out)


# Human names of the scorecard's keys: (label, unit); a key not listed is spelt out from its
# name (underscores to spaces, a unit suffix to its unit).
_LABELS: dict[str, tuple[str, str]] = {
    "horizontal_rmse_m": ("horizontal RMSE", "m"),
    "vertical_rmse_m": ("vertical RMSE", "m"),
    "horizontal_max_m": ("horizontal max", "m"),
    "vertical_max_m": ("vertical max", "m"),
    "roll_rmse_deg": ("roll RMSE", "deg"),
    "pitch_rmse_deg": ("pitch RMSE", "deg"),
    "yaw_rmse_deg": ("yaw RMSE", "deg"),
    "cep50_m": ("CEP50", "m"),
    "cep95_m": ("CEP95", "m"),
    "nees_mean": ("mean NEES", ""),
    "nees_dof": ("NEES degrees of freedom", ""),
    "rms_z_pos": ("rms(error / σ), position", ""),
    "rms_z_vel": ("rms(error / σ), velocity", ""),
    "rms_z_att": ("rms(error / σ), attitude", ""),
    "within_3sigma_pos": ("share within 3σ, position", ""),
    "within_3sigma_vel": ("share within 3σ, velocity", ""),
    "within_3sigma_att": ("share within 3σ, attitude", ""),
    "horizontal": ("horizontal", ""),
    "vertical": ("vertical", ""),
    "reconverge_s": ("re-converged after", "s"),
    "detect_s": ("detected after", "s"),
    "horizontal_error_m_at": ("horizontal error at", "m"),
    "vertical_error_m_at": ("vertical error at", "m"),
    "containment_3sigma": ("inside the 3σ bound", "share"),
    "gnss_on": ("GNSS on", ""),
    "outages": ("GNSS outages", ""),
    "events": ("events", ""),
}
_UNIT_SUFFIXES = (("_mps2", "m/s²"), ("_mps", "m/s"), ("_deg", "deg"), ("_rad", "rad"),
                  ("_us", "µs"), ("_ms", "ms"), ("_m", "m"), ("_s", "s"), ("_hz", "Hz"),
                  ("_pa", "Pa"))


def human(key: str) -> tuple[str, str]:
    """``(label, unit)`` of a scorecard key: ``horizontal_rmse_m`` -> ("horizontal RMSE",
    "m"); unknown keys are spelt out from their name."""
    if key in _LABELS:
        return _LABELS[key]
    for suffix, unit in _UNIT_SUFFIXES:
        if key.endswith(suffix):
            return key[: -len(suffix)].replace("_", " "), unit
    return key.replace("_", " "), ""


def metric_label(path: str) -> str:
    """A criterion's metric path in words: ``outages.horizontal_error_m_at.60`` -> "GNSS
    outages: horizontal error at 60 s (m)"."""
    parts = path.split(".")
    words: list[str] = []
    unit = ""
    for k, part in enumerate(parts):
        if part.isdigit() and k > 0 and parts[k - 1].endswith("_at"):
            words[-1] += f" {part} s"
            continue
        label, u = human(part)
        words.append(label)
        unit = u or unit
    text = words[0] + (": " + " ".join(words[1:]) if len(words) > 1 else "")
    return f"{text} ({unit})" if unit and unit != "share" else text


def _criteria(summary: Mapping[str, Any]) -> str:
    crit = list(summary.get("criteria") or [])
    if not crit:
        return "<p>No pass criteria.</p>"
    rows, cls = [], []
    for c in crit:
        ok = bool(c.get("ok"))
        rows.append([_e(c.get("name")), _e(metric_label(str(c.get("path", "")))),
                     _num(c.get("value")), _e(c.get("op", "<=")), _num(c.get("limit")),
                     "pass" if ok else "FAIL"])
        cls.append("pass" if ok else "fail")
    return _table(["criterion", "metric", "value", "", "limit", "result"], rows, cls, left=2)


def _at(row: Mapping[str, Any], key: str, s: str) -> Any:
    d = row.get(key) or {}
    return d.get(s) if isinstance(d, Mapping) else None


def _outages(summary: Mapping[str, Any]) -> str:
    outs = list(summary.get("outages") or [])
    if not outs:
        return "<p>No GNSS outage.</p>"
    head = ["#", "start (s)", "end (s)", "horizontal RMSE (m)", "horizontal max (m)",
            "at 10 s (m)", "at 30 s (m)", "at 60 s (m)", "at 120 s (m)", "at 300 s (m)",
            "CEP50 (m)", "CEP95 (m)", "vertical RMSE (m)", "inside 3σ, horizontal",
            "inside 3σ, vertical", "re-converged after (s)"]
    rows = []
    for i, o in enumerate(outs):
        c3 = o.get("containment_3sigma") or {}
        rows.append([
            str(i + 1), _num(o.get("start_s"), ".1f"), _num(o.get("end_s"), ".1f"),
            _num(o.get("horizontal_rmse_m")), _num(o.get("horizontal_max_m")),
            *(_num(_at(o, "horizontal_error_m_at", s)) for s in ("10", "30", "60", "120", "300")),
            _num(o.get("cep50_m")), _num(o.get("cep95_m")), _num(o.get("vertical_rmse_m")),
            _pct(c3.get("horizontal")), _pct(c3.get("vertical")),
            _num(o.get("reconverge_s"), ".1f"),
        ])
    comp_rows = []
    for i, o in enumerate(outs):
        r = o.get("rmse") or {}
        comp_rows.append([str(i + 1), _num(r.get("lat_deg"), ".3e"), _num(r.get("lon_deg"), ".3e"),
                          _num(r.get("h_m")), _num(r.get("vn_mps")), _num(r.get("ve_mps")),
                          _num(r.get("vd_mps"))])
    return (_table(head, rows)
            + "<details><summary>RMSE per component (the papers' table)</summary>"
            + _table(["#", "latitude (deg)", "longitude (deg)", "height (m)",
                      "north velocity (m/s)", "east velocity (m/s)", "down velocity (m/s)"],
                     comp_rows)
            + "</details>")


def _pct(v: Any) -> str:
    return f"{100.0 * v:.1f} %" if isinstance(v, int | float) and math.isfinite(v) else "–"


def _events(summary: Mapping[str, Any]) -> str:
    evs = list(summary.get("events") or [])
    if not evs:
        return "<p>No scored scenario event.</p>"
    rows, cls = [], []
    for ev in evs:
        early = ev.get("reaccepted_early")
        detected = ev.get("detect_s") is not None
        rows.append([
            _e(str(ev.get("type", "")).replace("_", " ")), _e(ev.get("sensor", "")),
            _num(ev.get("start_s"), ".1f"), _num(ev.get("end_s"), ".1f"),
            _num(ev.get("detect_s"), ".2f") if detected else "never",
            _num(ev.get("max_horizontal_m")), _num(ev.get("max_vertical_m")),
            _num(early), _num(ev.get("reaccept_count")), _num(ev.get("reconverge_s"), ".1f"),
        ])
        cls.append("fail" if early else ("pass" if detected else ""))
    return _table(["event", "sensor", "start (s)", "end (s)", "detected after (s)",
                   "max horizontal error (m)", "max vertical error (m)",
                   "bad fix re-accepted early", "re-acceptances", "re-converged after (s)"],
                  rows, cls, left=2)


def _flat(d: Mapping[str, Any], prefix: str = "") -> list[tuple[str, Any]]:
    out: list[tuple[str, Any]] = []
    for k, v in d.items():
        name = f"{prefix}{k}"
        if isinstance(v, Mapping):
            out += _flat(v, name + ".")
        elif isinstance(v, int | float | str | bool) or v is None:
            out.append((name, v))
    return out


def _kv(d: Mapping[str, Any], fmt: str = ".4g") -> str:
    items = _flat(d)
    if not items:
        return "<p>–</p>"
    return _table(["", "value"], [[_e(k), _num(v, fmt)] for k, v in items])


def _labelled(d: Mapping[str, Any], fmt: str = ".3g") -> str:
    """A flat mapping of scorecard keys as a two-column table with human labels and units."""
    rows = []
    for key, v in d.items():
        if isinstance(v, Mapping):
            continue
        label, unit = human(str(key))
        shown = _pct(v) if key.startswith("within_") else _num(v, fmt)
        rows.append([_e(label + (f" ({unit})" if unit and unit != "share" else "")), shown])
    return _table(["", "value"], rows) if rows else "<p>–</p>"


_PLOT_ORDER = ("ground_track", "horizontal_vertical", "errors", "drift")
_PLOT_CAPTIONS = {
    "ground_track": "Ground track: truth and estimate, outages and events marked",
    "horizontal_vertical": "Horizontal and vertical error with the filter's 3σ bound",
    "errors": "Errors per axis (position, velocity, attitude) with ±3σ",
    "drift": "Horizontal error against time into each outage",
    "autopilot_side_by_side": "hilnav and the autopilot's estimate against truth (with an "
                              "unaided baseline: the unaided autopilot of a second flight too)",
}


def _plots(plots: Sequence[Path] | Mapping[str, Path]) -> str:
    if isinstance(plots, Mapping):
        items = list(plots.items())
    else:
        rank = {name: k for k, name in enumerate(_PLOT_ORDER)}
        ordered = sorted(plots, key=lambda p: rank.get(Path(p).stem, len(rank)))
        items = [(_PLOT_CAPTIONS.get(Path(p).stem, Path(p).stem), p) for p in ordered]
    out = []
    for caption, p in items:
        data = base64.b64encode(Path(p).read_bytes()).decode("ascii")
        out.append(f'<figure><img alt="{_e(caption)}" src="data:image/png;base64,{data}">'
                   f"<figcaption>{_e(caption)}</figcaption></figure>")
    return "".join(out)


def side_by_side_rows(summary: Mapping[str, Any]) -> list[tuple[str, Any, Any]]:
    """``(figure, hilnav's value, the autopilot's value)`` rows of a run with an autopilot in
    the loop (its ``autopilot`` section): GNSS-on accuracy, then per outage (matched by start)
    the horizontal RMSE / max / error at 10, 30, 60 s, CEP50 / 95, vertical RMSE and
    re-convergence. Empty without an autopilot section."""
    ap = summary.get("autopilot")
    if not ap:
        return []
    rows: list[tuple[str, Any, Any]] = []
    on_h, on_a = summary.get("gnss_on") or {}, ap.get("gnss_on") or {}
    for key, label in (("horizontal_rmse_m", "horizontal RMSE (m)"),
                       ("vertical_rmse_m", "vertical RMSE (m)"),
                       ("roll_rmse_deg", "roll RMSE (deg)"), ("pitch_rmse_deg", "pitch RMSE (deg)"),
                       ("yaw_rmse_deg", "yaw RMSE (deg)")):
        rows.append((f"GNSS on: {label}", on_h.get(key), on_a.get(key)))
    theirs = {round(o["start_s"], 3): o for o in ap.get("outages") or []}
    for i, o in enumerate(summary.get("outages") or []):
        a = theirs.get(round(o["start_s"], 3), {})
        name = f"outage {i + 1} ({o['start_s']:.0f}-{o['end_s']:.0f} s)"
        for key, label in (("horizontal_rmse_m", "horizontal RMSE (m)"),
                           ("horizontal_max_m", "horizontal max (m)"),
                           ("cep50_m", "CEP50 (m)"), ("cep95_m", "CEP95 (m)"),
                           ("vertical_rmse_m", "vertical RMSE (m)"),
                           ("reconverge_s", "re-converged after (s)")):
            rows.append((f"{name}: {label}", o.get(key), a.get(key)))
        for at in ("10", "30", "60"):
            rows.append((f"{name}: horizontal error at {at} s (m)",
                         (o.get("horizontal_error_m_at") or {}).get(at),
                         (a.get("horizontal_error_m_at") or {}).get(at)))
    return rows


class CardRow(NamedTuple):
    """A row of the aided-vs-unaided card: a figure of the four estimates (``values``: hilnav,
    the aided autopilot, the unaided autopilot, hilnav in the unaided flight), or a ratio of
    horizontal RMSE against its ``target`` (``values`` None)."""

    name: str
    values: tuple[Any, Any, Any, Any] | None
    ratio: float | None = None
    target: float | None = None

    @property
    def met(self) -> bool | None:
        if self.ratio is None or self.target is None:
            return None
        return self.ratio <= self.target


def aided_unaided_rows(summary: Mapping[str, Any]) -> list[CardRow]:
    """The rows of a run scored beside its unaided baseline (``autopilot.aided_vs_unaided``):
    per outage the horizontal RMSE, max and error at 30 and 60 s of each estimate, then the two
    ratios of horizontal RMSE with their targets. Empty without a baseline."""
    card = (summary.get("autopilot") or {}).get("aided_vs_unaided")
    if not card:
        return []
    keys = ("hilnav", "aided", "unaided", "hilnav_unaided_flight")
    targets = card.get("targets") or {}
    rows: list[CardRow] = []
    for i, o in enumerate(card.get("outages") or []):
        end = o.get("end_s")
        name = f"outage {i + 1} ({o['start_s']:.0f}-{'?' if end is None else f'{end:.0f}'} s)"
        for label, key, at in (("horizontal RMSE (m)", "horizontal_rmse_m", None),
                               ("horizontal max (m)", "horizontal_max_m", None),
                               ("horizontal error at 30 s (m)", "horizontal_error_m_at", "30"),
                               ("horizontal error at 60 s (m)", "horizontal_error_m_at", "60")):
            got = [None if o.get(k) is None else o[k].get(key) for k in keys]
            if at is not None:
                got = [None if v is None else v.get(at) for v in got]
            if any(v is not None for v in got):
                rows.append(CardRow(f"{name}: {label}", (got[0], got[1], got[2], got[3])))
        for key, label in (("aided_over_hilnav", "aided / hilnav"),
                           ("aided_over_unaided", "aided / unaided")):
            rows.append(CardRow(f"{name}: {label} horizontal RMSE", None, o.get(key),
                                targets.get(key)))
    return rows


def _verdict(ok: bool | None) -> str:
    return "–" if ok is None else ("met" if ok else "missed")


def _aided_unaided(summary: Mapping[str, Any]) -> str:
    ap = summary["autopilot"]
    card = ap["aided_vs_unaided"]
    source = _e(ap.get("source"))
    rows = []
    for row in aided_unaided_rows(summary):
        if row.values is not None:
            rows.append([_e(row.name), *(_num(v) for v in row.values)])
        else:
            rows.append([_e(f"{row.name} (target <= {_num(row.target)})"), "",
                         f"{_num(row.ratio)} ({_verdict(row.met)})", "", ""])
    run = (ap.get("unaided") or {}).get("run") or {}
    flight = (f"<p>Unaided flight: {_e(run.get('folder'))}, seed {_e(run.get('seed'))}, "
              f"{_num(run.get('sim_duration_s'), '.1f')} s, "
              + ("passed" if run.get("passed") else "failed: " + _e(
                  "; ".join(run.get("failures") or []) or "its criteria")) + "</p>"
              if run else "")
    return "".join([
        _table(["figure", "hilnav", f"{source} aided by hilnav", f"{source} unaided",
                "hilnav, unaided flight"], rows),
        f"<p>Not compared: {_e(card['problem'])}</p>" if card.get("problem") else "",
        flight,
        f"<p class=meta>{_e(card.get('note'))}</p>",
    ])


def _autopilot(summary: Mapping[str, Any]) -> str:
    ap = summary["autopilot"]
    source = _e(ap.get("source"))
    state = [f"connected: {_num(ap.get('connected'))}",
             f"stalled: {_e(ap.get('stalled') or 'no')}"]
    if ap.get("problem"):
        state.append(f"not scored: {_e(ap['problem'])}")
    rows = [[_e(name), _num(h), _num(a)] for name, h, a in side_by_side_rows(summary)]
    health = ap.get("health") or {}
    texts = [f"{_num(t.get('time_s'), '.1f')} s: {_e(t.get('text'))}"
             for t in health.get("warnings") or []]
    est = health.get("estimator") or {}
    return "".join([
        f"<p>{source}: {' · '.join(state)}</p>",
        _table(["figure", "hilnav", source], rows),
        "<p>No NEES for the autopilot: its telemetry carries no covariance of the nine "
        "navigation errors.</p>",
        f"<p>{source} declared its absolute horizontal position lost at "
        f"{_e(est.get('pos_horiz_abs_lost_s') or '–')} s, regained at "
        f"{_e(est.get('pos_horiz_abs_regained_s') or '–')} s.</p>",
        "<p>Warnings and failsafes: " + ("; ".join(texts) if texts else "none") + "</p>",
        _script(ap),
        _kv({"counters": ap.get("counters") or {}, "link": ap.get("link") or {}}),
    ])


def _script(ap: Mapping[str, Any]) -> str:
    """What the scenario told the autopilot and when it was confirmed (empty without a
    script)."""
    script = ap.get("script")
    if not script:
        return ""
    rows = [[_e(step.get("step")), _e(step.get("status")), _num(step.get("started_s"), ".1f"),
             _num(step.get("done_s"), ".1f")] for step in script.get("steps") or []]
    times = (f"armed at {_num(ap.get('armed_s'), '.1f')} s, in {_e(script.get('mode') or '–')} "
             f"at {_num(ap.get('mode_reached_s'), '.1f')} s, trim released at "
             f"{_num(ap.get('trim_released_s'), '.1f')} s")
    failure = script.get("failure")
    return "".join([
        "<p>Scripted: " + times + (f"; failed: {_e(failure)}" if failure else "") + "</p>",
        _table(["step", "status", "started (s)", "confirmed (s)"], rows, left=2),
    ])


def _setup(summary: Mapping[str, Any]) -> str:
    """What was flown: the scenario's aircraft, sensors, air, seed and duration."""
    setup = summary.get("setup") or {}
    sensors = setup.get("sensors") or {}
    wind = setup.get("wind_ned_mps")
    rows: list[tuple[str, str]] = [
        ("scenario", _e(summary.get("scenario", ""))
         + (f" — {_e(setup['description'])}" if setup.get("description") else "")),
        ("aircraft", _e(setup.get("aircraft", "–"))),
        ("flight plan", _e(setup.get("plan", "–"))),
        ("IMU", _e(sensors.get("imu", "–"))), ("GNSS", _e(sensors.get("gnss", "–"))),
        ("barometer", _e(sensors.get("baro", "–"))),
        ("magnetometer", _e(sensors.get("mag", "–"))),
        ("pitot", _e(sensors.get("pitot", "–"))),
        ("wind N, E, D (m/s)", ", ".join(f"{w:g}" for w in wind) if wind else "–"),
        ("turbulence", _e(setup.get("turbulence", "–"))),
        ("seed", _e(summary.get("seed"))),
        ("flown", f"{_num(summary.get('sim_duration_s'), '.1f')} s simulated in "
                  f"{_num(summary.get('wall_s'), '.1f')} s"),
        ("navigation", f"bridge {_e(summary.get('bridge'))} · altitude "
                       f"{_e(summary.get('altitude'))}"),
    ]
    if summary.get("ended"):
        rows.append(("ended early", _e(summary["ended"])))
    body = "".join(f"<tr><th class=l>{k}</th><td class=l>{v}</td></tr>" for k, v in rows)
    return f"<table class=setup><tbody>{body}</tbody></table>"


def render_html(summary: Mapping[str, Any], plots: Sequence[Path] | Mapping[str, Path]) -> str:
    """The page as a string (see :func:`write_html`): the verdict and what was flown, the
    criteria, the plots, the outage and event tables, then the rest, folded."""
    passed = bool(summary.get("passed"))
    title = f"hilnav · {summary.get('scenario', 'run')}"
    badge = '<span class="badge pass">PASSED</span>' if passed else \
        '<span class="badge fail">FAILED</span>'
    parts = [
        "<!DOCTYPE html>", '<html lang="en"><head><meta charset="utf-8">',
        f"<title>{_e(title)}</title><style>{_CSS}</style></head><body>",
        f"<h1>{_e(title)} {badge}</h1>", _setup(summary),
        "<h2>Pass criteria</h2>", _criteria(summary),
        "<h2>Plots</h2>", _plots(plots),
        "<h2>GNSS outages</h2>", _outages(summary),
        "<h2>Scenario events</h2>", _events(summary),
        "<h2>GNSS-on accuracy</h2>", _labelled(summary.get("gnss_on") or {}),
        "<h2>Consistency</h2>", _labelled(summary.get("nees") or {}),
        "<p class=meta>Share of the run inside the filter's 3σ bound: horizontal "
        f"{_pct((summary.get('containment_3sigma') or {}).get('horizontal'))}, vertical "
        f"{_pct((summary.get('containment_3sigma') or {}).get('vertical'))}.</p>",
    ]
    if summary.get("autopilot"):
        parts += ["<h2>Both estimates on one scorecard</h2>", _autopilot(summary)]
    if (summary.get("autopilot") or {}).get("aided_vs_unaided"):
        parts += ["<h2>Aided by hilnav and unaided</h2>", _aided_unaided(summary)]
    if summary.get("rejections_outside_events"):
        parts += ["<h2>Rejections outside outages and events</h2>",
                  _labelled(summary["rejections_outside_events"])]
    parts += ["<h2>Counters</h2>",
              '<details id="counters"><summary>Health counters of the filter, decoder and '
              "fault injector</summary>", _kv(summary.get("health") or {}), "</details>",
              "</body></html>"]
    return "\n".join(parts) + "\n"


def write_html(
    summary: Mapping[str, Any], plots: Sequence[Path] | Mapping[str, Path], path: Path
) -> None:
    """Write a self-contained HTML report of a run.

    Parameters
    ----------
    summary : mapping
        The ``summary.json`` dict.
    plots : sequence of Path, or mapping of caption to Path
        PNG files, embedded as base64 ``data:`` URIs (captions default to the file stems).
    path : Path
        The ``.html`` file to write (UTF-8).
    """
    path.write_text(render_html(summary, plots), encoding="utf-8")
