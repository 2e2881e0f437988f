"""sim.faults: every event changes the sensor stream the way its docstring says, the timeline
check, determinism, and the sensor streamer dropping the HIL_GPS frames of an outage.

GIVEN a short SensorSuite run over a synthetic truth (level, north at 20 m/s, no JSBSim), WHEN
a fault timeline is applied, THEN the faulted stream is compared with the unfaulted one (the
suite's output does not depend on the injector, so one suite run serves both).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from functools import cache
from typing import Any

import numpy as np
import pytest
from pydantic import ValidationError
from scipy.spatial.transform import Rotation

from hil.codec import Decoder
from hil.streamer import GnssWindow, SensorStreamer
from sim._sensor_common import ecef_from_geodetic_m, meridian_prime_radii_m
from sim.faults import (
    EVENT_TYPES,
    PX4_FAILURE,
    AirspeedFailure,
    BaroDrift,
    BaroFreeze,
    BaroGlitch,
    FaultEvent,
    FaultInjector,
    FaultLogEntry,
    GnssDegradation,
    GnssDelay,
    GnssJamming,
    GnssOutage,
    GnssRate,
    GnssSpoofDrift,
    GnssSpoofHijack,
    ImuBiasStep,
    ImuSaturation,
    ImuStuck,
    MagAnomaly,
    PitotBlockage,
    PitotDrift,
    WeatherFront,
    check_events,
    px4_failure,
)
from sim.faults.events import field_unit
from sim.faults.timeline import Conflict, OutsideFlight, timeline_problems
from sim.presets import suite_config
from sim.samples import AirspeedSample, BaroSample, GnssFix, ImuSample, MagSample, Sample, Truth
from sim.sensors import SensorSuite

G = 9.80665
LAT0 = math.radians(47.0)
LON0 = math.radians(8.0)
ALT = 500.0
SPEED = 20.0  # m/s north
RATE_HZ = 50.0
STEP_US = round(1e6 / RATE_HZ)
R_M, R_N = meridian_prime_radii_m(LAT0)
LEVEL_NORTH = np.array([1.0, 0.0, 0.0, 0.0])

Step = tuple[Truth, list[Sample]]


def truth_at(time_us: int, q_nb: np.ndarray = LEVEL_NORTH) -> Truth:
    """Level flight due north at SPEED, constant altitude (a synthetic truth, no JSBSim)."""
    t = time_us * 1e-6
    return Truth(
        time_us=time_us,
        lat_rad=LAT0 + SPEED * t / (R_M + ALT),
        lon_rad=LON0,
        alt_msl_m=ALT,
        v_ned_mps=np.array([SPEED, 0.0, 0.0]),
        q_nb=q_nb,
        omega_b_rps=np.zeros(3),
        specific_force_b_mps2=np.array([0.0, 0.0, -G]),
        static_pressure_pa=95000.0,
        temperature_k=285.0,
        airspeed_mps=SPEED,
        indicated_airspeed_mps=SPEED,
    )


SECONDS = 15.0


@cache
def baseline() -> tuple[Step, ...]:
    """Unfaulted suite output per step over SECONDS (modern GNSS: 5 Hz, 0.1 s latency;
    everything else 50 Hz)."""
    suite = SensorSuite(suite_config(), seed=3, sim_rate_hz=RATE_HZ)
    steps = []
    for k in range(round(SECONDS * RATE_HZ) + 1):
        truth = truth_at(k * STEP_US)
        steps.append((truth, suite.step(truth)))
    return tuple(steps)


def run(events: Sequence[FaultEvent], *, seed: int = 0) -> tuple[list[Step], FaultInjector]:
    inj = FaultInjector(events, seed=seed, t0_us=0)
    return [(tr, inj.apply(tr, s)) for tr, s in baseline()], inj


def of_type(steps: Sequence[Step], cls: type) -> list[tuple[int, Any]]:
    """``(emission step time, sample)`` of one sample type, in stream order."""
    return [(tr.time_us, s) for tr, out in steps for s in out if isinstance(s, cls)]


def fixes(steps: Sequence[Step]) -> dict[int, GnssFix]:
    return {f.time_us: f for _, f in of_type(steps, GnssFix)}


def by_time(steps: Sequence[Step], cls: type) -> dict[int, Any]:
    return {s.time_us: s for _, s in of_type(steps, cls)}


def ned_offset_m(a: GnssFix, b: GnssFix) -> np.ndarray:
    """Position of ``a`` relative to ``b``: N, E through ECEF (independent of the injector's
    radii), D from the altitudes."""
    d = np.subtract(
        ecef_from_geodetic_m(a.lat_rad, a.lon_rad, a.alt_msl_m),
        ecef_from_geodetic_m(b.lat_rad, b.lon_rad, a.alt_msl_m),
    )
    sl, cl = math.sin(b.lat_rad), math.cos(b.lat_rad)
    so, co = math.sin(b.lon_rad), math.cos(b.lon_rad)
    north = -sl * co * d[0] - sl * so * d[1] + cl * d[2]
    east = -so * d[0] + co * d[1]
    return np.array([north, east, b.alt_msl_m - a.alt_msl_m])


def in_window(time_us: int, start_s: float, end_s: float) -> bool:
    return start_s <= time_us * 1e-6 < end_s


# --------------------------------------------------------------------------- vocabulary


def test_px4_failure_covers_every_event_type_with_valid_vocabulary() -> None:
    assert len(EVENT_TYPES) == 18
    assert set(PX4_FAILURE) == set(EVENT_TYPES)
    units = {"gps", "baro", "accel", "gyro", "mag", "airspeed"}
    kinds = {"off", "stuck", "garbage", "wrong", "slow", "delayed", "intermittent"}
    for name, (unit, kind) in PX4_FAILURE.items():
        assert unit in units and kind in kinds, name
        assert EVENT_TYPES[name].type_name == name  # type: ignore[attr-defined]
    assert PX4_FAILURE["gnss_outage"] == ("gps", "off")
    assert px4_failure(ImuStuck(1.0, 2.0, sensor="gyro", axis=2)) == ("gyro", "stuck")
    assert px4_failure(ImuBiasStep(1.0, None, sensor="accel", axis=0, value=0.1)) == (
        "accel",
        "wrong",
    )
    assert px4_failure(AirspeedFailure(1.0)) == ("airspeed", "off")
    assert px4_failure(PitotBlockage(1.0, mode="stuck")) == ("airspeed", "stuck")
    assert px4_failure(PitotBlockage(1.0, mode="zero")) == ("airspeed", "wrong")


@pytest.mark.parametrize(
    ("make", "match"),
    [
        (lambda: GnssOutage(-1.0, 5.0), r"GnssOutage\nstart_s\n  .* greater than or equal to 0"),
        (lambda: GnssOutage(1.0, -5.0), r"GnssOutage\nduration_s\n  .* greater than 0"),
        (lambda: GnssOutage(1.0, math.inf), r"GnssOutage\nduration_s\n  .* finite number"),
        (lambda: GnssRate(0.0, 1.0, rate_hz=0.0), r"GnssRate\nrate_hz\n  .* greater than 0"),
        (lambda: GnssDelay(0.0, 1.0, extra_latency_s=-0.1), r"extra_latency_s\n  .* than 0"),
        (lambda: GnssJamming(0.0, 1.0, flap_duty=1.5), r"GnssJamming\nflap_duty\n"),
        (lambda: GnssJamming(0.0, 1.0, flap_period_s=0.0), r"flap_period_s\n  .* greater than 0"),
        (lambda: GnssDegradation(0.0, 1.0, factor=0.5), r"GnssDegradation\nfactor\n  .* to 1"),
        (lambda: GnssSpoofDrift(0.0, 1.0, rate_mps=-1.0), r"GnssSpoofDrift\nrate_mps\n"),
        (lambda: GnssSpoofHijack(0.0, 1.0, (1.0, 2.0)), r"offset_ned_m\.2\n  Field required"),  # type: ignore[arg-type]
        (lambda: ImuStuck(0.0, 1.0, sensor="gyro", axis=3), r"ImuStuck\naxis\n  .* 0, 1 or 2"),
        (lambda: ImuStuck(0.0, 1.0, sensor="gyro", axis=True), r"ImuStuck\naxis\n  .* 0, 1 or 2"),
        (lambda: ImuStuck(0.0, 1.0, sensor="baro", axis=0), r"ImuStuck\nsensor\n  Input should be"),  # type: ignore[arg-type]
        (lambda: ImuSaturation(0.0, 1.0, sensor="accel", limit=0.0), r"limit\n  .* greater than 0"),
        (lambda: ImuBiasStep(0.0, 1.0, "gyro", 1, math.nan), r"ImuBiasStep\nvalue\n  .* finite"),
        (lambda: MagAnomaly(0.0, 1.0, ("a", 0.0, 0.0)), r"MagAnomaly\noffset_ned_t\.0\n"),  # type: ignore[arg-type]
        (lambda: BaroGlitch(True, 1.0), r"BaroGlitch\nstart_s\n  Input should be a valid number"),
    ],
)
def test_bad_event_fields_name_the_field(make: Any, match: str) -> None:
    # pydantic's message: "N validation error(s) for CLASS", then the field, then the rule
    with pytest.raises(ValidationError, match=match):
        make()


def test_events_are_frozen_and_normalised() -> None:
    ev = GnssSpoofHijack(2, None, [10, 0, 0])  # type: ignore[arg-type]
    assert ev.offset_ned_m == (10.0, 0.0, 0.0) and isinstance(ev.start_s, float)
    assert ev.end_s is None and GnssOutage(2.0, 3.0).end_s == 5.0
    with pytest.raises(ValidationError, match="frozen"):
        ev.start_s = 3.0  # type: ignore[misc]
    assert hash(ev) == hash(GnssSpoofHijack(2.0, None, (10.0, 0.0, 0.0)))
    # keywords, positions and a mapping build the same event
    assert ev == GnssSpoofHijack(start_s=2.0, offset_ned_m=(10.0, 0.0, 0.0))
    assert ev == GnssSpoofHijack.model_validate(
        {"type": "gnss_spoof_hijack", "start_s": 2, "offset_ned_m": [10, 0, 0]}
    )
    with pytest.raises(TypeError, match="positional"):
        GnssOutage(1.0, 2.0, 3.0)  # type: ignore[call-arg]


def test_fields_declare_their_units() -> None:
    assert field_unit(GnssOutage, "start_s") == "s"
    assert field_unit(BaroGlitch, "offset_pa") == "Pa"
    assert field_unit(WeatherFront, "rate_pa_per_s") == "Pa/s"
    assert field_unit(MagAnomaly, "offset_ned_t") == "T"
    assert field_unit(ImuBiasStep, "value", "gyro") == "rad/s"
    assert field_unit(ImuSaturation, "limit", "accel") == "m/s^2"
    assert field_unit(ImuBiasStep, "value") is None and field_unit(ImuStuck, "axis") is None


def test_injector_rejects_bad_seed_and_non_events() -> None:
    with pytest.raises(ValueError, match="seed"):
        FaultInjector([], seed=-1)
    with pytest.raises(ValueError, match="not a fault event"):
        FaultInjector([object()], seed=0)  # type: ignore[list-item]


# --------------------------------------------------------------------------- timeline check


@pytest.mark.parametrize(
    ("events", "match"),
    [
        ([GnssOutage(60.0, 5.0)], r"event 0 \(gnss_outage\) starts at 60 s, at or after the end"),
        ([BaroGlitch(50.0, 20.0)], r"event 0 \(baro_glitch\) ends at 70 s, after the end"),
        (
            [GnssOutage(10.0, 20.0), GnssSpoofDrift(25.0, None)],
            r"event 0 \(gnss_outage\) and event 1 \(gnss_spoof_drift\) overlap from 25 s to 30 s"
            r".*at most one GNSS position fault",
        ),
        ([GnssSpoofDrift(10.0, 20.0), GnssSpoofHijack(5.0, 10.0)], r"GNSS position fault"),
        ([BaroFreeze(10.0, 5.0), BaroGlitch(12.0, 1.0)], r"at most one barometer sensor fault"),
        (
            [ImuStuck(10.0, 5.0, "gyro", 1), ImuBiasStep(0.0, None, "gyro", 1, 0.01)],
            r"gyro axis 1 cannot be stuck and biased",
        ),
        ([GnssDelay(1.0, 5.0), GnssDelay(3.0, 5.0)], r"two gnss_delay events"),
        ([WeatherFront(1.0, 5.0), WeatherFront(3.0, 5.0)], r"two weather_front events"),
        (
            [ImuSaturation(1.0, 5.0, "accel", 30.0), ImuSaturation(3.0, 5.0, "accel", 20.0, 2)],
            r"two saturation limits",
        ),
    ],
)
def test_check_events_rejects_with_a_clear_message(
    events: list[FaultEvent], match: str
) -> None:
    with pytest.raises(ValueError, match=match):
        check_events(events, duration_s=60.0)


def test_check_events_lists_every_problem_once() -> None:
    with pytest.raises(ValueError) as info:
        check_events([GnssOutage(70.0, 1.0), BaroFreeze(1.0, 5.0), BaroDrift(2.0, 1.0)], 60.0)
    text = str(info.value)
    assert text.count("event 0") == 1 and "event 1 (baro_freeze) and event 2 (baro_drift)" in text


def test_timeline_problems_are_records_in_timeline_order() -> None:
    events = [GnssOutage(70.0, 1.0), BaroGlitch(50.0, 20.0), BaroFreeze(1.0, 5.0),
              BaroDrift(2.0, 1.0)]
    assert timeline_problems(events, 60.0) == [
        OutsideFlight(0, "start_s", 70.0, 60.0),
        OutsideFlight(1, "duration_s", 70.0, 60.0),
        Conflict(2, 3, 2.0, 3.0, "at most one barometer sensor fault (drift, glitch, freeze) "
                 "may be active at a time (a weather front may overlap any of them)"),
    ]
    assert timeline_problems(events[2:3], 60.0) == []


def test_check_events_accepts_compatible_timelines() -> None:
    check_events(
        [
            GnssOutage(10.0, 10.0),
            GnssSpoofDrift(20.0, 10.0),  # touches the outage, does not overlap it
            GnssDelay(5.0, 30.0),  # timing faults combine with position faults
            GnssRate(0.0, None),
            WeatherFront(0.0, None),  # ambient: overlaps baro sensor faults
            BaroGlitch(5.0, 1.0),
            BaroFreeze(7.0, 1.0),
            ImuStuck(1.0, 10.0, "gyro", 1),
            ImuBiasStep(1.0, 10.0, "gyro", 2, 0.01),  # other axis
            ImuBiasStep(1.0, 10.0, "accel", 1, 0.1),  # other sensor
            ImuBiasStep(2.0, 10.0, "accel", 1, 0.1),  # bias steps add up
            ImuSaturation(0.0, None, "accel", 50.0),
            MagAnomaly(0.0, None),
            MagAnomaly(5.0, 5.0),
        ],
        duration_s=60.0,
    )
    with pytest.raises(ValueError, match="duration_s"):
        check_events([], duration_s=0.0)


# --------------------------------------------------------------------------- injector basics


def test_no_active_event_leaves_samples_untouched_and_logs_boundaries() -> None:
    t0 = 5_000_000
    inj = FaultInjector([GnssOutage(1.0, 2.0), BaroGlitch(2.0, None)], seed=0, t0_us=t0)
    sample = BaroSample(t0 + 500_000, 95000.0, 288.0)
    out = inj.apply(truth_at(t0 + 500_000), [sample])
    assert out == [sample] and out[0] is sample and inj.log == []
    for k in range(0, 101):
        inj.apply(truth_at(t0 + k * 50_000), [])
    assert inj.log == [
        FaultLogEntry(t0 + 1_000_000, "gnss_outage", "start", 0),
        FaultLogEntry(t0 + 2_000_000, "baro_glitch", "start", 1),
        FaultLogEntry(t0 + 3_000_000, "gnss_outage", "end", 0),
    ]
    assert all(v == 0 for v in inj.counters.values())


def test_inputs_are_never_mutated() -> None:
    base = baseline()

    def imu_rows() -> list[tuple[int, np.ndarray]]:
        return [
            (s.time_us, s.specific_force_b_mps2.copy())
            for _, out in base
            for s in out
            if isinstance(s, ImuSample)
        ]

    before = imu_rows()
    run([ImuBiasStep(1.0, 3.0, "accel", 0, 0.5), ImuSaturation(1.0, 3.0, "accel", 1.0)])
    after = imu_rows()
    for (ta, a), (tb, b) in zip(before, after, strict=True):
        assert ta == tb
        np.testing.assert_array_equal(a, b)


# --------------------------------------------------------------------------- GNSS


def test_outage_removes_exactly_the_fixes_valid_in_its_window() -> None:
    steps, inj = run([GnssOutage(4.0, 3.0)])
    base, out = fixes(baseline()), fixes(steps)
    removed = sorted(set(base) - set(out))
    assert removed and all(in_window(t, 4.0, 7.0) for t in removed)
    assert all(not in_window(t, 4.0, 7.0) for t in out)
    assert len(removed) == 15 == inj.counters["gnss_dropped"]
    assert all(out[t] is base[t] for t in out)


def test_spoof_drift_pulls_position_at_rate_along_bearing() -> None:
    ev = GnssSpoofDrift(2.0, None, rate_mps=2.0, bearing_deg=30.0, vertical_rate_mps=0.5)
    steps, inj = run([ev])
    base, out = fixes(baseline()), fixes(steps)
    assert set(base) == set(out)
    b = math.radians(30.0)
    checked = 0
    for t, fix in out.items():
        dt = max(0.0, t * 1e-6 - 2.0)
        expected = np.array([2.0 * dt * math.cos(b), 2.0 * dt * math.sin(b), -0.5 * dt])
        np.testing.assert_allclose(ned_offset_m(fix, base[t]), expected, atol=0.01)
        if t >= 2_000_000:
            checked += 1
            np.testing.assert_allclose(
                fix.v_ned_mps - base[t].v_ned_mps,
                [2.0 * math.cos(b), 2.0 * math.sin(b), -0.5],
                atol=1e-12,
            )
            # A spoofer looks healthy.
            assert (fix.eph_m, fix.epv_m, fix.fix_type) == (
                base[t].eph_m,
                base[t].epv_m,
                base[t].fix_type,
            )
    last = max(out)
    assert np.linalg.norm(ned_offset_m(out[last], base[last])[:2]) == pytest.approx(
        2.0 * (last * 1e-6 - 2.0), abs=0.01
    )
    assert checked == inj.counters["gnss_spoofed"] > 60


def test_spoof_drift_without_consistent_velocity_keeps_velocity() -> None:
    steps, _ = run([GnssSpoofDrift(2.0, None, rate_mps=5.0, consistent_velocity=False)])
    base, out = fixes(baseline()), fixes(steps)
    t = max(out)
    np.testing.assert_array_equal(out[t].v_ned_mps, base[t].v_ned_mps)
    assert ned_offset_m(out[t], base[t])[1] == pytest.approx(5.0 * (t * 1e-6 - 2.0), abs=0.01)


def test_hijack_jumps_and_holds_then_releases() -> None:
    steps, _ = run([GnssSpoofHijack(4.0, 4.0, offset_ned_m=(300.0, -200.0, 10.0))])
    base, out = fixes(baseline()), fixes(steps)
    for t, fix in out.items():
        offset = ned_offset_m(fix, base[t])
        if in_window(t, 4.0, 8.0):
            np.testing.assert_allclose(offset, [300.0, -200.0, 10.0], atol=0.01)
            np.testing.assert_array_equal(fix.v_ned_mps, base[t].v_ned_mps)
        else:
            assert fix is base[t]


def test_degradation_scales_errors_and_reported_accuracy_with_ramp() -> None:
    steps, inj = run([GnssDegradation(3.0, 6.0, factor=4.0, ramp_s=2.0)])
    base, out = fixes(baseline()), fixes(steps)
    assert set(base) == set(out)
    for t, fix in out.items():
        if not in_window(t, 3.0, 9.0):
            assert fix is base[t]
            continue
        f = 1.0 + 3.0 * min(1.0, (t * 1e-6 - 3.0) / 2.0)
        tr = truth_at(t)
        # Errors in metres at the truth's radii (same scale for both fixes).
        scale = np.array([R_M + ALT, (R_N + ALT) * math.cos(tr.lat_rad), 1.0])
        truth_pos = np.array([tr.lat_rad, tr.lon_rad, tr.alt_msl_m])
        err = (np.array([fix.lat_rad, fix.lon_rad, fix.alt_msl_m]) - truth_pos) * scale
        err0 = (np.array([base[t].lat_rad, base[t].lon_rad, base[t].alt_msl_m]) - truth_pos)
        np.testing.assert_allclose(err, f * err0 * scale, atol=1e-6)
        np.testing.assert_allclose(
            fix.v_ned_mps - tr.v_ned_mps, f * (base[t].v_ned_mps - tr.v_ned_mps), atol=1e-9
        )
        assert fix.eph_m == pytest.approx(f * base[t].eph_m)
        assert fix.epv_m == pytest.approx(f * base[t].epv_m)
    assert inj.counters["gnss_degraded"] == 30


def test_jamming_blacks_out_then_flaps_with_garbage_fixes() -> None:
    ev = GnssJamming(2.0, 10.0, blackout_s=3.0, flap_period_s=2.0, flap_duty=0.5)
    steps, inj = run([ev])
    base, out = fixes(baseline()), fixes(steps)
    jammed = {t: f for t, f in out.items() if in_window(t, 2.0, 12.0)}
    # On for the first half of each 2 s period after the 3 s blackout: [5,6), [7,8), ...
    assert sorted({int(t * 1e-6) for t in jammed}) == [5, 7, 9, 11]
    assert len(jammed) == 20 == inj.counters["gnss_garbage"]
    assert inj.counters["gnss_dropped"] == 50 - 20
    for f in jammed.values():
        assert f.fix_type < 3 or f.eph_m >= 50.0
        assert f.eph_m >= 50.0 and f.satellites_visible <= 5
    assert {f.fix_type for f in jammed.values()} == {2, 3}
    horiz = np.array([ned_offset_m(f, base[t])[:2] for t, f in jammed.items()])
    rms = float(np.sqrt(np.mean(horiz**2)))
    assert 25.0 < rms < 100.0  # N(0, 50 m) per axis, 40 draws
    assert all(out[t] is base[t] for t in out if not in_window(t, 2.0, 12.0))


def test_delay_shifts_emission_not_validity_and_keeps_order() -> None:
    steps, inj = run([GnssDelay(3.0, 3.0, extra_latency_s=0.5)])
    base_emit = {f.time_us: t for t, f in of_type(baseline(), GnssFix)}
    emitted = of_type(steps, GnssFix)
    validity = [f.time_us for _, f in emitted]
    assert validity == sorted(base_emit)  # every fix, once, in order of validity
    for t_emit, f in emitted:
        assert f is fixes(baseline())[f.time_us]  # content untouched
        if in_window(f.time_us, 3.0, 6.0):
            assert t_emit == base_emit[f.time_us] + 500_000
        else:
            assert t_emit >= base_emit[f.time_us]
    # Fixes right after the window queue behind the delayed ones, none overtakes.
    assert [t for t, _ in emitted] == sorted(t for t, _ in emitted)
    assert inj.counters["gnss_delayed"] == 15 and inj.pending_gnss() == 0
    for tr, out in steps:
        times = [s.time_us for s in out]
        assert times == sorted(times) and all(x <= tr.time_us for x in times)


def test_rate_decimates_fixes_inside_the_window() -> None:
    steps, inj = run([GnssRate(2.0, 6.0, rate_hz=1.0)])
    base, out = fixes(baseline()), fixes(steps)
    inside = sorted(t for t in out if in_window(t, 2.0, 8.0))
    assert inside == [k * 1_000_000 for k in range(2, 8)]
    assert {t for t in base if not in_window(t, 2.0, 8.0)} == {
        t for t in out if not in_window(t, 2.0, 8.0)
    }
    assert inj.counters["gnss_dropped"] == 30 - 6


# --------------------------------------------------------------------------- barometer


def baro_offsets(events: Sequence[FaultEvent]) -> tuple[dict[int, float], dict[int, Any]]:
    steps, _ = run(events)
    base, out = by_time(baseline(), BaroSample), by_time(steps, BaroSample)
    assert set(base) == set(out)
    return {t: out[t].pressure_pa - base[t].pressure_pa for t in base}, out


def test_baro_drift_grows_while_active_and_clears() -> None:
    d, _ = baro_offsets([BaroDrift(3.0, 3.0, rate_pa_per_s=1.5)])
    for t, off in d.items():
        expect = 1.5 * (t * 1e-6 - 3.0) if in_window(t, 3.0, 6.0) else 0.0
        assert off == pytest.approx(expect, abs=1e-7)
    assert max(d.values()) == pytest.approx(1.5 * 2.98, abs=1e-7)


def test_baro_glitch_offsets_only_while_active() -> None:
    d, _ = baro_offsets([BaroGlitch(3.0, 0.5, offset_pa=-400.0)])
    for t, off in d.items():
        assert off == pytest.approx(-400.0 if in_window(t, 3.0, 3.5) else 0.0, abs=1e-7)


def test_weather_front_ramps_then_holds() -> None:
    d, _ = baro_offsets([WeatherFront(3.0, 4.0, rate_pa_per_s=-2.0)])
    for t, off in d.items():
        s = t * 1e-6
        expect = 0.0 if s < 3.0 else -2.0 * (min(s, 7.0) - 3.0)
        assert off == pytest.approx(expect, abs=1e-7)
    assert d[14_000_000] == pytest.approx(-8.0, abs=1e-7)


def test_baro_freeze_repeats_last_sample_with_new_times() -> None:
    steps, inj = run([BaroFreeze(3.0, 3.0)])
    base, out = by_time(baseline(), BaroSample), by_time(steps, BaroSample)
    last = base[max(t for t in base if t < 3_000_000)]
    frozen = [s for t, s in out.items() if in_window(t, 3.0, 6.0)]
    assert len(frozen) == 150 == inj.counters["baro_modified"]
    assert {(s.pressure_pa, s.temperature_k) for s in frozen} == {
        (last.pressure_pa, last.temperature_k)
    }
    assert len({s.time_us for s in frozen}) == 150
    assert len({base[s.time_us].pressure_pa for s in frozen}) > 1  # the real one moved
    assert all(out[t] is base[t] for t in out if not in_window(t, 3.0, 6.0))


# --------------------------------------------------------------------------- pitot


def test_pitot_blockage_stuck_holds_the_last_differential_pressure() -> None:
    steps, inj = run([PitotBlockage(3.0, 3.0, mode="stuck")])
    base, out = by_time(baseline(), AirspeedSample), by_time(steps, AirspeedSample)
    assert set(base) == set(out)  # still reporting, with new times
    last = base[max(t for t in base if t < 3_000_000)]
    held = [s for t, s in out.items() if in_window(t, 3.0, 6.0)]
    assert len(held) == 150 == inj.counters["airspeed_modified"]
    assert {s.diff_pressure_pa for s in held} == {last.diff_pressure_pa}
    assert len({base[s.time_us].diff_pressure_pa for s in held}) > 1  # the real one moved
    assert all(s.temperature_k == base[s.time_us].temperature_k for s in held)
    assert all(out[t] is base[t] for t in out if not in_window(t, 3.0, 6.0))


def test_pitot_blockage_zero_reads_zero_and_drift_ramps() -> None:
    steps, _ = run([PitotBlockage(2.0, 2.0, mode="zero"), PitotDrift(6.0, 4.0, rate_pa_per_s=3.0)])
    base, out = by_time(baseline(), AirspeedSample), by_time(steps, AirspeedSample)
    for t, s in out.items():
        if in_window(t, 2.0, 4.0):
            assert s.diff_pressure_pa == 0.0
        elif in_window(t, 6.0, 10.0):
            want = base[t].diff_pressure_pa + 3.0 * (t - 6_000_000) * 1e-6
            assert s.diff_pressure_pa == pytest.approx(want, rel=1e-14)
        else:
            assert s is base[t]


def test_airspeed_failure_removes_every_sample_in_its_window() -> None:
    steps, inj = run([AirspeedFailure(5.0, 2.0)])
    base, out = by_time(baseline(), AirspeedSample), by_time(steps, AirspeedSample)
    gone = {t for t in base if in_window(t, 5.0, 7.0)}
    assert len(gone) == 100 == inj.counters["airspeed_dropped"]
    assert set(out) == set(base) - gone
    # the other sensors are untouched
    assert by_time(steps, BaroSample) == by_time(baseline(), BaroSample)


def test_two_pitot_faults_at_once_contradict_each_other() -> None:
    problems = timeline_problems([PitotDrift(1.0, 5.0), AirspeedFailure(3.0, 1.0)], 10.0)
    assert len(problems) == 1 and isinstance(problems[0], Conflict)
    assert "one pitot fault" in problems[0].reason
    assert timeline_problems([PitotDrift(1.0, 2.0), AirspeedFailure(3.0, 1.0)], 10.0) == []


# --------------------------------------------------------------------------- IMU, magnetometer


def imu_pairs(events: Sequence[FaultEvent]) -> list[tuple[ImuSample, ImuSample]]:
    steps, _ = run(events)
    base, out = by_time(baseline(), ImuSample), by_time(steps, ImuSample)
    assert set(base) == set(out)
    return [(base[t], out[t]) for t in sorted(base)]


def test_imu_bias_step_adds_to_one_axis() -> None:
    for b, o in imu_pairs([ImuBiasStep(3.0, 3.0, "accel", 0, 0.2)]):
        step = 0.2 if in_window(b.time_us, 3.0, 6.0) else 0.0
        np.testing.assert_allclose(
            o.specific_force_b_mps2 - b.specific_force_b_mps2, [step, 0.0, 0.0], atol=1e-12
        )
        np.testing.assert_array_equal(o.angular_rate_b_rps, b.angular_rate_b_rps)
        assert (o.dt_s, o.temperature_k, o.sensor_id) == (b.dt_s, b.temperature_k, b.sensor_id)


def test_imu_stuck_axis_repeats_last_value() -> None:
    pairs = imu_pairs([ImuStuck(3.0, 3.0, "gyro", 2)])
    last = [b for b, _ in pairs if b.time_us < 3_000_000][-1].angular_rate_b_rps[2]
    stuck = [o for b, o in pairs if in_window(b.time_us, 3.0, 6.0)]
    assert len(stuck) == 150 and {float(o.angular_rate_b_rps[2]) for o in stuck} == {last}
    for b, o in pairs:
        np.testing.assert_array_equal(o.angular_rate_b_rps[:2], b.angular_rate_b_rps[:2])
        if not in_window(b.time_us, 3.0, 6.0):
            assert o is b


def test_imu_saturation_clips_at_limit() -> None:
    for b, o in imu_pairs([ImuSaturation(3.0, 3.0, "accel", limit=5.0)]):
        if in_window(b.time_us, 3.0, 6.0):
            assert o.specific_force_b_mps2[2] == -5.0
            np.testing.assert_array_equal(  # |x|, |y| < 5 m/s²: untouched
                o.specific_force_b_mps2[:2], b.specific_force_b_mps2[:2]
            )
        else:
            assert o is b


def test_mag_anomaly_adds_ned_offset_in_body_axes() -> None:
    steps, inj = run([MagAnomaly(3.0, 3.0, offset_ned_t=(2e-6, -1e-6, 3e-6))])
    base, out = by_time(baseline(), MagSample), by_time(steps, MagSample)
    for t in base:
        expect = [2e-6, -1e-6, 3e-6] if in_window(t, 3.0, 6.0) else [0.0, 0.0, 0.0]
        np.testing.assert_allclose(  # level, heading north: body = NED
            out[t].field_b_tesla - base[t].field_b_tesla, expect, atol=1e-15
        )
    assert inj.counters["mag_modified"] == 150


def test_mag_anomaly_rotation_matches_scipy() -> None:
    rng = np.random.default_rng(1)
    inj = FaultInjector([MagAnomaly(0.0, None, offset_ned_t=(1e-5, 2e-5, -3e-5))], seed=0)
    for _ in range(20):
        q = rng.standard_normal(4)
        q /= np.linalg.norm(q)
        (mag,) = inj.apply(truth_at(1000, q_nb=q), [MagSample(1000, np.zeros(3))])
        assert isinstance(mag, MagSample)
        expect = Rotation.from_quat([*q[1:], q[0]]).apply([1e-5, 2e-5, -3e-5], inverse=True)
        np.testing.assert_allclose(mag.field_b_tesla, expect, atol=1e-18)
    # Heading east: body x points east, y (right wing) south.
    q_east = np.array([math.cos(math.pi / 4), 0.0, 0.0, math.sin(math.pi / 4)])
    (mag,) = inj.apply(truth_at(2000, q_nb=q_east), [MagSample(2000, np.zeros(3))])
    assert isinstance(mag, MagSample)
    np.testing.assert_allclose(mag.field_b_tesla, [2e-5, -1e-5, -3e-5], atol=1e-18)


# --------------------------------------------------------------------------- whole stream


TIMELINE: list[FaultEvent] = [
    GnssRate(0.5, 2.0, rate_hz=2.0),
    GnssJamming(1.0, 5.0, blackout_s=1.0, flap_period_s=1.0),
    GnssDelay(4.0, 4.0, extra_latency_s=0.3),
    GnssDegradation(7.0, 3.0, factor=3.0, ramp_s=1.0),
    GnssSpoofDrift(10.0, None),
    BaroGlitch(2.0, 1.0),
    WeatherFront(1.0, 5.0),
    BaroFreeze(8.0, 2.0),
    ImuStuck(2.0, 2.0, "accel", 1),
    ImuSaturation(1.0, 5.0, "gyro", 1e-3),
    ImuBiasStep(5.0, None, "gyro", 0, 1e-3),
    MagAnomaly(6.0, 3.0),
    PitotDrift(3.0, 2.0, rate_pa_per_s=5.0),
    AirspeedFailure(6.0, 1.0),
    PitotBlockage(9.0, 2.0, mode="stuck"),
]


def flatten(steps: Sequence[Step]) -> list[tuple[Any, ...]]:
    rows: list[tuple[Any, ...]] = []
    for tr, out in steps:
        for s in out:
            values = [getattr(s, f) for f in s.__slots__]
            rows.append(
                (tr.time_us, type(s).__name__, *(np.asarray(v).tobytes() for v in values))
            )
    return rows


def test_same_seed_gives_identical_stream_other_seed_other_garbage() -> None:
    check_events(TIMELINE, duration_s=15.0)
    a, inj_a = run(TIMELINE, seed=5)
    b, inj_b = run(TIMELINE, seed=5)
    c, _ = run(TIMELINE, seed=6)
    assert flatten(a) == flatten(b)
    assert inj_a.log == inj_b.log and inj_a.counters == inj_b.counters
    assert flatten(a) != flatten(c)
    assert all(v > 0 for v in inj_a.counters.values()), inj_a.counters


def test_combined_timeline_keeps_every_step_in_time_order() -> None:
    steps, _ = run(TIMELINE, seed=5)
    last_fix = -1
    for tr, out in steps:
        times = [s.time_us for s in out]
        assert times == sorted(times) and all(x <= tr.time_us for x in times)
        for s in out:
            if isinstance(s, GnssFix):
                assert s.time_us > last_fix
                last_fix = s.time_us


# --------------------------------------------------------------------------- sensor streamer


def test_streamer_with_faults_drops_hil_gps_frames_of_an_outage() -> None:
    inj = FaultInjector([GnssOutage(2.0, 2.0)], seed=0, t0_us=0)
    streamer = SensorStreamer(faults=inj, gnss_off=[GnssWindow(1.0, 0.5)])
    plain = SensorStreamer()
    dec, dec_plain = Decoder(), Decoder()
    got: list[GnssFix] = []
    want: list[GnssFix] = []
    for tr, samples in baseline()[: round(6 * RATE_HZ) + 1]:
        for _, frame in streamer.frames(tr, samples):
            got += [d.sample for d in dec.feed(frame) if isinstance(d.sample, GnssFix)]
        for _, frame in plain.frames(tr, samples):
            want += [d.sample for d in dec_plain.feed(frame) if isinstance(d.sample, GnssFix)]
    got_t, want_t = [f.time_us for f in got], [f.time_us for f in want]
    assert got_t == [t for t in want_t if not in_window(t, 2.0, 4.0) and not in_window(t, 1, 1.5)]
    assert len(want_t) - len(got_t) == 13
    assert streamer.fault_counters["gnss_dropped"] == 10 and streamer.gnss_suppressed == 3
    assert [(e.time_us, e.phase) for e in streamer.fault_log] == [
        (2_000_000, "start"),
        (4_000_000, "end"),
    ]
    assert plain.fault_log == [] and plain.fault_counters == {}
