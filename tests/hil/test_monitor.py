"""Monitor: MCAP recording readable by the mcap reader, dashboard state, and the live loop over
a real in-process Zenoh router."""

from __future__ import annotations

import json
import math
import threading
import time
from pathlib import Path
from types import SimpleNamespace

import jsonschema
import numpy as np
import pytest
from mcap.reader import make_reader
from rich.console import Console

from fusion.rotations import euler_to_quat
from hil.bus import (
    PUBLISHED_TOPICS,
    SCHEMAS,
    Bus,
    BusConfig,
    Message,
    Topic,
    encode,
    error_payload,
    estimate_payload,
    event_payload,
    key,
    status_payload,
    truth_payload,
)
from hil.monitor import McapRecorder, MonitorState, monitor_main

LAT0, LON0 = math.radians(47.0), math.radians(8.0)


def nav(time_us: int, *, mode: str = "gnss", north_m: float = 0.0, since: float = 0.1):
    """A NavEstimate-shaped object (and, with north_m = 0, a Truth-shaped one)."""
    return SimpleNamespace(
        time_us=time_us,
        lat_rad=LAT0 + north_m / 6_371_000.0,
        lon_rad=LON0,
        alt_msl_m=1000.0,
        v_ned_mps=np.array([40.0, 0.0, 0.0]),
        q_nb=euler_to_quat(np.radians([0.0, 2.0, 90.0])),
        P_diag=np.full(16, 1.0),
        mode=mode,
        time_since_gnss_s=since,
        test_ratios={"gnss_pos": 0.4},
        health={"gnss_fused": 3},
    )


def msg(vehicle: str, topic: Topic, payload: dict, t_ns: int = 1_000_000_000) -> Message:
    return Message(key(vehicle, topic), vehicle, topic, payload, encode(payload), t_ns)


def one_of_each(vehicle: str) -> list[Message]:
    est, truth = nav(5_000_000, mode="bridging", north_m=12.0, since=12.0), nav(5_000_000)
    return [
        msg(vehicle, Topic.TRUTH, truth_payload(truth)),
        msg(vehicle, Topic.ESTIMATE, estimate_payload(est)),
        msg(
            vehicle,
            Topic.STATUS,
            status_payload(est, links={"sim": {"received": 9, "accepted": 7}}),
        ),
        msg(vehicle, Topic.ERROR, error_payload(est, truth)),
        msg(vehicle, Topic.EVENTS, event_payload(4_000_000, "gnss_off", "jammer on")),
    ]


def test_mcap_recording_is_readable_with_schemas_per_channel(tmp_path: Path) -> None:
    path = tmp_path / "run.mcap"
    messages = one_of_each("v1")
    with McapRecorder(path, metadata={"vehicle": "v1"}) as rec:
        for i in range(3):
            for m in messages:
                rec.write(Message(m.key, m.vehicle, m.topic, m.payload, m.raw, m.received_ns + i))
        rec.write(Message("hilnav/v1/fusion/estimate", "v1", Topic.ESTIMATE, None, b"\xff", 5))
    # 5 JSON samples + LocationFix and FrameTransform of truth and estimate + Log of the event
    assert rec.messages == 3 * 10 and rec.skipped == 1
    rec.write(messages[0])  # after close: ignored, not an error

    with path.open("rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary is not None
        channels = {c.topic: c for c in summary.channels.values() if c.topic.startswith("hilnav/")}
        assert set(channels) == {m.key for m in messages}
        for m in messages:
            ch = channels[m.key]
            assert ch.message_encoding == "json"
            schema = summary.schemas[ch.schema_id]
            assert m.topic is not None
            assert schema.encoding == "jsonschema"
            assert schema.name == SCHEMAS[m.topic]["title"]
            assert json.loads(schema.data) == SCHEMAS[m.topic]
        decoded = [(c.topic, json.loads(x.data)) for _s, c, x in reader.iter_messages()
                   if c.message_encoding == "json"]
        metadata = {r.name: r.metadata for r in reader.iter_metadata()}
    assert len(decoded) == 15
    by_key = {m.key: m.payload for m in messages}
    for topic_key, payload in decoded:
        assert payload == by_key[topic_key]
    assert metadata["hilnav"]["vehicle"] == "v1"


def test_recorder_refuses_a_missing_folder(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="does not exist"):
        McapRecorder(tmp_path / "nope" / "x.mcap")


def test_dashboard_state_shows_mode_errors_outage_and_links() -> None:
    clock = [100.0]
    state = MonitorState("v1", clock=lambda: clock[0])
    for m in one_of_each("v1"):
        state.ingest(m)
    state.ingest(msg("other", Topic.ESTIMATE, estimate_payload(nav(1))))  # not our vehicle
    state.set_alive("hilnav/v1/fusion/alive", True)
    line = state.summary_line()
    assert "mode=bridging" in line
    assert "OUTAGE 12.0 s" in line
    assert "err h=12.0" in line  # 12 m north of truth
    assert "lat=47.000108" in line
    assert "fusion alive=yes" in line
    assert line.endswith("sim lost=0 drop=2")
    assert state.unknown == 1
    assert state.rate_hz(Topic.ESTIMATE) == pytest.approx(0.5)  # 1 message in the 2 s window
    clock[0] += 5.0
    assert state.rate_hz(Topic.ESTIMATE) == 0.0
    assert state.age_s(Topic.ESTIMATE) == pytest.approx(5.0)

    console = Console(record=True, width=140, color_system=None)
    console.print(state.render())
    text = console.export_text()
    for needle in ("bridging", "GNSS outage", "12.0 s", "horizontal", "12.00 m", "fusion/estimate",
                   "mavlink sim", "drop 2", "gnss_off"):  # fmt: skip
        assert needle in text, needle


def test_monitor_rejects_bad_input(tmp_path: Path) -> None:
    common = {"connect": "tcp/127.0.0.1:1", "headless": True}
    with pytest.raises(ValueError, match="duration"):
        monitor_main(vehicle="v", record=None, duration_s=0.0, **common)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="mcap"):
        monitor_main(vehicle="v", record=tmp_path / "x.txt", duration_s=1.0, **common)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="vehicle"):
        monitor_main(vehicle="a/b", record=None, duration_s=1.0, **common)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="endpoint"):
        monitor_main(connect="nowhere", vehicle="v", record=None, duration_s=1.0, headless=True)


def test_monitor_main_headless_records_what_the_fusion_publishes(
    router: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "live.mcap"
    stop = threading.Event()
    cfg = BusConfig(rates_hz=dict.fromkeys(PUBLISHED_TOPICS))

    def fusion() -> None:
        with Bus(router, vehicle="m1", config=cfg) as bus:
            bus.declare_liveliness()
            i = 0
            while not stop.is_set():
                t = i * 20_000
                est, truth = nav(t, north_m=3.0), nav(t)
                bus.publish_truth(truth)
                bus.publish_estimate(est)
                bus.publish_error(est, truth)
                if i % 10 == 0:
                    bus.publish_status(est)
                i += 1
                time.sleep(0.02)

    thread = threading.Thread(target=fusion)
    thread.start()
    try:
        rc = monitor_main(connect=router, vehicle="m1", record=path, duration_s=1.5, headless=True)
    finally:
        stop.set()
        thread.join()
    assert rc == 0
    out, err = capsys.readouterr()
    lines = [ln for ln in out.splitlines() if " m1 " in ln]
    assert len(lines) >= 1
    assert "mode=gnss" in lines[-1] and "router=up" in lines[-1]
    assert "err h=3.00" in lines[-1]
    assert "recorded" in err

    with path.open("rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary is not None
        topics = {c.topic for c in summary.channels.values() if c.message_encoding == "json"}
        assert topics == {
            key("m1", t) for t in (Topic.TRUTH, Topic.ESTIMATE, Topic.ERROR, Topic.STATUS)
        }
        validators = {t: jsonschema.Draft202012Validator(SCHEMAS[t]) for t in Topic if t in SCHEMAS}
        n = 0
        for _schema, channel, message in reader.iter_messages():
            if channel.message_encoding != "json":
                continue  # the Foxglove channels: tests/hil/test_foxglove.py
            _vehicle, topic = channel.topic.split("/", 1)[1].split("/", 1)
            validators[Topic(topic)].validate(json.loads(message.data))
            n += 1
    assert n >= 10
