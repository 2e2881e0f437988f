"""Zenoh bus: key space, payload schemas, and real sessions over loopback.

One in-process router (module scope) serves most tests; the reconnect test runs its own router
so it can stop and restart it. Waits poll for an outcome with a generous bound; nothing asserts
on elapsed time.
"""

from __future__ import annotations

import dataclasses
import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import jsonschema
import numpy as np
import pydantic
import pytest

from fusion.estimate import AirDataStatus, Health, NavEstimate, TestRatios
from fusion.rotations import euler_to_quat
from hil.bus import (
    PUBLISHED_TOPICS,
    SCHEMA_VERSION,
    SCHEMAS,
    Bus,
    BusConfig,
    Message,
    Topic,
    check_bus,
    encode,
    error_payload,
    estimate_payload,
    event_payload,
    fusion_event_payload,
    innovation_payload,
    key,
    parse_key,
    sample_payload,
    status_payload,
    truth_payload,
)
from hil.link.counters import LinkCounters
from hil.router import ZenohRouter, free_tcp_port, router_main, zenoh_router
from sim.samples import AirspeedSample, BaroSample, GnssFix, ImuSample, MagSample, Truth

LAT0, LON0, ALT0 = math.radians(47.0), math.radians(8.0), 1000.0
UNLIMITED = BusConfig(rates_hz=dict.fromkeys(PUBLISHED_TOPICS))


def wait_for(predicate: Callable[[], bool], timeout_s: float = 10.0) -> bool:
    """Poll ``predicate`` until true or ``timeout_s`` passes; the last value."""
    deadline = time.monotonic() + timeout_s
    while not predicate():
        if time.monotonic() > deadline:
            return predicate()
        time.sleep(0.01)
    return True


# --------------------------------------------------------------------------- sample objects
def make_truth(time_us: int = 1_000_000, *, yaw_deg: float = 30.0, north_m: float = 0.0) -> Truth:
    return Truth(
        time_us=time_us,
        lat_rad=LAT0 + north_m / 6_371_000.0,
        lon_rad=LON0,
        alt_msl_m=ALT0,
        v_ned_mps=np.array([40.0, 5.0, -1.0]),
        q_nb=euler_to_quat(np.radians([2.0, 3.0, yaw_deg])),
        omega_b_rps=np.array([0.01, 0.0, 0.02]),
        specific_force_b_mps2=np.array([0.1, 0.0, -9.8]),
        static_pressure_pa=89_875.0,
        temperature_k=281.65,
        airspeed_mps=41.0,
        indicated_airspeed_mps=39.0,
    )


@dataclass
class FakeEstimate:
    """NavEstimate-shaped object (duck typing: the bus must not need the real class)."""

    time_us: int = 1_000_000
    lat_rad: float = LAT0
    lon_rad: float = LON0
    alt_msl_m: float = ALT0
    v_ned_mps: Any = field(default_factory=lambda: np.array([40.0, 5.0, -1.0]))
    q_nb: Any = field(default_factory=lambda: euler_to_quat(np.radians([2.0, 3.0, 30.0])))
    P_diag: Any = field(default_factory=lambda: np.array([4.0, 9.0, 16.0] + [0.01] * 13))
    mode: str = "gnss"
    time_since_gnss_s: float = 0.2


def real_estimate(mode: str = "bridging") -> NavEstimate:
    return NavEstimate(
        time_us=2_000_000,
        lat_rad=LAT0,
        lon_rad=LON0,
        alt_msl_m=ALT0 + 3.0,
        v_ned_mps=np.array([40.0, 5.0, -1.0]),
        q_nb=euler_to_quat(np.radians([2.0, 3.0, 30.0])),
        euler_rad=np.radians([2.0, 3.0, 30.0]),
        P_diag=np.full(16, 0.25),
        mode=mode,
        accel_bias_b_mps2=np.array([0.01, -0.02, 0.03]),
        gyro_bias_b_rps=np.array([1e-5, 2e-5, -1e-5]),
        baro_bias_m=1.5,
        health=Health(gnss_fused=12, gnss_outages=1),
        test_ratios=TestRatios(gnss_pos=0.3),
        time_since_gnss_s=math.inf,
        state_layout="ins16",
    )


SENSORS = [
    ImuSample(1_000_000, 0.005, np.array([0.1, 0.0, -9.8]), np.array([0.0, 0.01, 0.0])),
    GnssFix(1_000_000, LAT0, LON0, ALT0, np.array([40.0, 5.0, -1.0]), 1.5, 3.0, 0.2),
    BaroSample(1_000_000, 89_875.0, 281.65),
    MagSample(1_000_000, np.array([2e-5, 1e-6, 4e-5])),
    AirspeedSample(1_000_000, 1_390.0, 283.65),
]


def every_payload() -> dict[Topic, dict[str, Any]]:
    """One payload per published topic, from the builders."""
    est = real_estimate()
    out = {Topic.TRUTH: truth_payload(make_truth())}
    for s in SENSORS:
        topic, payload = sample_payload(s)
        out[topic] = payload
    out[Topic.ESTIMATE] = estimate_payload(est)
    out[Topic.STATUS] = status_payload(
        est, bridge={"method": "gmdh", "trained": True}, links={"sim": LinkCounters(accepted=5)}
    )
    out[Topic.INNOVATIONS] = innovation_payload(
        2_000_000, "gnss_pos", [0.5, -0.2, 1.0], S=np.diag([4.0, 4.0, 9.0]), test_ratio=0.1,
        accepted=True,
    )  # fmt: skip
    out[Topic.ERROR] = error_payload(est, make_truth(2_000_000))
    out[Topic.EVENTS] = event_payload(3_000_000, "gnss_off", "GNSS jammed", {"duration_s": 60})
    out[Topic.FUSION_EVENTS] = fusion_event_payload(3_100_000, "mode", "warning",
                                                    "GNSS lost: dead-reckoning",
                                                    {"from": "gnss", "to": "dead-reckoning"})
    return out


# ------------------------------------------------------------------------------- key space
def test_keys_follow_the_architecture_key_space() -> None:
    assert key("sim1", Topic.TRUTH) == "hilnav/sim1/sim/truth"
    sensor_topics = (Topic.IMU, Topic.GNSS, Topic.BARO, Topic.MAG, Topic.AIRSPEED)
    assert [key("v", t) for t in sensor_topics] == [
        f"hilnav/v/sensors/{s}" for s in ("imu", "gnss", "baro", "mag", "airspeed")
    ]
    assert key("v", Topic.ESTIMATE) == "hilnav/v/fusion/estimate"
    assert key("v", Topic.STATUS) == "hilnav/v/fusion/status"
    assert key("v", Topic.INNOVATIONS) == "hilnav/v/fusion/innovations"
    assert key("v", Topic.ERROR) == "hilnav/v/fusion/error"
    assert key("v", Topic.EVENTS) == "hilnav/v/scenario/events"
    assert key("v", Topic.CONFIG) == "hilnav/v/fusion/config"
    assert key("v", Topic.ALIVE) == "hilnav/v/fusion/alive"
    assert key("*", "**") == "hilnav/*/**"
    for t in Topic:
        assert parse_key(key("uav-2.a", t)) == ("uav-2.a", t)
    assert parse_key("hilnav/v/other/thing") == ("v", None)


@pytest.mark.parametrize("vehicle", ["", "a/b", "*", "a*", "x$", "a b", "v?x"])
def test_bad_vehicle_names_are_rejected(vehicle: str) -> None:
    with pytest.raises(ValueError, match="vehicle"):
        Bus("tcp/127.0.0.1:1", vehicle=vehicle)


def test_bad_endpoints_modes_and_keys_are_rejected() -> None:
    with pytest.raises(ValueError, match="endpoint"):
        Bus("127.0.0.1:7447")
    with pytest.raises(ValueError, match="router endpoint"):
        Bus(None, mode="client")
    with pytest.raises(ValueError, match="mode"):
        Bus("tcp/127.0.0.1:1", mode="router")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="unknown topic"):
        key("v", "fusion/nothing")
    with pytest.raises(ValueError, match="not under"):
        parse_key("other/v/fusion/estimate")


# -------------------------------------------------------------------------------- payloads
def test_schemas_are_valid_json_schemas_for_every_topic() -> None:
    assert set(SCHEMAS) == set(Topic) - {Topic.ALIVE}
    for topic, schema in SCHEMAS.items():
        jsonschema.Draft202012Validator.check_schema(schema)
        assert schema["properties"]["schema_version"]["const"] == SCHEMA_VERSION
        assert "schema_version" in schema["required"], topic


def test_every_builder_matches_its_schema_field_for_field() -> None:
    payloads = every_payload()
    assert set(payloads) == set(PUBLISHED_TOPICS)
    for topic, payload in payloads.items():
        jsonschema.validate(payload, SCHEMAS[topic])
        # exact: no field the schema does not describe, none it promises missing
        assert set(payload) == set(SCHEMAS[topic]["properties"]), topic
        assert payload["schema_version"] == SCHEMA_VERSION


def test_estimate_payload_units_and_non_finite_values() -> None:
    est = real_estimate()
    p = estimate_payload(est)
    assert p["lat_deg"] == pytest.approx(47.0) and p["lon_deg"] == pytest.approx(8.0)
    assert [p["roll_deg"], p["pitch_deg"], p["yaw_deg"]] == pytest.approx([2.0, 3.0, 30.0])
    assert p["pos_sigma_ned_m"] == pytest.approx([0.5, 0.5, 0.5])
    assert p["att_sigma_deg"] == pytest.approx([math.degrees(0.5)] * 3)
    assert p["time_since_gnss_s"] is None  # inf is not JSON
    assert p["mode"] == "bridging"
    s = status_payload(est)
    assert s["test_ratios"]["gnss_pos"] == 0.3 and s["test_ratios"]["gnss_vel"] is None
    assert s["health"]["gnss_fused"] == 12
    encode(p)  # valid JSON (allow_nan=False)
    # duck typing: no euler_rad -> derived from q_nb; P_diag of another length still read
    d = estimate_payload(FakeEstimate())
    assert d["yaw_deg"] == pytest.approx(30.0)
    assert d["pos_sigma_ned_m"] == pytest.approx([2.0, 3.0, 4.0])
    assert d["gyro_bias_b_rps"] is None


def test_status_payload_carries_the_air_data_turbulence_and_flags() -> None:
    # GIVEN an estimate whose air data learned its turbulence and flagged a pitot reading
    air = AirDataStatus("fusing", True, (4.0, -3.0), 0.01, 50.0, "", (0.2, -0.1), 0.4,
                        "estimated", "pitot_implausible", 0.12)
    s = status_payload(dataclasses.replace(real_estimate(), air_data=air))
    # THEN the status payload carries them, valid against the published schema
    a = s["air_data"]
    assert a["turbulence_mps"] == 0.4 and a["turbulence_source"] == "estimated"
    assert a["flags"] == "pitot_implausible" and a["position_error_per_rad"] == 0.12
    jsonschema.validate(s, SCHEMAS[Topic.STATUS])
    encode(s)


_EDGE_VALUES = [0.0, -0.0, 5e-324, -5e-324, 1e-300, -1e-300, 1.0, -1.0, 1e300, -1e300,
                math.inf, -math.inf, math.nan]


def test_estimate_payload_fast_path_gives_the_bytes_of_the_numpy_formulation() -> None:
    """GIVEN estimates with random and edge values (-0.0, subnormals, +-inf, NaN) in the
    variances and biases WHEN their payload is encoded THEN the bytes are those of the same
    values given as lists (the generic numpy conversion), and the sigmas are exactly
    ``np.sqrt(np.maximum(P, 0))`` (``np.degrees`` for attitude), non-finite as null."""
    rng = np.random.default_rng(15)
    base = real_estimate()
    for i in range(300):
        if i % 3 == 0:
            p_diag = rng.choice(_EDGE_VALUES, 16)
            bias = rng.choice(_EDGE_VALUES, 3)
        else:
            p_diag = rng.normal(0.0, 1.0, 16) * 10.0 ** rng.integers(-9, 9, 16)
            bias = rng.normal(0.0, 1e-3, 3)
        est = dataclasses.replace(base, P_diag=p_diag, accel_bias_b_mps2=bias,
                                  v_ned_mps=rng.normal(0.0, 30.0, 3),
                                  euler_rad=rng.uniform(-3.0, 3.0, 3))
        as_lists = dataclasses.replace(
            est, P_diag=p_diag.tolist(), accel_bias_b_mps2=bias.tolist(),
            v_ned_mps=est.v_ned_mps.tolist(), q_nb=est.q_nb.tolist(),
            euler_rad=est.euler_rad.tolist(), gyro_bias_b_rps=est.gyro_bias_b_rps.tolist())
        got = estimate_payload(est)
        assert encode(got) == encode(estimate_payload(as_lists))
        sd = np.sqrt(np.maximum(p_diag[:9], 0.0))
        want = [[x if math.isfinite(x) else None for x in a.tolist()]
                for a in (sd[0:3], sd[3:6], np.degrees(sd[6:9]))]
        sigmas = [got["pos_sigma_ned_m"], got["vel_sigma_ned_mps"], got["att_sigma_deg"]]
        assert encode({"s": sigmas}) == encode({"s": want})  # bytes: -0.0 is not 0.0


def test_error_payload_is_estimate_minus_truth() -> None:
    truth = make_truth(yaw_deg=-179.0)
    est = FakeEstimate(
        lat_rad=truth.lat_rad + 10.0 / 6_378_000.0,  # ~10 m north
        alt_msl_m=ALT0 + 2.0,
        v_ned_mps=np.array([41.0, 5.0, -1.0]),
        q_nb=euler_to_quat(np.radians([2.0, 3.0, 179.0])),
    )
    e = error_payload(est, truth)
    assert e["pos_error_ned_m"][0] == pytest.approx(10.0, abs=0.1)
    assert e["pos_error_ned_m"][1] == pytest.approx(0.0, abs=1e-6)
    assert e["pos_error_ned_m"][2] == pytest.approx(-2.0)
    assert e["vertical_error_m"] == pytest.approx(2.0)
    assert e["horizontal_error_m"] == pytest.approx(10.0, abs=0.1)
    assert e["vel_error_ned_mps"] == pytest.approx([1.0, 0.0, 0.0])
    assert e["yaw_error_deg"] == pytest.approx(-2.0)  # 179 - (-179) wraps to -2
    assert e["att_error_deg"] == pytest.approx(2.0, abs=0.01)


def test_bad_payload_input_names_the_field() -> None:
    with pytest.raises(ValueError, match="time_us"):
        estimate_payload(object())
    with pytest.raises(ValueError, match="q_nb"):
        estimate_payload(FakeEstimate(q_nb=np.array([1.0, 0.0, 0.0])))
    with pytest.raises(ValueError, match="lat_rad"):
        estimate_payload(FakeEstimate(lat_rad=math.nan))
    with pytest.raises(ValueError, match="time_us"):
        estimate_payload(FakeEstimate(time_us=1.5))  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="P_diag"):
        estimate_payload(FakeEstimate(P_diag=np.ones(3)))
    with pytest.raises(ValueError, match="sensor sample"):
        sample_payload(object())
    with pytest.raises(ValueError, match="JSON"):
        encode({"x": math.nan})
    with pytest.raises(ValueError, match="JSON"):
        encode({"x": object()})
    assert encode({"x": np.float32(1.5), "v": np.arange(2)}) == (
        b'{"schema_version":1,"x":1.5,"v":[0,1]}'
    )


def test_config_rejects_bad_rates_and_unknown_keys() -> None:
    with pytest.raises(pydantic.ValidationError, match="rates_hz"):
        BusConfig(rates_hz={"fusion/nope": 10.0})  # type: ignore[dict-item]
    with pytest.raises(pydantic.ValidationError, match="rate of fusion/estimate"):
        BusConfig(rates_hz={Topic.ESTIMATE: -1.0})
    with pytest.raises(pydantic.ValidationError, match="not a published topic"):
        BusConfig(rates_hz={Topic.CONFIG: 1.0})
    with pytest.raises(pydantic.ValidationError, match="queue_sise"):
        BusConfig(queue_sise=3)  # type: ignore[call-arg]
    assert BusConfig(rates_hz={"fusion/estimate": 5}).rate_hz(Topic.ESTIMATE) == 5.0  # type: ignore[dict-item]


# ------------------------------------------------------------------ local bus (no network)
def test_rate_limit_decimates_on_simulated_time() -> None:
    # standalone peer session: publishing needs no router
    cfg = BusConfig(rates_hz={Topic.IMU: 25.0})
    with Bus(None, mode="peer", config=cfg) as bus:
        got: list[Message] = []
        bus.subscribe(Topic.IMU, got.append)
        assert wait_for(lambda: bus.has_subscribers(Topic.IMU))
        for i in range(400):  # 2 s of a 200 Hz IMU
            s = ImuSample(i * 5000, 0.005, np.zeros(3), np.zeros(3))
            bus.publish_sample(s)
        assert wait_for(lambda: len(got) == 50)
        st = bus.stats()
        assert (st.enqueued, st.decimated) == (50, 350)
        times = [m.payload["time_us"] for m in got if m.payload]
        assert np.all(np.diff(times) == 40_000)  # evenly spaced at 25 Hz of simulated time
        # a new run (time back to 0) starts over instead of waiting for the old schedule
        assert bus.publish_sample(ImuSample(0, 0.005, np.zeros(3), np.zeros(3)))


def test_publish_needs_an_open_bus_and_a_published_topic() -> None:
    bus = Bus(None, mode="peer")
    with pytest.raises(RuntimeError, match="not open"):
        bus.publish(Topic.EVENTS, {"time_us": 0})
    with bus:
        with pytest.raises(ValueError, match="cannot publish"):
            bus.publish(Topic.CONFIG, {})
    with pytest.raises(RuntimeError, match="closed"):
        bus.open()


# ----------------------------------------------------------------------- over the router
def test_round_trip_of_every_topic_with_schema_version(router: str) -> None:
    payloads = every_payload()
    got: dict[Topic, Message] = {}
    with (
        Bus(router, vehicle="rt", config=UNLIMITED) as pub,
        Bus(router, vehicle="rt") as sub,
    ):
        sub.subscribe("**", lambda m: got.setdefault(m.topic, m) if m.topic else None)
        assert wait_for(lambda: all(pub.has_subscribers(t) for t in payloads))
        for topic, payload in payloads.items():
            assert pub.publish(topic, payload)
        assert wait_for(lambda: len(got) == len(payloads))
    for topic, payload in payloads.items():
        m = got[topic]
        assert m.key == f"hilnav/rt/{topic.value}" and m.vehicle == "rt"
        assert m.payload == payload
        assert m.payload is not None and m.payload["schema_version"] == SCHEMA_VERSION
        jsonschema.validate(m.payload, SCHEMAS[topic])


def test_typed_publish_helpers_and_vehicle_isolation(router: str) -> None:
    mine: list[Message] = []
    every: list[Message] = []
    with (
        Bus(router, vehicle="a", config=UNLIMITED) as a,
        Bus(router, vehicle="b", config=UNLIMITED) as b,
        Bus(router, vehicle="a") as sub,
    ):
        sub.subscribe(Topic.ESTIMATE, mine.append)
        sub.subscribe("**", every.append, vehicle="*")
        assert wait_for(lambda: all(a.has_subscribers(t) for t in PUBLISHED_TOPICS))
        assert wait_for(lambda: b.has_subscribers(Topic.ESTIMATE))
        est, truth = real_estimate(), make_truth(2_000_000)
        assert a.publish_estimate(est) and b.publish_estimate(est)
        assert a.publish_truth(truth) and a.publish_error(est, truth)
        assert a.publish_status(est, links={"sim": LinkCounters()})
        assert a.publish_innovation(2_000_000, "baro_hgt", [0.3], S=[[1.0]], accepted=False)
        assert a.publish_event(2_000_000, "gnss_on")
        for s in SENSORS:
            assert a.publish_sample(s)
        assert wait_for(lambda: len(every) == 12)
        assert wait_for(lambda: len(mine) == 1)
    assert mine[0].payload == estimate_payload(est)
    assert sorted(m.vehicle for m in every) == ["a"] * 11 + ["b"]
    status = next(m.payload for m in every if m.topic is Topic.STATUS)
    assert status is not None and status["bus"]["enqueued"] >= 2  # the publisher's counters


def test_config_queryable_answers(router: str) -> None:
    class Cfg(pydantic.BaseModel):
        bridge: str = "gmdh"
        imu_rate_hz: float = 200.0

    def broken() -> dict[str, Any]:
        raise RuntimeError("filter not configured")

    with Bus(router, vehicle="q1") as fusion, Bus(router, vehicle="q2") as bad, Bus(router) as ui:
        fusion.declare_config_queryable(lambda: Cfg())
        bad.declare_config_queryable(broken)
        reply = ui.query_config(vehicle="q1")
        assert reply == {
            "schema_version": SCHEMA_VERSION,
            "vehicle": "q1",
            "config": {"bridge": "gmdh", "imu_rate_hz": 200.0},
        }
        jsonschema.validate(reply, SCHEMAS[Topic.CONFIG])
        assert ui.query_config(vehicle="q2", timeout_s=1.0) is None  # error reply
        assert ui.query_config(vehicle="nobody", timeout_s=0.5) is None


def test_liveliness_token_appears_and_disappears(router: str) -> None:
    events: list[tuple[str, bool]] = []
    with Bus(router, vehicle="live") as watcher:
        watcher.subscribe_liveliness(lambda k, alive: events.append((k, alive)))
        assert not watcher.fusion_alive(timeout_s=0.5)
        with Bus(router, vehicle="live") as fusion:
            token = fusion.declare_liveliness()
            assert token.declared
            assert wait_for(lambda: ("hilnav/live/fusion/alive", True) in events)
            assert wait_for(lambda: watcher.fusion_alive(timeout_s=0.5))
            token.undeclare()
            assert wait_for(lambda: events[-1] == ("hilnav/live/fusion/alive", False))
            assert wait_for(lambda: not watcher.fusion_alive(timeout_s=0.5))
            fusion.declare_liveliness()
            assert wait_for(lambda: events[-1][1])
        # the process (session) went away: so did its token
        assert wait_for(lambda: events[-1] == ("hilnav/live/fusion/alive", False))


def test_flood_without_router_drops_oldest_and_counts() -> None:
    dead = f"tcp/127.0.0.1:{free_tcp_port()}"
    cfg = BusConfig(rates_hz=dict.fromkeys(PUBLISHED_TOPICS), queue_size=64, connect_timeout_s=0.2)
    with Bus(dead, vehicle="flood", config=cfg) as bus:
        for i in range(10_000):
            assert bus.publish(Topic.ESTIMATE, {"time_us": i})
        st = bus.stats()
        assert not st.connected and st.connect_attempts >= 1
        assert st.enqueued == 10_000
        assert st.queued == 64
        assert st.dropped_queue_full == 10_000 - 64
        assert st.dropped_by_topic == {"fusion/estimate": 10_000 - 64}
        assert st.published == 0


def test_flood_with_a_stuck_subscriber_never_blocks_the_publisher(router: str) -> None:
    release = threading.Event()
    seen: list[int] = []

    def stuck(_m: Message) -> None:
        seen.append(1)
        release.wait(10.0)  # holds the subscriber's receive thread

    cfg = BusConfig(rates_hz=dict.fromkeys(PUBLISHED_TOPICS), queue_size=256)
    with Bus(router, vehicle="slow", config=cfg) as pub, Bus(router, vehicle="slow") as sub:
        sub.subscribe(Topic.ESTIMATE, stuck)
        assert wait_for(lambda: pub.has_subscribers(Topic.ESTIMATE))
        try:
            bound = 0
            blob = "x" * 2000  # 2 kB messages fill socket buffers quickly
            for i in range(10_000):
                pub.publish(Topic.ESTIMATE, {"time_us": i, "pad": blob})
                if i % 100 == 0:
                    bound = max(bound, pub.stats().queued)

            # the publisher thread keeps draining although nobody reads: zenoh drops (DROP)
            def settled() -> bool:
                st = pub.stats()
                return st.published + st.dropped_queue_full == st.enqueued

            assert wait_for(settled)
        finally:
            release.set()  # before closing: the subscriber's thread must be free to stop
    st = pub.stats()
    assert bound <= 256 and st.queued == 0
    assert st.enqueued == 10_000
    assert st.put_errors == 0
    assert len(seen) >= 1


def test_callback_errors_are_counted_not_fatal(router: str) -> None:
    ok: list[Message] = []

    def boom(_m: Message) -> None:
        raise RuntimeError("bad subscriber")

    with Bus(router, vehicle="cb", config=UNLIMITED) as pub, Bus(router, vehicle="cb") as sub:
        sub.subscribe(Topic.EVENTS, boom)
        sub.subscribe(Topic.EVENTS, ok.append)
        assert wait_for(lambda: pub.has_subscribers(Topic.EVENTS))
        pub.publish_event(1, "note")
        pub.publish_event(2, "note")
        assert wait_for(lambda: len(ok) == 2)
        assert wait_for(lambda: sub.stats().callback_errors == 2)
        assert sub.stats().received == 4


def test_publisher_started_before_router_then_router_restart() -> None:
    port = free_tcp_port()
    endpoint = f"tcp/127.0.0.1:{port}"
    cfg = BusConfig(rates_hz=dict.fromkeys(PUBLISHED_TOPICS), connect_timeout_s=0.3, retry_s=0.05)
    got: list[int] = []
    with Bus(endpoint, vehicle="rc", config=cfg) as pub:
        assert pub.session is None and not pub.stats().connected  # no router yet
        pub.declare_liveliness()  # declared once the session exists
        router = ZenohRouter(port).open()
        try:
            with Bus(endpoint, vehicle="rc") as sub:
                sub.subscribe(
                    Topic.EVENTS, lambda m: got.append(m.payload["time_us"]) if m.payload else None
                )

                def flows(t0: int) -> bool:
                    for i in range(500):  # ~10 s at most
                        pub.publish_event(t0 + i, "tick")
                        if any(t >= t0 for t in got):
                            return True
                        time.sleep(0.02)
                    return False

                assert flows(0)
                assert pub.stats().connected
                assert wait_for(lambda: sub.fusion_alive(timeout_s=0.5))
                router.close()
                assert wait_for(lambda: not pub.stats().connected)
                router.open()  # same port
                assert flows(100_000)
                assert wait_for(lambda: sub.fusion_alive(timeout_s=0.5))  # token re-declared
                assert wait_for(lambda: pub.stats().reconnects >= 1)
        finally:
            router.close()


def test_health_check(router: str) -> None:
    lines: list[str] = []
    with Bus(router, vehicle="hc", config=UNLIMITED) as fusion:
        assert check_bus(router, "hc", alive=True, timeout_s=2.0, report=lines.append) == 1
        assert lines == ["no hilnav/hc/fusion/alive token"]
        fusion.declare_liveliness()
        assert check_bus(router, "hc", alive=True, timeout_s=5.0) == 0
        stop = threading.Event()

        def ticker() -> None:
            i = 0
            while not stop.is_set():
                fusion.publish(Topic.TRUTH, truth_payload(make_truth(i)))
                i += 10_000
                time.sleep(0.02)

        t = threading.Thread(target=ticker)
        t.start()
        try:
            assert check_bus(router, keys=["hilnav/hc/sim/truth"]) == 0
        finally:
            stop.set()
            t.join()
    dead = f"tcp/127.0.0.1:{free_tcp_port()}"
    lines.clear()
    assert check_bus(dead, timeout_s=0.3, report=lines.append) == 1
    assert lines == [f"no router at {dead}"]
    lines.clear()
    assert check_bus("localhost:7447", report=lines.append) == 2
    assert len(lines) == 1 and lines[0].startswith("error: invalid Zenoh endpoint")


def test_health_check_prints_nothing_itself(capsys: pytest.CaptureFixture[str]) -> None:
    dead = f"tcp/127.0.0.1:{free_tcp_port()}"
    assert check_bus(dead, timeout_s=0.3) == 1
    assert check_bus("localhost:7447") == 2
    assert capsys.readouterr() == ("", "")


def test_router_runs_for_a_duration_and_reports_a_busy_port(router: str) -> None:
    port = int(router.rsplit(":", 1)[1])
    with pytest.raises(ValueError, match="cannot start a Zenoh router"):
        ZenohRouter(port).open()
    with pytest.raises(ValueError, match="cannot start a Zenoh router"):
        router_main(listen=router, duration_s=0.1)
    with pytest.raises(ValueError, match="endpoint"):
        router_main(listen="localhost:7447", duration_s=0.1)
    free = f"tcp/127.0.0.1:{free_tcp_port()}"
    assert router_main(listen=free, duration_s=0.2) == 0
    with zenoh_router() as endpoint, Bus(endpoint, vehicle="z") as bus:
        assert endpoint.startswith("tcp/127.0.0.1:") and bus.stats().connected
