"""A self-contained HTML page of a run: verdict, criteria, outages, events, health, plots.

Everything is inside the one file (inline CSS, PNG plots as base64 ``data:`` URIs, no script,
no external link), so the page can be attached to a CI job or mailed and still opens offline.
"""

from __future__ import annotations

import base64
import html
import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

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


def _criteria(summary: Mapping[str, Any]) -> str:
    crit = list(summary.get("criteria") or [])
    if not crit:
        return "<p>No pass criteria.</p>"
    rows, cls = [], []
    for c in crit:
        ok = bool(c.get("ok"))
        rows.append([_e(c.get("name")), _num(c.get("value")), _e(c.get("op", "<=")),
                     _num(c.get("limit")), "pass" if ok else "FAIL"])
        cls.append("pass" if ok else "fail")
    return _table(["criterion", "value", "", "limit", "result"], rows, cls)


def _at(row: Mapping[str, Any], key: str, s: str) -> Any:
    d = row.get(key) or {}
    return d.get(s) if isinstance(d, Mapping) else None


def _outages(summary: Mapping[str, Any]) -> str:
    outs = list(summary.get("outages") or [])
    if not outs:
        return "<p>No GNSS outage.</p>"
    head = ["#", "start (s)", "end (s)", "h RMSE (m)", "h max (m)", "h@10 s", "h@30 s",
            "h@60 s", "h@120 s", "CEP50 (m)", "CEP95 (m)", "v RMSE (m)", "3σ h", "3σ v",
            "re-converge (s)"]
    rows = []
    for i, o in enumerate(outs):
        c3 = o.get("containment_3sigma") or {}
        rows.append([
            str(i + 1), _num(o.get("start_s"), ".1f"), _num(o.get("end_s"), ".1f"),
            _num(o.get("horizontal_rmse_m")), _num(o.get("horizontal_max_m")),
            *(_num(_at(o, "horizontal_error_m_at", s)) for s in ("10", "30", "60", "120")),
            _num(o.get("cep50_m")), _num(o.get("cep95_m")), _num(o.get("vertical_rmse_m")),
            _num(c3.get("horizontal"), ".3f"), _num(c3.get("vertical"), ".3f"),
            _num(o.get("reconverge_s"), ".1f"),
        ])
    comp_rows = []
    for i, o in enumerate(outs):
        r = o.get("rmse") or {}
        comp_rows.append([str(i + 1), _num(r.get("lat_deg"), ".3e"), _num(r.get("lon_deg"), ".3e"),
                          _num(r.get("h_m")), _num(r.get("vn_mps")), _num(r.get("ve_mps")),
                          _num(r.get("vd_mps"))])
    return (_table(head, rows) + "<p class=meta>Component RMSEs (the papers' table)</p>"
            + _table(["#", "lat (deg)", "lon (deg)", "h (m)", "vN (m/s)", "vE (m/s)",
                      "vD (m/s)"], comp_rows))


def _events(summary: Mapping[str, Any]) -> str:
    evs = list(summary.get("events") or [])
    if not evs:
        return "<p>No scored scenario event.</p>"
    rows, cls = [], []
    for ev in evs:
        early = ev.get("reaccepted_early")
        detected = ev.get("detect_s") is not None
        rows.append([
            _e(ev.get("type")), _e(ev.get("kind", "")), _num(ev.get("start_s"), ".1f"),
            _num(ev.get("end_s"), ".1f"),
            _num(ev.get("detect_s"), ".2f") if detected else "never",
            _num(ev.get("max_horizontal_m")), _num(ev.get("max_vertical_m")),
            _num(early), _num(ev.get("reaccept_count")), _num(ev.get("reconverge_s"), ".1f"),
        ])
        cls.append("fail" if early else ("pass" if detected else ""))
    return _table(["event", "kind", "start (s)", "end (s)", "detected after (s)",
                   "max h (m)", "max v (m)", "re-accepted early", "re-accepts",
                   "re-converge (s)"], rows, cls, left=2)


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


def _plots(plots: Sequence[Path] | Mapping[str, Path]) -> str:
    items = list(plots.items()) if isinstance(plots, Mapping) else [(p.stem, p) for p in plots]
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
        _kv({"counters": ap.get("counters") or {}, "link": ap.get("link") or {}}),
    ])


def render_html(summary: Mapping[str, Any], plots: Sequence[Path] | Mapping[str, Path]) -> str:
    """The page as a string (see :func:`write_html`)."""
    passed = bool(summary.get("passed"))
    title = f"hilnav · {summary.get('scenario', 'run')}"
    meta = (f"seed {_e(summary.get('seed'))} · bridge {_e(summary.get('bridge'))} · "
            f"altitude {_e(summary.get('altitude'))} · "
            f"{_num(summary.get('sim_duration_s'), '.1f')} s simulated in "
            f"{_num(summary.get('wall_s'), '.1f')} s "
            f"(×{_num(summary.get('realtime_factor'), '.1f')} real time)")
    badge = '<span class="badge pass">PASSED</span>' if passed else \
        '<span class="badge fail">FAILED</span>'
    parts = [
        "<!DOCTYPE html>", '<html lang="en"><head><meta charset="utf-8">',
        f"<title>{_e(title)}</title><style>{_CSS}</style></head><body>",
        f"<h1>{_e(title)} {badge}</h1><p class=meta>{meta}</p>",
        "<h2>Pass criteria</h2>", _criteria(summary),
        "<h2>GNSS outages</h2>", _outages(summary),
        "<h2>Scenario events</h2>", _events(summary),
        "<h2>GNSS-on accuracy</h2>", _kv(summary.get("gnss_on") or {}),
        "<h2>Consistency</h2>",
        _kv({"nees": summary.get("nees") or {},
             "containment_3sigma": summary.get("containment_3sigma") or {}}),
        "<h2>Health counters</h2>", _kv(summary.get("health") or {}),
    ]
    if summary.get("autopilot"):
        parts += ["<h2>Both estimates on one scorecard</h2>", _autopilot(summary)]
    if summary.get("rejections_outside_events"):
        parts += ["<h2>Rejections outside outages and events</h2>",
                  _kv(summary["rejections_outside_events"])]
    parts += ["<h2>Plots</h2>", _plots(plots), "</body></html>"]
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
