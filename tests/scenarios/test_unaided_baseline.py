"""The aided-vs-unaided card (scenarios.unaided_baseline): the rows are each estimate's own
outage figures matched by the outage's start, the ratios their horizontal RMSEs' against the
targets, a missing baseline named; and the unaided flight's script (aiding: disabled)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from scenarios.html import aided_unaided_rows, render_html
from scenarios.schema import ScenarioError, load_scenario
from scenarios.unaided_baseline import (
    AIDED_OVER_HILNAV_TARGET,
    AIDED_OVER_UNAIDED_TARGET,
    UnaidedBaseline,
    aided_vs_unaided,
    unaided_scenario,
)


def _outage(start_s: float, rmse_m: float, max_m: float) -> dict[str, Any]:
    return {"start_s": start_s, "end_s": start_s + 60.0, "horizontal_rmse_m": rmse_m,
            "horizontal_max_m": max_m, "cep50_m": 1.0,
            "horizontal_error_m_at": {"10": 1.0, "30": max_m / 2, "60": max_m}}


def test_rows_are_each_estimates_outage_matched_by_start_and_ratios_of_rmse() -> None:
    summary = {"outages": [_outage(300.0, 4.0, 8.0), _outage(900.0, 5.0, 9.0)]}
    # the autopilots' gaps start a sample or two apart; the second outage was not denied to
    # the unaided one
    aided = {"outages": [_outage(300.2, 5.0, 9.0), _outage(899.9, 9.0, 20.0)]}
    unaided = {"outages": [_outage(299.8, 20.0, 40.0)]}
    again = {"outages": [_outage(300.0, 4.1, 8.2), _outage(900.0, 5.2, 9.1)]}
    card = aided_vs_unaided(summary, aided, unaided, again)
    first, second = card["outages"]
    assert first["hilnav"] == {"horizontal_rmse_m": 4.0, "horizontal_max_m": 8.0,
                               "horizontal_error_m_at": {"30": 4.0, "60": 8.0}}
    assert first["aided"]["horizontal_rmse_m"] == 5.0
    assert first["unaided"]["horizontal_max_m"] == 40.0
    assert first["hilnav_unaided_flight"]["horizontal_rmse_m"] == 4.1
    assert first["aided_over_hilnav"] == pytest.approx(1.25)
    assert first["aided_over_unaided"] == pytest.approx(0.25)
    assert first["meets"] == {"aided_over_hilnav": True, "aided_over_unaided": True}
    assert second["unaided"] is None and second["aided_over_unaided"] is None
    assert second["aided_over_hilnav"] == pytest.approx(1.8)
    assert second["meets"] == {"aided_over_hilnav": False, "aided_over_unaided": None}
    assert card["targets"] == {"aided_over_hilnav": AIDED_OVER_HILNAV_TARGET,
                               "aided_over_unaided": AIDED_OVER_UNAIDED_TARGET}
    assert (AIDED_OVER_HILNAV_TARGET, AIDED_OVER_UNAIDED_TARGET) == (1.5, 0.5)
    assert card["problem"] is None and "not deterministic" in card["note"]


def test_a_baseline_that_never_flew_is_named_and_fails_the_aided_run() -> None:
    baseline = UnaidedBaseline(Path("out/unaided"))
    baseline.absent("PX4 did not connect within 30 s (link tcpin:127.0.0.1:4560)")
    summary: dict[str, Any] = {"outages": [_outage(300.0, 4.0, 8.0)],
                               "autopilot": {"source": "PX4",
                                             "outages": [_outage(300.0, 5.0, 9.0)]}}
    failure = baseline.add_to(summary)
    assert failure == ("the unaided baseline (out/unaided) has nothing to compare: PX4 did "
                       "not connect within 30 s (link tcpin:127.0.0.1:4560)")
    ap = summary["autopilot"]
    assert ap["unaided"] is None
    (row,) = ap["aided_vs_unaided"]["outages"]
    assert row["unaided"] is None and row["aided_over_hilnav"] == pytest.approx(1.25)
    html = render_html(summary, [])
    assert "Aided by hilnav and unaided" in html and "Not compared: PX4 did not connect" in html


def test_the_html_and_printout_rows() -> None:
    summary = {"outages": [_outage(300.0, 4.0, 8.0)],
               "autopilot": {"source": "ArduPilot", "outages": [_outage(300.0, 5.0, 9.0)]}}
    summary["autopilot"]["aided_vs_unaided"] = aided_vs_unaided(
        summary, summary["autopilot"], {"outages": [_outage(300.0, 8.0, 30.0)]}, None)
    rows = aided_unaided_rows(summary)
    assert [r.name for r in rows] == [
        "outage 1 (300-360 s): horizontal RMSE (m)", "outage 1 (300-360 s): horizontal max (m)",
        "outage 1 (300-360 s): horizontal error at 30 s (m)",
        "outage 1 (300-360 s): horizontal error at 60 s (m)",
        "outage 1 (300-360 s): aided / hilnav horizontal RMSE",
        "outage 1 (300-360 s): aided / unaided horizontal RMSE"]
    assert rows[0].values == (4.0, 5.0, 8.0, None)
    assert rows[4].values is None and rows[4].ratio == pytest.approx(1.25) and rows[4].met
    assert rows[5].ratio == pytest.approx(0.625) and rows[5].met is False
    html = render_html(summary, [])
    assert "ArduPilot aided by hilnav" in html and "0.625 (missed)" in html


def _scenario(tmp_path: Path, aiding: str, params: str | None = None) -> Path:
    path = tmp_path / "s.yaml"
    extra = "" if params is None else f"\n  params: {params}"
    path.write_text(f"""
name: s
duration_s: 30
autopilot:
  kind: ardupilot
  aiding: {aiding}{extra}
""")
    return path


def test_the_unaided_flight_sets_the_aiding_parameters_off_over_the_file(
        tmp_path: Path) -> None:
    (tmp_path / "c172.parm").write_text("GPS2_TYPE 14\nARSPD_SKIP_CAL 1\n")
    scn = load_scenario(_scenario(tmp_path, "hilnav", "c172.parm"))
    script = scn.autopilot_script()
    assert [(p.name, p.value) for p in script.params] == [
        ("GPS2_TYPE", 14.0), ("ARSPD_SKIP_CAL", 1.0), ("GPS_AUTO_SWITCH", 1.0)]
    base = unaided_scenario(scn)
    assert base.autopilot.aiding == "disabled" and not base.autopilot.unaided_baseline
    off = base.autopilot_script()
    assert [(p.name, p.value, p.line) for p in off.params] == [
        ("ARSPD_SKIP_CAL", 1.0, 2), ("GPS2_TYPE", 0.0, 0)]
    assert off.aiding_off and not off.aiding
    assert base.seed == scn.seed and base.duration_s == scn.duration_s


def test_unaided_baseline_is_refused_without_aiding_by_hilnav(tmp_path: Path) -> None:
    path = _scenario(tmp_path, "disabled")
    path.write_text(path.read_text() + "  unaided_baseline: true\n")
    with pytest.raises(ScenarioError, match="unaided_baseline compares the autopilot aided by "
                                            "hilnav with it unaided: set aiding to hilnav"):
        load_scenario(path)
