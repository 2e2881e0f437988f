"""The one pipeline (hil.pipeline): flight setups, lockstep flying, fusing, the filter factory."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from hil.codec import AUTOPILOT_COMPONENT_ID, Decoder
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
from hil.tlog import iter_decoded, read_tlog
from sim.presets import gnss_preset
from sim.samples import ActuatorSample, RpmSample
from sim.vehicle_state import VehicleStateConfig


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
    with pytest.raises(ValueError, match=r"alignment 'sideways'.*in-flight"):
        filter_config("industrial-mems", gnss_preset("modern"), align="sideways")


def test_the_commands_filter_aligns_automatically_unless_told() -> None:
    default = filter_config("industrial-mems", gnss_preset("modern"))
    assert default.init.mode == "auto" and default.mag.reference == "wmm"
    for choice, mode in (("static", "static"), ("in-flight", "in_flight"), ("auto", "auto")):
        cfg = filter_config("industrial-mems", gnss_preset("modern"), align=choice)
        assert cfg.init.mode == mode
        assert cfg.model_copy(update={"init": default.init}) == default


def test_the_commands_filter_carries_the_air_data_states_and_the_airspeed_choice() -> None:
    # the default layout has the (dormant) air-data block, with or without the GNSS bias block;
    # air data is used when the stream carries it (DEFAULT_AIRSPEED_MODE)
    default = filter_config("industrial-mems", gnss_preset("modern"))
    assert default.state_layout == "ins35+gnss+air" and default.airspeed.enabled
    on = filter_config("industrial-mems", gnss_preset("modern"), airspeed="on")
    assert on == default and not on.airspeed.synthetic_when_no_pitot
    off = filter_config("industrial-mems", gnss_preset("modern"), airspeed="off")
    assert off.state_layout == default.state_layout and not off.airspeed.enabled
    syn = filter_config("industrial-mems", gnss_preset("modern"), airspeed="synthetic")
    assert syn.airspeed.enabled and syn.airspeed.synthetic_when_no_pitot


@pytest.fixture(scope="module")
def flown(tmp_path_factory: pytest.TempPathFactory) -> tuple[list[tuple[int, bytes]], FusionRun,
                                                              Path]:
    """40 s racetrack fused while it flies (tee into a list and a FusionRun) and recorded."""
    setup = SimSetup.build(duration_s=40.0, seed=5, gnss_off=["25:5"])
    config = filter_config("industrial-mems", gnss_preset("modern"), "loop")
    frames: list[tuple[int, bytes]] = []
    live = FusionRun(config, "none", keep_objects=True)
    report = fly(setup, tee(lambda t, f: frames.append((t, f)), live, None))
    assert report.ended is None and report.frames == len(frames) > 10_000
    assert report.sim_duration_s == pytest.approx(40.0, abs=0.01)
    log = tmp_path_factory.mktemp("pipe") / "run.tlog"
    record_flight(setup, log)
    return frames, live, log


def test_fused_while_flying_equals_fused_afterwards_and_from_the_recording(flown) -> None:
    """GIVEN one flight WHEN fused as it flies (whole lockstep batches: decoded, then fused),
    from the frames kept in memory (frame by frame), and from its .tlog THEN the three give
    bit-identical estimates (the same seed flies the same bytes)."""
    frames, live, log = flown
    after = fuse_frames(frames, live.config, "none", keep_objects=True)
    assert live.samples == after.samples and live.decoder.counters == after.decoder.counters
    recorded = [(t, f) for t, f in read_tlog(log)]
    assert [f for _, f in recorded] == [f for _, f in frames]
    assert live.collector is not None and after.collector is not None
    a, b = live.collector.estimates, after.collector.estimates
    assert len(a) == len(b) > 1000
    for x, y in zip(a, b, strict=True):
        assert (x.time_us, x.lat_rad, x.lon_rad, x.alt_msl_m) == (
            y.time_us, y.lat_rad, y.lon_rad, y.alt_msl_m)
        np.testing.assert_array_equal(x.v_ned_mps, y.v_ned_mps)
        np.testing.assert_array_equal(x.P_diag, y.P_diag)
    assert [s.time_us for s in live.collector.truths] == [
        s.time_us for s in after.collector.truths]
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


def test_the_stream_carries_the_vehicle_state_without_changing_the_fusion(flown) -> None:
    """GIVEN the recorded flight WHEN decoded THEN it carries HIL_ACTUATOR_CONTROLS and RAW_RPM
    from the autopilot component at 50 Hz with nothing dropped; AND the same flight flown
    without them gives the same sensor bytes and bit-identical estimates (the filter does not
    use them yet; each component has its own sequence)."""
    frames, live, log = flown
    dec = Decoder()
    vehicle = [d for _, d in iter_decoded(log, dec)
               if isinstance(d.sample, ActuatorSample | RpmSample)]
    assert {d.component_id for d in vehicle} == {AUTOPILOT_COMPONENT_ID}
    act = [d.sample.time_us for d in vehicle if isinstance(d.sample, ActuatorSample)]
    rpm = [d.sample.time_us for d in vehicle if isinstance(d.sample, RpmSample)]
    assert act == rpm and len(act) == 2000 and set(np.diff(act)) == {20_000}
    c = dec.counters
    assert (c.controls_clipped, c.controls_invalid, c.rpm_invalid, c.rpm_untimed,
            c.ignored_msgs) == (0, 0, 0, 0, 0)
    setup = SimSetup.build(duration_s=40.0, seed=5, gnss_off=["25:5"])
    quiet = dataclasses.replace(setup, vehicle_state=VehicleStateConfig(actuators=False,
                                                                        rpm=False))
    without: list[tuple[int, bytes]] = []
    fly(quiet, lambda t, f: without.append((t, f)))
    # MAVLink 2 header: byte 6 is the component id
    autopilot = [f for _, f in frames if f[6] == AUTOPILOT_COMPONENT_ID]
    assert len(autopilot) == 4000
    assert [f for _, f in frames if f[6] != AUTOPILOT_COMPONENT_ID] == [f for _, f in without]
    other = fuse_frames(without, live.config, "none", keep_objects=True)
    assert live.collector is not None and other.collector is not None
    a, b = live.collector.estimates, other.collector.estimates
    assert len(a) == len(b) > 1000
    for x, y in zip(a, b, strict=True):
        assert (x.time_us, x.lat_rad, x.lon_rad, x.alt_msl_m) == (
            y.time_us, y.lat_rad, y.lon_rad, y.alt_msl_m)


def test_the_default_aircraft_streams_airspeed_and_without_a_pitot_nothing_else_changes() -> None:
    """GIVEN the same JSBSim flight with the default pitot and with ``pitot="none"`` WHEN both
    go through the encoder and a decoder (real MAVLink 2 bytes) THEN the default stream carries
    airspeed at 50 Hz in the same HIL_SENSOR frames as the barometer, its impact pressure
    matches the truth's airspeed within the sensor's errors, and every other decoded sample is
    bit-identical."""
    from hil.codec import Decoder
    from physconst.airdata import true_airspeed_mps
    from sim.samples import AirspeedSample, BaroSample, Truth

    def decoded(pitot: str) -> list[object]:
        frames: list[bytes] = []
        fly(SimSetup.build(duration_s=4.0, seed=2, pitot=pitot), lambda t, f: frames.append(f))
        dec = Decoder()
        out = [d.sample for f in frames for d in dec.feed(f)]
        assert dec.counters.bad_diff_pressure == 0
        return out

    with_pitot, without = decoded("ms4525do"), decoded("none")
    airspeed = [s for s in with_pitot if isinstance(s, AirspeedSample)]
    assert 199 <= len(airspeed) <= 201 and not any(isinstance(s, AirspeedSample) for s in without)
    baro_times = {s.time_us for s in with_pitot if isinstance(s, BaroSample)}
    assert {a.time_us for a in airspeed} == baro_times  # one HIL_SENSOR carries both
    truth = {s.time_us: s for s in with_pitot if isinstance(s, Truth)}
    baro = {s.time_us: s for s in with_pitot if isinstance(s, BaroSample)}
    # the decoded airspeed carries the HIL_SENSOR (barometer) temperature: the air's, here
    measured = [
        true_airspeed_mps(a.diff_pressure_pa, baro[a.time_us].pressure_pa, a.temperature_k)
        for a in airspeed if a.time_us in truth
    ]
    tas = [truth[a.time_us].airspeed_mps for a in airspeed if a.time_us in truth]
    # ms4525do: 2 % scale error (1σ, one draw) is 1 % in speed, the offset a few Pa of ~1.4 kPa:
    # 5 % of the speed is a 10σ bound on the scale draw
    assert len(tas) > 100
    assert np.max(np.abs(np.subtract(measured, tas))) < 0.05 * 50.0

    def key(s: object) -> tuple[object, ...]:
        return (type(s).__name__, *(np.asarray(getattr(s, f)).tobytes() for f in s.__slots__))  # type: ignore[attr-defined]

    others = [key(s) for s in with_pitot if not isinstance(s, AirspeedSample)]
    assert others == [key(s) for s in without]


def _stalling_setup() -> SimSetup:
    """A flight that stalls within its duration (pitch held at 25 deg, 50 Hz)."""
    from sim import presets
    from sim.flight import FlightConfig
    from sim.plans import FlightPlan, Leg

    plan = FlightPlan(
        name="stall",
        legs=(Leg(kind="attitude", pitch_deg=25.0, duration_s=600.0, airspeed_mps=20.0),),
    )
    return SimSetup(flight=FlightConfig(rate_hz=50.0, stall_alpha_deg=14.0), plan=plan,
                    sensors=presets.suite_config(), duration_s=600.0, seed=3)


def test_batched_steps_fly_the_same_steps_up_to_the_end_of_the_flight() -> None:
    """GIVEN a flight that stalls WHEN its chain steps one by one, in batches of 7, and when
    :func:`fly` sinks it in batches of 1 and 64 THEN every step (truth, samples as sent,
    frames) and every sunk frame is the same, the flight ends at the same step for the same
    reason, and the batch must be at least 1."""
    setup = _stalling_setup()

    def stepped(batch: int) -> tuple[list[tuple[object, ...]], str, int]:
        with SimChain(setup) as chain:
            out = [(s.truth.time_us, s.truth.lat_rad, tuple(s.truth.v_ned_mps), s.frames,
                    [type(x).__name__ for x in s.sensed]) for s in chain.steps(batch=batch)]
            with pytest.raises(ValueError, match="batch"):
                next(chain.steps(batch=0))
        assert chain.ended is not None
        return out, chain.ended.reason, chain.time_us

    one, seven = stepped(1), stepped(7)
    assert "stall" in one[1] and len(one[0]) > 100
    assert len(one[0]) % 7 != 0  # the flight ends inside a batch
    assert seven == one

    def sunk(batch: int) -> tuple[list[tuple[int, bytes]], int, float]:
        frames: list[tuple[int, bytes]] = []
        report = fly(setup, lambda t, f: frames.append((t, f)), batch=batch)
        assert report.ended is not None and report.frames == len(frames)
        return frames, report.frames, report.sim_duration_s

    by_one = sunk(1)
    assert by_one == sunk(64)
    assert [f for _, f in by_one[0]] == [f for s in one[0] for _, f in s[3]]


def test_a_thermal_imu_flies_with_its_temperature_on_the_wire() -> None:
    """GIVEN a flight with a BMI088's thermal model WHEN it is flown and decoded THEN every IMU
    sample carries the part's reported temperature (0.125 K steps about 23 C) and every
    barometer sample the barometer's; without the model the IMU gets the barometer's."""
    from hil.codec.wire import KELVIN_AT_0_CELSIUS
    from sim.samples import BaroSample, ImuSample

    def decoded(thermal: str) -> tuple[list[float], list[float]]:
        frames: list[bytes] = []
        fly(SimSetup.build(duration_s=3.0, seed=2, imu_thermal=thermal),
            lambda t, f: frames.append(f))
        dec = Decoder()
        out = [d.sample for f in frames for d in dec.feed(f)]
        return ([s.temperature_k for s in out if isinstance(s, ImuSample)],
                [s.temperature_k for s in out if isinstance(s, BaroSample)])

    imu, baro = decoded("bmi088")
    n = (np.array(imu) - KELVIN_AT_0_CELSIUS - 23.0) / 0.125
    np.testing.assert_allclose(n, np.round(n), atol=1e-9)
    plain_imu, plain_baro = decoded("off")
    assert set(plain_imu[1:]) <= set(plain_baro)  # the barometer's, as before
    assert baro == plain_baro  # the barometer's own, in its own frame
    grid = (np.array(plain_imu[1:]) - KELVIN_AT_0_CELSIUS - 23.0) / 0.125
    assert np.max(np.abs(grid - np.round(grid))) > 0.01  # not the part's steps
