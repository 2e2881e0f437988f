"""NavFilter.innovations (the updates of the last step, labelled by the aiding source that made
them) and the per-source aiding status of the estimate."""

from __future__ import annotations

import math
from collections import Counter
from typing import Any

import numpy as np
import pytest

from fusion import kalman
from fusion.aiding import Observation
from fusion.bridging.interface import BridgeAction, BridgeEpoch, NoBridge, PseudoGnss
from fusion.config import FilterConfig
from fusion.estimate import AidingStatus, AidSource, Innovation
from fusion.filter import NavFilter
from sim.samples import BaroSample, GnssFix, ImuSample, MagSample
from tests.helpers.nav_synth import Flight, Prepared, SensorErrors, make_scenario, prepare

CFG = FilterConfig()
ERRORS = SensorErrors.from_config(CFG)


@pytest.fixture(scope="module")
def flight() -> Prepared:
    """40 s with a turn and a climb (every source observable)."""
    return prepare(Flight(duration_s=40.0, crab_rad=math.radians(5.0),
                          turns=[(10.0, 20.0, 0.2)], climbs=[(22.0, 30.0, 3.0)]))  # fmt: skip


class _Tapped(NavFilter):
    """Records what goes through the update funnel, as hil.service's subclass does."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        self.funnel: list[tuple[Observation, kalman.Correction]] = []
        super().__init__(*args, **kwargs)

    def _correct(self, *args: Any, **kwargs: Any) -> kalman.Correction:
        res = super()._correct(*args, **kwargs)
        self.funnel.append((args[0], res))
        return res


def _sources(records: tuple[Innovation, ...]) -> list[str]:
    return [str(r.source) for r in records]


def test_each_step_reports_exactly_its_own_updates_with_their_sources(flight: Prepared) -> None:
    # GIVEN a filter with GNSS, baro and magnetometer, running
    sc = make_scenario(flight, np.random.default_rng(1), ERRORS, mag_rate_hz=10.0)
    nav = _Tapped(CFG)
    by_kind: dict[str, Counter[str]] = {"imu": Counter(), "gnss": Counter(), "baro": Counter(),
                                        "mag": Counter()}  # fmt: skip
    for s in sc.samples:
        before = len(nav.funnel)
        nav.step(s)
        made = nav.funnel[before:]
        inn = nav.innovations
        # THEN innovations are exactly the updates this step made, in order, with their numbers
        assert len(inn) == len(made)
        for rec, (obs, res) in zip(inn, made, strict=True):
            assert isinstance(rec, Innovation)
            np.testing.assert_array_equal(rec.innovation, res.innovation)
            np.testing.assert_array_equal(rec.S, res.S)
            assert rec.test_ratio == res.test_ratio and rec.fused == (res.test_ratio <= 1.0)
            assert rec.innovation.shape == obs.z.shape
            assert rec.time_us == s.time_us  # the stepped sample's time
        kind = ("imu" if isinstance(s, ImuSample) else "gnss" if isinstance(s, GnssFix)
                else "baro" if isinstance(s, BaroSample) else "mag")  # fmt: skip
        by_kind[kind].update(_sources(inn))
    # AND a fix step yields a GNSS position and a velocity update, a baro step a height update,
    # a mag step a heading update; IMU steps fuse nothing (no fix waits for the IMU here)
    assert by_kind["gnss"]["gnss_pos"] > 100 and by_kind["gnss"]["gnss_pos"] == by_kind["gnss"][
        "gnss_vel"] and set(by_kind["gnss"]) == {"gnss_pos", "gnss_vel"}  # fmt: skip
    assert set(by_kind["baro"]) == {"baro_hgt"} and by_kind["baro"]["baro_hgt"] > 100
    assert set(by_kind["mag"]) == {"mag_hdg"} and by_kind["mag"]["mag_hdg"] >= 3
    assert not by_kind["imu"]


def test_a_fix_fused_when_the_imu_catches_up_is_reported_by_that_imu_step(
    flight: Prepared,
) -> None:
    # GIVEN fixes delivered 50 ms before the IMU reaches their time of validity
    sc = make_scenario(flight, np.random.default_rng(2), ERRORS, baro_rate_hz=None)
    early = []
    for s in sc.samples:
        if isinstance(s, GnssFix):
            k = next(i for i in range(len(early) - 1, -1, -1)
                     if s.time_us - early[i].time_us >= 50_000)  # fmt: skip
            early.insert(k + 1, s)
        else:
            early.append(s)
    nav = NavFilter(CFG)
    imu_steps = 0
    for s in early:
        nav.step(s)
        if isinstance(s, GnssFix):
            assert nav.innovations == () or nav.mode == "initializing"
        elif nav.innovations:
            imu_steps += 1
            assert _sources(nav.innovations) == ["gnss_pos", "gnss_vel"]
            assert all(r.time_us == s.time_us for r in nav.innovations)
    # THEN the queued fixes were fused by the IMU step that caught up with them
    assert imu_steps > 100


class _PseudoFixes(NoBridge):
    def __init__(self, action: Any) -> None:
        self.action = action

    def on_outage(self, epoch: BridgeEpoch) -> BridgeAction | None:
        result: BridgeAction | None = self.action(epoch)
        return result


def test_pseudo_gnss_updates_of_a_bridging_strategy_are_bridge_records(flight: Prepared) -> None:
    # GIVEN a strategy that sends the true position and velocity as pseudo-fixes in an outage
    sc = make_scenario(flight, np.random.default_rng(3), ERRORS, baro_rate_hz=None,
                       gnss_outages=[(20.0, 32.0)])  # fmt: skip

    def oracle(epoch: BridgeEpoch) -> BridgeAction:
        kin = sc.traj(np.array([epoch.time_us * 1e-6]))
        lat, lon, h = kin.lla[0]
        return PseudoGnss(lat, lon, h, tuple(kin.v_ned_mps[0]), 3.0, 0.3)

    nav = NavFilter(CFG, bridge=_PseudoFixes(oracle))
    bridged_steps = 0
    for s in sc.samples:
        est = nav.step(s)
        if nav.innovations and isinstance(s, ImuSample):
            # THEN an IMU step during the outage reports the pseudo-fix's two updates
            assert _sources(nav.innovations) == ["bridge_pos", "bridge_vel"]
            assert nav.mode == "bridging"
            bridged_steps += 1
        for e in est:
            if e.mode == "bridging":
                assert e.aiding is not None and e.aiding.bridge_pos.last is not None
    assert bridged_steps == nav.health.bridge_updates > 40
    # AND the receiver's own status was untouched by them
    final = nav.estimate()
    assert final is not None and final.aiding is not None
    bridge_last = final.aiding[AidSource.BRIDGE_POS].last
    assert bridge_last is not None and final.aiding[AidSource.BRIDGE_VEL].last is not None
    gnss_fused_us = final.aiding.gnss_pos.time_last_fused_us
    assert gnss_fused_us is not None and gnss_fused_us > bridge_last.time_us


def test_estimate_aiding_status_and_test_ratios_follow_the_last_updates(flight: Prepared) -> None:
    sc = make_scenario(flight, np.random.default_rng(4), ERRORS, mag_rate_hz=10.0)
    nav = NavFilter(CFG)
    last: dict[str, Innovation] = {}
    fused_at: dict[str, int] = {}
    checked = 0
    for s in sc.samples:
        for e in nav.step(s):
            aid = e.aiding
            assert isinstance(aid, AidingStatus)
            for src in AidSource:
                status = aid[src]
                assert status.source == src
                rec = last.get(str(src))
                # THEN each source shows its last update and the time it last fused
                assert status.last is rec
                assert status.time_last_fused_us == fused_at.get(str(src))
            for name in ("gnss_pos", "gnss_vel", "baro_hgt", "mag_hdg"):
                ratio = getattr(e.test_ratios, name)
                want = last[name].test_ratio if name in last else math.nan
                assert ratio == want or (math.isnan(ratio) and math.isnan(want))
            checked += 1
        for rec in nav.innovations:
            last[str(rec.source)] = rec
            if rec.fused:
                fused_at[str(rec.source)] = rec.time_us
    assert checked > 1000 and {"gnss_pos", "gnss_vel", "baro_hgt", "mag_hdg"} <= set(last)
    assert AidingStatus().gnss_pos.last is None and math.isnan(AidingStatus().mag_hdg.test_ratio)


def test_innovations_empty_before_alignment_and_after_a_step_without_update() -> None:
    nav = NavFilter(CFG)
    assert nav.innovations == ()
    nav.step(ImuSample(10_000, 0.01, np.zeros(3), np.zeros(3)))
    assert nav.innovations == ()
    nav.step(MagSample(20_000, np.array([2e-5, 0.0, 4e-5])))
    assert nav.innovations == ()
