"""The one pipeline (hil.pipeline): flight setups, lockstep flying, fusing, the filter factory."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from hil.pipeline import (
    FusionRun,
    SimChain,
    SimSetup,
    build_filter,
    filter_config,
    fly,
    fuse_frames,
    record_flight,
    tee,
)
from hil.tlog import read_tlog
from sim.presets import gnss_preset


@pytest.mark.parametrize(
    ("kwargs", "needle"),
    [({"duration_s": 0.0}, "duration"), ({"seed": -1}, "seed"), ({"wind": "5,3"}, "wind"),
     ({"gnss_off": ["300"]}, "START:DURATION"), ({"plan": "nowhere"}, "plan")],
)
def test_bad_setup_options_name_the_option(kwargs: dict, needle: str) -> None:
    with pytest.raises(ValueError, match=needle):
        SimSetup.build(**kwargs)


def test_the_factory_names_bad_methods_and_presets() -> None:
    with pytest.raises(ValueError, match=r"altitude method 'baro'.*loop-mpc"):
        filter_config("industrial-mems", gnss_preset("modern"), "baro")
    with pytest.raises(ValueError, match="industrial-mems"):
        filter_config("no-such-imu", gnss_preset("modern"))
    with pytest.raises(ValueError, match=r"bridging method 'magic'.*gmdh"):
        build_filter(filter_config("industrial-mems", gnss_preset("modern")), "magic")
    with pytest.raises(ValueError, match=r"airspeed mode 'maybe'.*synthetic"):
        filter_config("industrial-mems", gnss_preset("modern"), "ekf", "maybe")


def test_the_commands_filter_carries_the_air_data_states_and_the_airspeed_choice() -> None:
    # the default layout has the (dormant) air-data block, with or without the GNSS bias block
    on = filter_config("industrial-mems", gnss_preset("modern"))
    assert on.state_layout == "ins35+gnss+air" and on.airspeed.enabled
    assert not on.airspeed.synthetic_when_no_pitot
    off = filter_config("industrial-mems", gnss_preset("modern"), airspeed="off")
    assert off.state_layout == on.state_layout and not off.airspeed.enabled
    syn = filter_config("industrial-mems", gnss_preset("modern"), airspeed="synthetic")
    assert syn.airspeed.enabled and syn.airspeed.synthetic_when_no_pitot


@pytest.fixture(scope="module")
def flown(tmp_path_factory: pytest.TempPathFactory) -> tuple[list[tuple[int, bytes]], FusionRun,
                                                              Path]:
    """40 s racetrack fused while it flies (tee into a list and a FusionRun) and recorded."""
    setup = SimSetup.build(duration_s=40.0, seed=5, gnss_off=["25:5"])
    config = filter_config("industrial-mems", gnss_preset("modern"), "loop")
    frames: list[tuple[int, bytes]] = []
    live = FusionRun(config, "none")
    report = fly(setup, tee(lambda t, f: frames.append((t, f)), live, None))
    assert report.ended is None and report.frames == len(frames) > 10_000
    assert report.sim_duration_s == pytest.approx(40.0, abs=0.01)
    log = tmp_path_factory.mktemp("pipe") / "run.tlog"
    record_flight(setup, log)
    return frames, live, log


def test_fused_while_flying_equals_fused_afterwards_and_from_the_recording(flown) -> None:
    """GIVEN one flight WHEN fused as it flies, from the frames kept in memory, and from its
    .tlog THEN the three give bit-identical estimates (the same seed flies the same bytes)."""
    frames, live, log = flown
    after = fuse_frames(frames, live.config, "none")
    recorded = [(t, f) for t, f in read_tlog(log)]
    assert [f for _, f in recorded] == [f for _, f in frames]
    assert live.collector is not None and after.collector is not None
    a, b = live.collector.estimates, after.collector.estimates
    assert len(a) == len(b) > 1000
    for x, y in zip(a, b, strict=True):
        assert (x.time_us, x.lat_rad, x.lon_rad, x.alt_msl_m) == (
            y.time_us, y.lat_rad, y.lon_rad, y.alt_msl_m)
        np.testing.assert_array_equal(x.v_ned_mps, y.v_ned_mps)
    assert live.collector.end_s() == pytest.approx(40.0, abs=0.1)


def test_a_run_without_collection_steps_the_same_filter(flown) -> None:
    frames, live, _ = flown
    bare = FusionRun(live.config, "none", collect=False)
    estimates = [e for _, f in frames for e in bare.feed_frame(f)]
    assert bare.collector is None
    assert live.collector is not None
    assert [e.time_us for e in estimates] == [e.time_us for e in live.collector.estimates]
    assert estimates[-1].lat_rad == live.collector.estimates[-1].lat_rad


def test_sim_chain_steps_only_inside_its_context() -> None:
    chain = SimChain(SimSetup.build(duration_s=1.0))
    with pytest.raises(RuntimeError, match="with"):
        next(chain.steps())
    with chain:
        steps = list(chain.steps())
    assert len(steps) == 200 and chain.ended is None
    assert chain.sim_duration_s == pytest.approx(1.0)
    assert all(step.frames for step in steps)
