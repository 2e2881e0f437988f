"""fusion.estimate: the Mode and AidSource string enums, the status records, the estimate."""

from __future__ import annotations

import dataclasses
import json
import math
import pickle

import numpy as np

from fusion.estimate import (
    AidingStatus,
    AidSource,
    AidSourceStatus,
    AirDataStatus,
    AlignmentStatus,
    Health,
    Mode,
    NavEstimate,
    TestRatios,
    new_estimate,
    new_innovation,
)


def test_mode_is_a_string_for_every_consumer() -> None:
    # comparisons, str(), f-strings, JSON, dict keys and numpy string arrays see the value
    assert Mode.GNSS == "gnss" and "free-inertial" == Mode.FREE_INERTIAL
    assert [str(m) for m in Mode] == [
        "initializing", "gnss", "free-inertial", "bridging", "dead-reckoning",
    ]  # fmt: skip
    assert f"{Mode.BRIDGING}" == "bridging" and format(Mode.INITIALIZING) == "initializing"
    assert json.dumps({"mode": Mode.GNSS}) == '{"mode": "gnss"}'
    assert {"gnss": 1}[Mode.GNSS] == 1 and Mode("bridging") is Mode.BRIDGING
    arr = np.array([Mode.GNSS, Mode.FREE_INERTIAL], dtype=np.str_)
    assert arr.tolist() == ["gnss", "free-inertial"] and (arr == "gnss").tolist() == [True, False]
    assert pickle.loads(pickle.dumps(Mode.GNSS)) is Mode.GNSS
    assert isinstance(Mode.GNSS, str)


def test_aid_sources_are_named_as_on_the_innovations_topic() -> None:
    assert [str(s) for s in AidSource] == [
        "gnss_pos", "gnss_vel", "baro_hgt", "mag_hdg", "bridge_pos", "bridge_vel", "airspeed",
        "sideslip", "zero_vel", "zero_rate",
    ]  # fmt: skip
    # the status record has one field per source, in the same order
    assert [f.name for f in dataclasses.fields(AidingStatus)] == [s.value for s in AidSource]


def test_source_status_keeps_the_last_update_and_the_last_fused_time() -> None:
    st = AidSourceStatus(AidSource.BARO_HGT)
    assert st.last is None and not st.fused and math.isnan(st.test_ratio) and st.innovation is None
    ok = new_innovation(1_000, AidSource.BARO_HGT, np.array([0.2]), np.array([[0.3]]), 0.1, True)
    bad = new_innovation(2_000, AidSource.BARO_HGT, np.array([9.0]), np.array([[0.3]]), 7.0, False)
    st = st.after(ok)
    assert (st.last, st.time_last_fused_us, st.fused, st.test_ratio) == (ok, 1_000, True, 0.1)
    st = st.after(bad)
    assert (st.last, st.time_last_fused_us, st.fused, st.test_ratio) == (bad, 1_000, False, 7.0)
    assert st.innovation is bad.innovation and st.source is AidSource.BARO_HGT
    assert AidingStatus(baro_hgt=st)[AidSource.BARO_HGT] is st
    # the fast constructor gives the dataclass's fields
    assert dataclasses.asdict(ok)["time_us"] == 1_000 and ok.source is AidSource.BARO_HGT


def test_new_estimate_fills_every_field_in_order() -> None:
    values = [
        5, 0.1, 0.2, 300.0, np.zeros(3), np.array([1.0, 0, 0, 0]), np.zeros(3), np.ones(16),
        Mode.GNSS, np.full(3, 0.01), np.full(3, 1e-5), 2.0, Health(), TestRatios(), 0.2,
        "ins16", None, None, AidingStatus(), np.eye(9), AirDataStatus(), np.zeros(3),
        AlignmentStatus("static_mag", True),
    ]  # fmt: skip
    est = new_estimate(*values)
    names = [f.name for f in dataclasses.fields(NavEstimate)]
    assert len(names) == len(values)
    for name, value in zip(names, values, strict=True):
        assert getattr(est, name) is value
    assert "accel_bias_b_mps2" in names and "gyro_bias_b_rps" in names
