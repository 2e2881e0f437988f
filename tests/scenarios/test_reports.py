"""Run reports: summary.json scoring (criteria, events, re-convergence), JUnit XML, plots and
the self-contained HTML page; and a recorded flight replayed end to end."""

from __future__ import annotations

import base64
import json
import math
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import hil.pipeline as pipeline_mod
from fusion import earth
from hil.tracks import Collector, Fixes, HealthSeries, Track
from scenarios import metrics, report
from scenarios import replay as replay_mod
from scenarios.html import write_html
from scenarios.junit import failure_message, write_junit
from scenarios.metrics import Window
from scenarios.summary import Criterion, RunInfo, ScoringConfig, build_summary, write_summary

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


# ------------------------------------------------------------------ a hand-made run


def _track(t: np.ndarray, north: np.ndarray, east: np.ndarray, down: np.ndarray,
           sigma: np.ndarray | None = None) -> Track:
    lat0, lon0, h0 = math.radians(47.0), math.radians(8.0), 500.0
    r_n, r_e = (float(r) for r in earth.principal_radii(lat0))
    n = t.size
    return Track(t, lat0 + north / (r_n + h0), lon0 + east / ((r_e + h0) * math.cos(lat0)),
                 h0 - down, np.zeros((n, 3)), np.zeros((n, 3)), sigma)


def _steps(t: np.ndarray, times: np.ndarray) -> np.ndarray:
    return np.searchsorted(np.sort(times), t, side="right").astype(np.int64)


T = np.round(np.arange(0.0, 400.0, 0.1), 6)
OUTAGE = Window(100.0, 160.0)
SPOOF = {"type": "gnss_spoof_hijack", "kind": "spoof", "start_s": 250.0, "end_s": 300.0}


def _run() -> tuple[Track, Track, HealthSeries]:
    """Flying east at 40 m/s. Error 1 m north with GNSS; +1 m/s north in the outage
    (100-160 s), decaying 10 m/s from 61.5 m after it (below 3 m after 165.85 s); a 500 m spoof
    at 250-300 s whose fixes the filter fuses for 2 s (6 m error for 10 s), then rejects;
    sigma 1 m everywhere."""
    east = 40.0 * T
    err_n = np.ones_like(T)
    grow = OUTAGE.mask(T)
    err_n[grow] = 1.0 + (T[grow] - 100.0)
    after = (T >= 160.0) & (T < 170.0)
    err_n[after] = np.maximum(61.5 - 10.0 * (T[after] - 160.0), 1.0)
    err_n[(T >= 250.0) & (T < 260.0)] = 6.0  # pulled off by the spoofed fixes it fused
    sig = np.tile([1.0, 1.0, 1.0, 0.1, 0.1, 0.1, 0.01, 0.01, 0.01], (T.size, 1))
    zero = np.zeros_like(T)
    truth = _track(T, zero, east, zero)
    est = _track(T, err_n, east, zero, sig)
    fix_t = np.concatenate([np.arange(0.05, 100.0, 0.2), np.arange(160.05, 400.0, 0.2)])
    fix_t = np.round(fix_t, 6)
    fused_t = fix_t[(fix_t < 252.0) | (fix_t > 300.0)]
    rejected_t = fix_t[(fix_t >= 252.0) & (fix_t <= 300.0)]
    spoof = (fix_t >= 250.0) & (fix_t <= 300.0)
    fixes = Fixes(fix_t, truth.lat_rad[0] + spoof * 500.0 / 6.4e6,
                          np.asarray(np.interp(fix_t, T, truth.lon_rad)),
                          np.full(fix_t.size, 500.0))
    mode = np.where((T > 101.0) & (T < 160.0), "free-inertial", "gnss")
    health = HealthSeries(
        T, mode=mode, gnss_fused=_steps(T, fused_t + 0.01),
        gnss_rejected=_steps(T, rejected_t + 0.01), gnss_resets=np.zeros(T.size, np.int64),
        fixes=fixes)
    return est, truth, health


CRITERIA = (
    Criterion("drift at 30 s", "outages.horizontal_error_m_at.30", 40.0),
    Criterion("component h RMSE", "outages.rmse.horizontal_m", 10.0),
    Criterion("spoof detected within 5 s", "events.detect_s", 5.0, none_fails=True),
    Criterion("no early re-accept", "events.reaccepted_early", 0.0),
    Criterion("3-sigma containment", "containment_3sigma.horizontal", 0.9, op=">="),
    Criterion("re-converged within 10 s", "outages.reconverge_s", 10.0),
    Criterion("missing value", "outages.no_such_key", 1.0),
)


@pytest.fixture(scope="module")
def scored() -> tuple[dict[str, Any], metrics.Errors, Track, Track]:
    est, truth, health = _run()
    info = RunInfo("hand-made", 3, 400.0, 2.0, "none", "ekf")
    summary, err = build_summary(
        info, est, truth, [OUTAGE], settle_s=20.0, criteria=CRITERIA,
        health={"filter": {"gnss_fused": 1500, "gnss_rejected": 240}},
        events=[SPOOF], series=health, scoring=ScoringConfig(reconverge_k=3.0, bad_fix_m=50.0))
    return summary, err, est, truth


def test_summary_keeps_the_contract_and_adds_the_scorecard(
    scored: tuple[dict[str, Any], metrics.Errors, Track, Track],
) -> None:
    s = scored[0]
    for key in ("scenario", "seed", "sim_duration_s", "wall_s", "realtime_factor", "bridge",
                "altitude", "outages", "gnss_on", "nees", "criteria", "passed",
                "containment_3sigma", "events", "health", "rejections_outside_events"):
        assert key in s
    o = s["outages"][0]
    assert o["horizontal_error_m_at"]["30"] == pytest.approx(31.0, abs=1e-6)
    assert o["horizontal_max_m"] == pytest.approx(60.9, abs=1e-6)
    assert o["cep50_m"] == pytest.approx(31.0, abs=0.2)
    # inside the 3.44-sigma circle while 1 + tau <= 3.44 m: 25 of 600 samples
    assert o["containment_3sigma"]["horizontal"] == pytest.approx(25 / 600)
    # GNSS-on RMSE is 1 m -> threshold 3 m; 61.5 - 10 tau < 3 from tau = 5.85 s: sample 5.9 s
    assert s["scoring"]["reconverge_threshold_m"] == pytest.approx(3.0)
    assert o["reconverge_s"] == pytest.approx(5.9, abs=1e-6)
    ev = s["events"][0]
    assert ev["type"] == "gnss_spoof_hijack" and ev["kind"] == "spoof"
    assert ev["detect_s"] == pytest.approx(2.1, abs=1e-6)  # first rejection 252.05 -> 252.1
    # the ten spoofed fixes of 250-252 s went in (500 m > bad_fix_m); none after the detection
    assert ev["bad_fixes_fused"] == 10
    assert ev["reaccepted_early"] is True and ev["reaccept_count"] == 10
    assert ev["max_horizontal_m"] == pytest.approx(6.0, abs=1e-6)
    assert ev["reconverge_s"] == pytest.approx(0.0)  # 1 m again when the spoof ends
    assert s["detect_s_by_sensor"]["gnss"] == [pytest.approx(2.1, abs=1e-6)]
    assert s["detect_s_by_sensor"]["airspeed"] == []
    # the spoof window and its settling are not "GNSS on": the GNSS-on RMSE stays 1 m
    assert s["gnss_on"]["horizontal_rmse_m"] == pytest.approx(1.0, abs=1e-6)
    assert s["rejections_outside_events"] == {"gnss_rejected": 0}


def test_criteria_worst_case_ops_and_missing_values(
    scored: tuple[dict[str, Any], metrics.Errors, Track, Track],
) -> None:
    s = scored[0]
    by_name = {c["name"]: c for c in s["criteria"]}
    assert by_name["drift at 30 s"]["ok"] is True
    # a nested path through the outage list (outages.rmse.horizontal_m) is found
    assert by_name["component h RMSE"]["value"] == pytest.approx(
        s["outages"][0]["rmse"]["horizontal_m"])
    assert by_name["component h RMSE"]["ok"] is False
    assert by_name["spoof detected within 5 s"]["ok"] is True
    assert by_name["no early re-accept"]["value"] == 1.0
    assert by_name["no early re-accept"]["ok"] is False
    assert by_name["3-sigma containment"]["op"] == ">="
    assert by_name["missing value"]["value"] is None and not by_name["missing value"]["ok"]
    assert s["passed"] is False
    # none_fails: one event never detected fails the criterion even if another was fast
    tree = {"events": [{"detect_s": 1.0}, {"detect_s": None}]}
    strict = Criterion("d", "events.detect_s", 5.0, none_fails=True).evaluate(tree)
    lenient = Criterion("d", "events.detect_s", 5.0).evaluate(tree)
    assert strict["ok"] is False and strict["value"] is None
    assert lenient["ok"] is True and lenient["value"] == 1.0
    # a per-sensor detection list: the same rules, and an empty one (no such event) fails
    per = {"detect_s_by_sensor": {"airspeed": [4.0, None], "baro": []}}
    assert Criterion("a", "detect_s_by_sensor.airspeed", 5.0).evaluate(per)["value"] == 4.0
    assert not Criterion("a", "detect_s_by_sensor.airspeed", 5.0, none_fails=True).evaluate(
        per)["ok"]
    assert not Criterion("b", "detect_s_by_sensor.baro", 5.0).evaluate(per)["ok"]
    # >= takes the smallest value over a list
    low = Criterion("c", "outages.x", 0.5, op=">=").evaluate({"outages": [{"x": 0.9}, {"x": 0.4}]})
    assert low["value"] == 0.4 and low["ok"] is False
    with pytest.raises(ValueError, match="op"):
        Criterion("c", "x", 1.0, op="<")  # type: ignore[arg-type]


def test_summary_without_events_or_series_is_backward_compatible() -> None:
    est, truth, _ = _run()
    s, _err = build_summary(RunInfo("x", None, 400.0, 0.0, "none", "ekf"), est, truth,
                            [OUTAGE], settle_s=20.0)
    assert s["events"] == [] and "rejections_outside_events" not in s
    assert s["realtime_factor"] is None and s["criteria"] == [] and s["passed"] is True
    # without the spoof window excluded the GNSS-on RMSE sees the 6 m of the spoof period
    assert s["gnss_on"]["horizontal_rmse_m"] > 1.3


def test_junit_parses_and_counts_match(
    tmp_path: Path, scored: tuple[dict[str, Any], metrics.Errors, Track, Track],
) -> None:
    s = scored[0]
    path = tmp_path / "junit.xml"
    write_junit(s, path, "hilnav.hand-made")
    root = ET.parse(path).getroot()
    assert root.tag == "testsuites"
    suites = root.findall("testsuite")
    assert len(suites) == 1
    suite = suites[0]
    cases = suite.findall("testcase")
    failed = [c for c in s["criteria"] if not c["ok"]]
    assert len(cases) == len(s["criteria"]) == int(suite.get("tests", "-1"))
    assert int(suite.get("failures", "-1")) == len(failed) == int(root.get("failures", "-1"))
    assert int(root.get("tests", "-1")) == len(cases)
    assert suite.get("errors") == "0" and suite.get("skipped") == "0"
    assert float(suite.get("time", "nan")) == pytest.approx(2.0)
    assert [c.get("name") for c in cases] == [c["name"] for c in s["criteria"]]
    failures = {c.get("name"): c.find("failure") for c in cases}
    assert failures["drift at 30 s"] is None
    f = failures["component h RMSE"]
    assert f is not None
    value = s["outages"][0]["rmse"]["horizontal_m"]
    assert f.get("message") == f"value {value:.6g} > limit 10"
    missing = failures["missing value"]
    assert missing is not None and "no value" in (missing.get("message") or "")
    props = {p.get("name"): p.get("value") for p in suite.iter("property")}
    assert props["scenario"] == "hand-made" and props["passed"] == "false"
    assert failure_message({"value": 0.4, "limit": 0.5, "op": ">="}) == "value 0.4 < limit 0.5"


def test_html_embeds_plots_and_tables(
    tmp_path: Path, scored: tuple[dict[str, Any], metrics.Errors, Track, Track],
) -> None:
    s, err, est, truth = scored
    plots = report.write_plots(est, truth, err, [OUTAGE], tmp_path, events=s["events"])
    assert [p.name for p in plots] == ["ground_track.png", "errors.png",
                                       "horizontal_vertical.png", "drift.png"]
    page_path = tmp_path / "report.html"
    write_html(s, plots, page_path)
    page = page_path.read_text(encoding="utf-8")
    assert page.startswith("<!DOCTYPE html>")
    chunks = page.split('src="data:image/png;base64,')[1:]
    assert len(chunks) == len(plots)
    embedded = [base64.b64decode(chunk.split('"', 1)[0]) for chunk in chunks]
    assert all(data.startswith(PNG_MAGIC) for data in embedded)
    # every plot, once, in reading order: the ground track first, the drift last
    by_name = {p.stem: p.read_bytes() for p in plots}
    assert embedded == [by_name[n] for n in ("ground_track", "horizontal_vertical", "errors",
                                             "drift")]
    for c in s["criteria"]:
        assert c["name"] in page
    assert page.count('<tr class="fail">') >= sum(1 for c in s["criteria"] if not c["ok"])
    assert "gnss spoof hijack" in page and "FAILED" in page and "gnss_rejected" in page
    # self-contained: nothing fetched from anywhere
    for needle in ("http://", "https://", "<script", "<link", "url("):
        assert needle not in page


def test_report_reads_top_down_for_a_navigation_engineer(
    tmp_path: Path, scored: tuple[dict[str, Any], metrics.Errors, Track, Track],
) -> None:
    """GIVEN a scored run with what was flown WHEN its page is written THEN the verdict and the
    setup (aircraft, sensor presets, wind, seed) come first, then the criteria with their
    metrics in words, then the plots in reading order (ground track first), then the outage and
    event tables with units, and the counters last, folded; no snake_case key outside them."""
    s, err, est, truth = scored
    s = {**s, "setup": {"aircraft": "c172x", "plan": "racetrack", "description": "a test",
                        "sensors": {"imu": "industrial-mems", "gnss": "modern",
                                    "baro": "ms5611", "mag": "consumer", "pitot": "ms4525do"},
                        "wind_ned_mps": [3.0, -2.0, 0.0], "turbulence": 0.2}}
    plots = report.write_plots(est, truth, err, [OUTAGE], tmp_path, events=s["events"])
    page_path = tmp_path / "report.html"
    write_html(s, plots, page_path)
    page = page_path.read_text(encoding="utf-8")
    order = [page.index(x) for x in (
        "FAILED", "c172x", "industrial-mems", "3, -2, 0", "Pass criteria",
        "GNSS outages: horizontal error at 30 s (m)", "Ground track", "Horizontal and vertical",
        "<h2>GNSS outages</h2>", "horizontal RMSE (m)", "<h2>Scenario events</h2>",
        '<details id="counters">')]
    assert order == sorted(order), order
    visible = page[:page.index('<details id="counters">')]
    for raw in ("rms_z_pos", "containment_3sigma.horizontal", "horizontal_error_m_at",
                "nees_mean", "gnss_spoof_hijack"):
        assert raw not in visible, raw
    assert "rms(error / σ), position" in visible


@pytest.mark.parametrize(("path", "words"), [
    ("outages.horizontal_error_m_at.60", "GNSS outages: horizontal error at 60 s (m)"),
    ("gnss_on.yaw_rmse_deg", "GNSS on: yaw RMSE (deg)"),
    ("containment_3sigma.horizontal", "inside the 3σ bound: horizontal"),
    ("events.detect_s", "events: detected after (s)"),
])
def test_metric_paths_in_words(path: str, words: str) -> None:
    from scenarios.html import metric_label

    assert metric_label(path) == words


def test_report_renders_in_a_real_browser_with_the_first_plot_above_the_counters(
    tmp_path: Path, scored: tuple[dict[str, Any], metrics.Errors, Track, Track],
) -> None:
    """GIVEN the page of a scored run WHEN headless Chromium lays it out at 1400 px wide THEN
    every plot image decodes, and the first plot is above the counters and within the first
    3000 px (a first screenful or two, not after the tables)."""
    from tests.helpers.browser import chromium_or_skip, layout_of

    chromium = chromium_or_skip()
    s, err, est, truth = scored
    plots = report.write_plots(est, truth, err, [OUTAGE], tmp_path, events=s["events"])
    page_path = tmp_path / "report.html"
    write_html(s, plots, page_path)
    got = layout_of(chromium, page_path, tmp_path / "profile", """({
        images: [...document.images].map(i => i.complete && i.naturalWidth > 0),
        first_plot_top: document.images[0].getBoundingClientRect().top,
        counters_top: document.getElementById('counters').getBoundingClientRect().top,
    })""")
    assert got["images"] == [True] * len(plots), got
    assert got["first_plot_top"] < got["counters_top"], got
    assert got["first_plot_top"] < 3000, got


def test_drift_compare_plot_from_summaries(
    tmp_path: Path, scored: tuple[dict[str, Any], metrics.Errors, Track, Track],
) -> None:
    s = scored[0]
    curves = report.drift_curves(s)
    assert len(curves) == 1
    tau, h = curves[0]
    assert tau[10] == pytest.approx(10.0) and h[10] == pytest.approx(11.0, abs=1e-6)
    half = [(tau, 0.5 * h)]
    path = tmp_path / "drift_compare.png"
    report.plot_drift_compare({"none": curves + curves, "gmdh": half}, path)
    assert path.read_bytes().startswith(PNG_MAGIC)


# ------------------------------------------------------------------ a recorded flight


def test_replay_writes_what_it_wrote_before_and_the_series_match_the_filter(
    tmp_path: Path, short_flight_log: Path, monkeypatch: pytest.MonkeyPatch,
) -> None:
    """GIVEN the recorded racetrack with GNSS off 120-150 s WHEN replayed THEN summary.json and
    the plots are there as before (plus drift.png and the new keys), and the collected health
    series agree with the filter: counters monotonic, free-inertial inside the outage, the
    outage detected by the filter within its outage timeout and re-converged after it."""
    seen: list[Collector] = []

    class Spy(Collector):
        def __init__(self, **kwargs: Any) -> None:
            super().__init__(**kwargs)
            seen.append(self)

    monkeypatch.setattr(pipeline_mod, "Collector", Spy)  # the replay's FusionRun collects
    out = tmp_path / "replay"
    res = replay_mod.replay(short_flight_log, out, settle_s=30.0)
    s = json.loads((out / "summary.json").read_text())
    for png in ("ground_track.png", "errors.png", "horizontal_vertical.png", "drift.png"):
        assert (out / png).stat().st_size > 10_000
    assert len(s["outages"]) == 1
    o = s["outages"][0]
    for key in ("cep50_m", "cep95_m", "containment_3sigma", "reconverge_s"):
        assert key in o
    assert o["reconverge_s"] is not None and o["reconverge_s"] < 30.0
    assert s["events"] == []

    col = seen[0]
    series = col.series()
    est = col.estimate_track()
    np.testing.assert_array_equal(series.time_s, est.time_s)
    assert series.gnss_fused is not None and series.mode is not None
    assert np.all(np.diff(series.gnss_fused) >= 0)
    assert series.gnss_fused[-1] <= s["health"]["filter"]["gnss_fused"]
    assert series.gnss_fused[-1] >= s["health"]["filter"]["gnss_fused"] - 2
    w = Window(o["start_s"], o["end_s"])
    inside = w.mask(series.time_s) & (series.time_s > w.start_s + 2.0)
    assert np.all(series.mode[inside] != "gnss")
    assert np.all(series.mode[series.time_s > w.end_s + 2.0] == "gnss")
    assert series.fixes is not None and series.fixes.time_s.size == len(col.fix_times_us)

    # the same run scored with the outage as a scenario event
    truth = col.truth_track()
    summary, _ = build_summary(
        res_info(s), est, truth, [w], settle_s=30.0, series=series,
        events=[{"type": "gnss_outage", "start_s": w.start_s, "end_s": w.end_s}])
    ev = summary["events"][0]
    assert ev["detect_s"] is not None and 0.0 < ev["detect_s"] < 2.0  # the 1 s outage timeout
    assert ev["reaccepted_early"] is False  # no fix arrived, none went in
    assert ev["max_horizontal_m"] == pytest.approx(o["horizontal_max_m"], rel=0.05)
    write_summary(summary, tmp_path / "again.json")  # NaN-free JSON
    assert res.summary_path == out / "summary.json"


def res_info(s: dict[str, Any]) -> RunInfo:
    return RunInfo(s["scenario"], s["seed"], s["sim_duration_s"], s["wall_s"], s["bridge"],
                   s["altitude"])


def test_envelope_decimation_keeps_every_bins_extremes_spikes_and_gaps() -> None:
    """GIVEN an hour-long noisy curve at 50 Hz with one-sample spikes and a NaN gap
    WHEN it is decimated for 400 time bins
    THEN at most first / last / min / max of each series per bin are kept, and in every bin
    the kept samples reach the same minimum and maximum as all of them (so do the spikes and
    the band's edges), the ends and the gap are kept, and a short curve is kept whole."""
    rng = np.random.default_rng(3)
    n, bins = 180_000, 400
    t = np.arange(n) / 50.0
    y = np.cumsum(rng.normal(0.0, 0.1, n))
    spikes = rng.choice(n, 25, replace=False)
    y[spikes] += rng.choice([-50.0, 50.0], spikes.size)
    y[1000:1010] = np.nan
    band = 3.0 + np.abs(np.sin(t / 100.0))
    k = report.envelope_indices(t, y, band, -band, bins=bins)
    assert np.all(np.diff(k) > 0)
    assert k.size <= bins * (2 + 2 * 3) + 10
    assert k[0] == 0 and k[-1] == n - 1
    assert set(spikes.tolist()) <= set(k.tolist())
    assert set(range(1000, 1010)) <= set(k.tolist())
    b = np.minimum((t * (bins / t[-1])).astype(int), bins - 1)
    for v in (y, band, -band):
        for j in range(bins):
            all_j, kept_j = v[b == j], v[k][b[k] == j]
            assert np.nanmin(kept_j) == np.nanmin(all_j) and np.nanmax(kept_j) == np.nanmax(all_j)
    np.testing.assert_array_equal(report.envelope_indices(t[:1600], y[:1600], bins=bins),
                                  np.arange(1600))


def test_path_decimation_stays_within_a_cell_of_the_full_path() -> None:
    """GIVEN a wandering ground track of 20,000 samples
    WHEN it is decimated with cells of 5 m
    THEN every dropped sample is within one cell diagonal of the segment between the kept
    samples around it, the ends are kept, and far fewer samples are drawn."""
    rng = np.random.default_rng(5)
    heading = np.cumsum(rng.normal(0.0, 0.02, 20_000))
    x, y = np.cumsum(np.cos(heading)), np.cumsum(np.sin(heading))
    cell = 5.0
    k = report.path_indices(x, y, cell)
    assert k[0] == 0 and k[-1] == x.size - 1 and k.size < x.size / 2
    nxt = np.searchsorted(k, np.arange(x.size))  # the kept sample at or after each one
    for j in np.setdiff1d(np.arange(x.size), k):
        a, c = k[nxt[j] - 1], k[nxt[j]]
        p, q, r = np.array([x[a], y[a]]), np.array([x[c], y[c]]), np.array([x[j], y[j]])
        u = np.clip(np.dot(r - p, q - p) / max(np.dot(q - p, q - p), 1e-300), 0.0, 1.0)
        assert np.linalg.norm(r - (p + u * (q - p))) <= cell * np.sqrt(2.0)


@pytest.mark.filterwarnings("error::RuntimeWarning")
def test_path_decimation_of_a_track_without_positions_keeps_every_sample_quietly() -> None:
    """GIVEN a ground track whose east or north is NaN throughout (a log without positions)
    WHEN it is decimated
    THEN every sample is kept and numpy warns about nothing."""
    x = np.full(100, np.nan)
    y = np.linspace(0.0, 99.0, 100)
    assert np.array_equal(report.path_indices(x, y, 1.0), np.arange(100))
    assert np.array_equal(report.path_indices(y, x, 1.0), np.arange(100))


def test_saving_without_the_layout_placeholder_writes_the_same_png_bytes(tmp_path: Path) -> None:
    """GIVEN a figure with shared axes, shading, a band and a legend
    WHEN it is saved by ``report._save`` (tight layout, then one draw) and by matplotlib's
    plain ``tight_layout()`` + ``savefig`` (which draws it twice)
    THEN the two PNG files are byte for byte the same."""
    from matplotlib.figure import Figure

    t = np.linspace(0.0, 100.0, 400)
    paths = (tmp_path / "plain.png", tmp_path / "saved.png")
    for k, path in enumerate(paths):
        fig = Figure(figsize=(6, 4))
        axes = fig.subplots(2, 2, sharex=True)
        for i, ax in enumerate(axes.flat):
            ax.plot(t, np.sin(t / (i + 1)), lw=0.8, label="error")
            ax.fill_between(t, -1.0, 1.0, color="tab:gray", alpha=0.25, label="±3σ")
            ax.axvspan(20.0, 40.0, color="tab:red", alpha=0.12)
            ax.set_title(f"panel {i}", fontsize=9)
        axes[0, 0].legend(loc="upper left", fontsize=8)
        fig.suptitle("estimate minus truth", fontsize=10)
        if k == 0:
            fig.tight_layout()
            fig.savefig(path, dpi=80)
        else:
            report._save(fig, path, dpi=80)
    assert paths[0].read_bytes() == paths[1].read_bytes()
