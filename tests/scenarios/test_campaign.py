"""Campaigns: planning, Dask execution, determinism, resume, failed runs, aggregation.

GIVEN a 40 s flight at 50 Hz (short for CI) with a 12 s GNSS outage, 2 seeds x 2 IMU presets,
WHEN the campaign runs on a local Dask cluster of 2 worker processes,
THEN it gives the same aggregate as a second campaign (on another cluster, reached by its
address) and as the same runs flown one by one in this process, a second call into the same
folder flies nothing, and a run that raises is reported in ``failed`` with its message.
"""

from __future__ import annotations

import json
import shutil
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from typer.testing import CliRunner

from scenarios.campaign import (
    VARY_KEYS,
    CampaignResult,
    aggregate,
    apply_point,
    grid_points,
    parse_vary,
    plan_runs,
    run_campaign,
    run_id,
    stats,
)
from scenarios.cli.app import app
from scenarios.runner import run_scenario
from scenarios.schema import load_scenario

TINY = """\
name: tiny
aircraft: c172x
plan: racetrack
duration_s: 40
sim_rate_hz: 50
seed: 1
sensors:
  imu: {preset: industrial-mems}
fusion: {bridge: none, altitude: ekf}
criteria:
  - {name: outage drift, metric: outages.horizontal_rmse_m, max: 1000 m}
events:
  - {type: gnss_outage, at: 26, duration: 12}
"""

# A c172x cannot be trimmed at 14 km: the schema accepts the file, the flight raises at start.
UNFLYABLE = """\
name: unflyable
aircraft: c172x
start: {alt_msl_m: 14000, airspeed_mps: 40}
plan: racetrack
duration_s: 40
sim_rate_hz: 50
events:
  - {type: gnss_outage, at: 25, duration: 10}
"""

SEEDS = [1, 2]
VARY = {"imu": ["consumer-mems", "industrial-mems"]}
# Fields that measure the machine, not the navigation.
TIMING_KEYS = ("wall_s", "realtime_factor")


@pytest.fixture(scope="module")
def tiny(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("scenarios") / "tiny.yaml"
    path.write_text(TINY)
    return path


@pytest.fixture(scope="module")
def scheduler() -> Iterator[str]:
    """An already running cluster, as ``--scheduler tcp://HOST:PORT`` would find one (started
    once: worker start-up is most of a small campaign's cost)."""
    import logging

    from dask.distributed import LocalCluster

    cluster = LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                           dashboard_address=None, silence_logs=logging.ERROR)
    try:
        yield cluster.scheduler_address
    finally:
        cluster.close()


@pytest.fixture(scope="module")
def first(tiny: Path, tmp_path_factory: pytest.TempPathFactory) -> CampaignResult:
    out = tmp_path_factory.mktemp("campaign-a")
    return run_campaign([tiny], SEEDS, VARY, out, workers=2)


def _navigation(summary: dict[str, Any]) -> dict[str, Any]:
    """A summary without the wall-clock fields."""
    nav = {k: v for k, v in summary.items() if k not in TIMING_KEYS}
    nav["health"] = {k: v for k, v in summary["health"].items() if k != "fusion_us_per_sample"}
    return nav


def _deterministic(report: dict[str, Any]) -> dict[str, Any]:
    return {k: report[k] for k in ("groups", "runs", "failed", "not_passed")}


# -- planning and parsing (no cluster) --------------------------------------------------------


def test_parse_vary_keeps_order_and_values() -> None:
    grid = parse_vary(["imu=consumer-mems, industrial-mems", "bridge=none"])
    assert grid == {"imu": ["consumer-mems", "industrial-mems"], "bridge": ["none"]}
    assert grid_points(grid) == [
        {"imu": "consumer-mems", "bridge": "none"},
        {"imu": "industrial-mems", "bridge": "none"},
    ]
    assert grid_points({}) == [{}]


@pytest.mark.parametrize(
    ("items", "message"),
    [
        (["imu"], "KEY=VALUE"),
        (["=a"], "KEY=VALUE"),
        (["speed=1,2"], "unknown key 'speed'"),
        (["imu=a", "imu=b"], "given twice"),
        (["imu="], "empty value"),
        (["imu=a,,b"], "empty value"),
        (["imu=a,a"], "listed twice"),
    ],
)
def test_parse_vary_rejects(items: list[str], message: str) -> None:
    with pytest.raises(ValueError, match=message):
        parse_vary(items)


def test_unknown_key_message_lists_valid_keys() -> None:
    with pytest.raises(ValueError) as info:
        parse_vary(["imus=a"])
    for key in VARY_KEYS:
        assert key in str(info.value)


def test_every_vary_key_reaches_the_scenario(tiny: Path) -> None:
    base = load_scenario(tiny)
    varied = apply_point(base, {"imu": "consumer-mems", "gnss": "paper-p2", "baro": "ideal",
                                "mag": "ideal", "bridge": "gmdh", "altitude": "loop",
                                "aircraft": "c310", "plan": "survey"})
    assert varied.imu_preset == "consumer-mems"
    assert varied.sensors.gnss.preset == "paper-p2"
    assert varied.sensors.baro.preset == "ideal"
    assert varied.sensors.mag.preset == "ideal"
    assert (varied.fusion.bridge, varied.fusion.altitude) == ("gmdh", "loop")
    assert varied.aircraft == "c310"
    assert varied.flight_plan().name == "survey"
    # everything else is the file's
    assert (varied.name, varied.duration_s, varied.sim_rate_hz, varied.seed) == ("tiny", 40, 50, 1)
    assert varied.fault_events() == base.fault_events()


def test_bad_grid_value_is_bad_input_before_anything_runs(tiny: Path) -> None:
    with pytest.raises(ValueError, match="no-such-imu"):
        plan_runs([tiny], SEEDS, {"imu": ["industrial-mems", "no-such-imu"]})
    with pytest.raises(ValueError, match="warp"):
        plan_runs([tiny], SEEDS, {"bridge": ["warp"]})


def test_plan_is_the_full_product_with_stable_ids(tiny: Path, tmp_path: Path) -> None:
    specs = plan_runs([tiny], SEEDS, VARY)
    assert len(specs) == 4
    assert [s.id for s in specs] == sorted(s.id for s in specs)
    assert {(s.seed, s.point["imu"]) for s in specs} == {
        (seed, imu) for seed in SEEDS for imu in VARY["imu"]}
    for s in specs:
        assert s.scenario.seed == s.seed
        assert s.scenario.imu_preset == s.point["imu"]
    # the id depends on the file's bytes, the seed and the point; not on the file's name
    copy = tmp_path / "renamed.yaml"
    shutil.copy(tiny, copy)
    assert [s.id for s in plan_runs([copy], SEEDS, VARY)] == [s.id for s in specs]
    assert run_id("a" * 64, 1, {"imu": "x", "gnss": "y"}) == run_id(
        "a" * 64, 1, {"gnss": "y", "imu": "x"})
    assert run_id("a" * 64, 1, {}) != run_id("a" * 64, 2, {})
    copy.write_text(TINY + "# edited\n")
    assert not {s.id for s in plan_runs([copy], SEEDS, VARY)} & {s.id for s in specs}


def test_bad_campaign_input(tiny: Path, tmp_path: Path) -> None:
    result = CliRunner().invoke(app, ["campaign", str(tiny), "--seeds", "0", "--out",
                                      str(tmp_path)])
    assert result.exit_code == 2 and "seeds" in result.output
    with pytest.raises(ValueError, match="workers"):
        run_campaign([tiny], SEEDS, {}, tmp_path, workers=0)
    with pytest.raises(ValueError, match="scheduler"):
        run_campaign([tiny], SEEDS, {}, tmp_path, workers=2, scheduler="tcp://127.0.0.1:1")
    with pytest.raises(ValueError, match="same content"):
        plan_runs([tiny, tiny], SEEDS, {})
    with pytest.raises(FileNotFoundError):
        plan_runs([tmp_path / "missing.yaml"], SEEDS, {})


def test_stats_known_answer_and_order_independent() -> None:
    values = [float(v) for v in range(1, 21)]  # 1..20
    s = stats(values)
    assert s == {"mean": 10.5, "p95": 19.05, "worst": 20.0, "n": 20}
    assert stats(values[::-1]) == s
    assert stats([]) == {"mean": None, "p95": None, "worst": None, "n": 0}


# -- on a local Dask cluster ------------------------------------------------------------------


def test_campaign_writes_every_run_and_the_aggregate(first: CampaignResult) -> None:
    out, rep = first.out_dir, first.report
    assert (first.executed, first.resumed, first.errored) == (4, 0, 0)
    assert rep["execution"]["workers"] == 2
    assert len(rep["runs"]) == 4 and not rep["failed"]
    for r in rep["runs"]:
        summary = json.loads((out / "runs" / r["id"] / "summary.json").read_text())
        assert (summary["seed"], summary["scenario"]) == (r["seed"], "tiny")
        assert not (out / "runs" / r["id"] / "run.tlog").exists()  # light by default
    assert [g["point"] for g in rep["groups"]] == grid_points(VARY)
    for g in rep["groups"]:
        assert g["runs"] == 2 and g["bridge"] == ["none"] and g["altitude"] == ["ekf"]
        assert g["pass_rate"] == g["passed"] / 2
        m = g["metrics"]["outage_horizontal_rmse_m"]
        assert m["n"] == 2  # one outage per run
        assert 0.0 < m["mean"] <= m["p95"] <= m["worst"]
        assert g["metrics"]["outage_horizontal_error_m_at_10s"]["n"] == 2
        assert g["metrics"]["outage_horizontal_error_m_at_60s"]["n"] == 0  # 12 s outage
    # the IMU preset reached the runs: same seeds, different numbers
    consumer, industrial = (g["metrics"]["outage_horizontal_rmse_m"] for g in rep["groups"])
    assert consumer != industrial
    for name in ("campaign.json", "campaign.md", "distributions.png"):
        assert (out / name).stat().st_size > 0
    assert json.loads((out / "campaign.json").read_text())["groups"] == rep["groups"]
    assert "imu=consumer-mems" in (out / "campaign.md").read_text()
    # the scenario's own criterion, per row: its metric, limit, pass count and values
    for g in rep["groups"]:
        c = g["criteria"]["outage drift"]
        assert (c["metric"], c["op"], c["limit"], c["runs"]) == (
            "outages.horizontal_rmse_m", "<=", 1000.0, 2)
        # one outage per run: the criterion's values are the outage RMSEs of the row
        assert c["passed"] == 2 and c["n"] == 2
        assert c["worst"] == g["metrics"]["outage_horizontal_rmse_m"]["worst"]
    md = (out / "campaign.md").read_text()
    assert "## Each scenario's own criteria" in md and "| outage drift |" in md


def test_criterion_stats_worst_is_on_the_failing_side() -> None:
    """GIVEN a ``>=`` criterion (e.g. containment) WHEN aggregated THEN its worst value is the
    smallest; for ``<=`` it is the largest."""
    from scenarios.campaign.aggregate import criterion_stats

    row = {"metric": "containment_3sigma.horizontal", "op": ">=", "limit": 0.9,
           "values": [0.99, 0.95, 0.97], "passed": 3, "runs": 3}
    assert criterion_stats(row)["worst"] == 0.95
    assert criterion_stats({**row, "op": "<="})["worst"] == 0.99


def test_same_aggregate_twice(first: CampaignResult, tiny: Path, tmp_path: Path,
                              scheduler: str) -> None:
    # the second time on another cluster, reached by its address
    second = run_campaign([tiny], SEEDS, VARY, tmp_path / "b", scheduler=scheduler)
    assert second.report["execution"]["scheduler"] == scheduler
    assert second.executed == 4 and not second.report["failed"]
    assert _deterministic(second.report) == _deterministic(first.report)
    assert (tmp_path / "b" / "campaign.md").read_text().split("\n")[4:] == (
        first.out_dir / "campaign.md").read_text().split("\n")[4:]


def test_same_as_running_the_runs_one_by_one(first: CampaignResult, tmp_path: Path,
                                             tiny: Path) -> None:
    specs = plan_runs([tiny], SEEDS, VARY)
    for spec in specs:
        result = run_scenario(spec.scenario, tmp_path / "runs" / spec.id, tlog=False,
                              reports=False)
        on_cluster = json.loads(
            (first.out_dir / "runs" / spec.id / "summary.json").read_text())
        assert _navigation(on_cluster) == _navigation(
            json.loads(result.files[0].read_text()))
    assert _deterministic(aggregate(specs, tmp_path)) == _deterministic(first.report)


def test_resume_flies_only_missing_runs(first: CampaignResult, tiny: Path, tmp_path: Path,
                                       scheduler: str) -> None:
    out = tmp_path / "resumed"
    shutil.copytree(first.out_dir, out)
    again = run_campaign([tiny], SEEDS, VARY, out, workers=2)
    assert (again.executed, again.resumed) == (0, 4)
    assert again.report["execution"]["workers"] == 0  # no cluster was even started
    assert _deterministic(again.report) == _deterministic(first.report)
    # a run that failed (error.txt, no summary.json) is flown again, the others are not
    victim = out / "runs" / first.report["runs"][0]["id"]
    (victim / "summary.json").unlink()
    (victim / "error.txt").write_text("RuntimeError: worker lost\n")
    again = run_campaign([tiny], SEEDS, VARY, out, scheduler=scheduler, keep_tlogs=True)
    assert (again.executed, again.resumed, again.errored) == (1, 3, 0)
    assert not (victim / "error.txt").exists()
    assert (victim / "run.tlog").stat().st_size > 0  # kept on request, sent back by the worker
    assert _deterministic(again.report) == _deterministic(first.report)


def test_a_run_that_raises_is_reported(tmp_path: Path, scheduler: str) -> None:
    bad = tmp_path / "unflyable.yaml"
    bad.write_text(UNFLYABLE)
    out = tmp_path / "c"
    result = CliRunner().invoke(app, ["campaign", str(bad), "--seeds", "1", "--seed-base", "7",
                                      "--out", str(out), "--scheduler", scheduler])
    assert result.exit_code == 1, result.output
    rep = json.loads((out / "campaign.json").read_text())
    assert len(rep["failed"]) == 1
    failed = rep["failed"][0]
    assert failed["seed"] == 7 and failed["scenario"] == "unflyable"
    assert failed["error"].startswith("ValueError: JSBSim cannot trim c172x")
    assert rep["runs"][0]["status"] == "error"
    assert rep["groups"][0]["errored"] == 1 and rep["groups"][0]["pass_rate"] == 0.0
    error_txt = (out / "runs" / failed["id"] / "error.txt").read_text()
    assert "Traceback" in error_txt
    assert not (out / "runs" / failed["id"] / "summary.json").exists()
    assert "JSBSim cannot trim" in (out / "campaign.md").read_text()


def test_remote_cluster_recipe_on_loopback(first: CampaignResult, tiny: Path,
                                           tmp_path: Path) -> None:
    """The Dask-cluster recipe of docs/scenarios.md, on 127.0.0.1: ``dask scheduler`` and two ``dask
    worker`` processes (what other hosts would run), ``hilnav campaign --scheduler``."""
    from tests.helpers.dask_cluster import dask_cli_cluster

    out = tmp_path / "remote"
    args = ["campaign", str(tiny), "--seeds", str(len(SEEDS)), "--seed-base", str(SEEDS[0]),
            "--vary", "imu=" + ",".join(VARY["imu"]), "--out", str(out)]
    with dask_cli_cluster(2, tmp_path / "cluster") as address:
        result = CliRunner().invoke(app, [*args, "--scheduler", address])
        assert result.exit_code == 0, result.output
        rep = json.loads((out / "campaign.json").read_text())
        assert rep["execution"]["scheduler"] == address
        assert rep["execution"]["workers"] == 2 and rep["execution"]["executed"] == 4
        assert rep["execution"]["warm_up_s"] >= 0.0
        # the outputs come back to the client's folder; the workers' folders keep no run
        for r in rep["runs"]:
            assert (out / "runs" / r["id"] / "summary.json").is_file()
        assert not list((tmp_path / "cluster").rglob("summary.json"))
        # same numbers whichever machine flew the runs
        assert _deterministic(rep) == _deterministic(first.report)
        # resumable: the same command again flies nothing
        again = CliRunner().invoke(app, [*args, "--scheduler", address])
        assert again.exit_code == 0, again.output
        rep2 = json.loads((out / "campaign.json").read_text())
        assert (rep2["execution"]["executed"], rep2["execution"]["resumed"]) == (0, 4)


def test_workers_that_cannot_import_hilnav_stop_the_campaign_before_any_run(
        tiny: Path, tmp_path: Path, scheduler: str, monkeypatch: pytest.MonkeyPatch) -> None:
    import scenarios.campaign.execute as execute

    def no_hilnav() -> float:  # a closure: pickled by value, so it runs as is on the worker
        raise ModuleNotFoundError("No module named 'scenarios'")

    monkeypatch.setattr(execute, "warm_up", no_hilnav)
    result = CliRunner().invoke(app, ["campaign", str(tiny), "--seeds", "1", "--out",
                                      str(tmp_path / "c"), "--scheduler", scheduler])
    assert result.exit_code == 2, result.output
    assert "cannot import hilnav" in result.output and "install the same hilnav" in result.output
    assert "Traceback" not in result.output
    assert not list((tmp_path / "c" / "runs").rglob("summary.json"))
