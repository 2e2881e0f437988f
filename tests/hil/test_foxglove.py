"""Foxglove: the MCAP's well-known channels decode with their official schemas and carry the
simulated time; the live WebSocket server speaks the Foxglove protocol (``foxglove.sdk.v1``, the
successor name of ``foxglove.websocket.v1``) to a real client."""

from __future__ import annotations

import asyncio
import json
import math
import socket
import struct
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import foxglove.messages
import numpy as np
from google.protobuf import descriptor_pb2, descriptor_pool, message_factory
from mcap.reader import make_reader
from websockets.asyncio.client import connect

from hil.bus import Message, Topic, encode, estimate_payload, event_payload, key, truth_payload
from hil.monitor import McapRecorder
from hil.monitor.foxglove import FIX_TOPICS, LOG_TOPIC, TF_TOPIC, sim_time_ns
from scenarios.cli.up import stop_process, wait_gone
from tests.hil.test_monitor import nav

_FOX = {"foxglove.LocationFix", "foxglove.FrameTransform", "foxglove.Log"}


def decoder(name: str, fds: bytes) -> Any:
    """The protobuf message class ``name`` from a schema's FileDescriptorSet."""
    pool = descriptor_pool.DescriptorPool()
    for f in descriptor_pb2.FileDescriptorSet.FromString(fds).file:
        pool.Add(f)
    return message_factory.GetMessageClass(pool.FindMessageTypeByName(name))


def read_mcap(path: Path) -> tuple[dict[str, str], list[tuple[str, str, int, Any]]]:
    """Channel topic -> schema name, and (topic, schema, log_time, decoded) per message."""
    with path.open("rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary is not None
        schemas = {c.topic: summary.schemas[c.schema_id].name if c.schema_id else ""
                   for c in summary.channels.values()}
        out = []
        classes: dict[str, Any] = {}
        for schema, channel, m in reader.iter_messages():
            if channel.message_encoding == "protobuf":
                assert schema is not None
                assert schema.encoding == "protobuf"
                # Foxglove's own definition, as the foxglove-sdk package ships it
                official = getattr(foxglove.messages, schema.name.removeprefix("foxglove."))
                assert bytes(schema.data) == bytes(official.get_schema().data), schema.name
                cls = classes.setdefault(schema.name, decoder(schema.name, schema.data))
                out.append((channel.topic, schema.name, m.log_time, cls.FromString(m.data)))
            else:
                name = "" if schema is None else schema.name
                out.append((channel.topic, name, m.log_time, json.loads(m.data)))
    return schemas, out


def _msg(topic: Topic | str, payload: dict[str, Any]) -> Message:
    t = topic if isinstance(topic, Topic) else None
    k = key("v1", topic) if t is not None else f"hilnav/v1/{topic}"
    return Message(k, "v1", t, payload, encode(payload), 1_700_000_000_000_000_000)


def test_mcap_has_foxglove_channels_decoded_with_the_official_schemas(tmp_path: Path) -> None:
    est, truth = nav(5_000_000, north_m=12.0), nav(5_000_000)
    gnss = {"time_us": 4_900_000, "lat_deg": 47.0, "lon_deg": 8.0, "alt_msl_m": 1001.0,
            "eph_m": 2.0, "epv_m": 3.0, "v_ned_mps": [40.0, 0.0, 0.0]}
    path = tmp_path / "run.mcap"
    with McapRecorder(path) as rec:
        rec.write(_msg(Topic.TRUTH, truth_payload(truth)))
        rec.write(_msg(Topic.ESTIMATE, estimate_payload(est)))
        rec.write(_msg(Topic.GNSS, gnss))
        rec.write(_msg(Topic.EVENTS, event_payload(4_000_000, "gnss_off", "jammer on")))
        # the shadow vehicle's detections: consumed by suffix, whatever the key space says
        rec.write(_msg("fusion/events", {"time_us": 6_000_000, "name": "spoof_suspected",
                                         "level": "warning", "message": "jump 300 m"}))
    schemas, messages = read_mcap(path)
    assert schemas[FIX_TOPICS[Topic.ESTIMATE]] == "foxglove.LocationFix"
    assert schemas[FIX_TOPICS[Topic.TRUTH]] == "foxglove.LocationFix"
    assert schemas[FIX_TOPICS[Topic.GNSS]] == "foxglove.LocationFix"
    assert schemas[TF_TOPIC] == "foxglove.FrameTransform"
    assert schemas[LOG_TOPIC] == "foxglove.Log"
    fox = {(t, s): (lt, d) for t, s, lt, d in messages if s in _FOX and t != TF_TOPIC}
    lt, fix = fox[(FIX_TOPICS[Topic.ESTIMATE], "foxglove.LocationFix")]
    assert lt == sim_time_ns(5_000_000) == 5_000_000_000
    assert fix.timestamp.seconds == 5 and fix.timestamp.nanos == 0
    assert math.isclose(fix.latitude, math.degrees(est.lat_rad), rel_tol=1e-12)
    # P_diag = 1 m^2 on N/E/D -> ENU diagonal, "diagonal known" (2)
    assert list(fix.position_covariance) == [1.0, 0, 0, 0, 1.0, 0, 0, 0, 1.0]
    assert fix.position_covariance_type == 2
    _lt, g = fox[(FIX_TOPICS[Topic.GNSS], "foxglove.LocationFix")]
    assert list(g.position_covariance)[::4] == [4.0, 4.0, 9.0] and g.position_covariance_type == 1
    logs = sorted((lt, d) for t, s, lt, d in messages if s == "foxglove.Log")
    assert [lt for lt, _ in logs] == [4_000_000_000, 6_000_000_000]
    assert logs[0][1].message == "gnss_off: jammer on" and logs[0][1].level == 2  # INFO
    assert logs[1][1].name == "fusion/events" and logs[1][1].level == 3  # WARNING
    assert "spoof_suspected" in logs[1][1].message
    tfs = {d.child_frame_id: d for t, _s, _lt, d in messages if t == TF_TOPIC}
    assert set(tfs) == {"base_link", "truth_base_link"}
    # attitude roll 0, pitch 2 deg, yaw 90 deg (east): the FLU x axis points along ENU +x
    q = tfs["base_link"].rotation
    r = np.array([1 - 2 * (q.y**2 + q.z**2), 2 * (q.x * q.y + q.w * q.z),
                  2 * (q.x * q.z - q.w * q.y)])
    assert np.allclose(r, [math.cos(math.radians(2.0)), 0.0, math.sin(math.radians(2.0))],
                       atol=1e-9)
    # the estimate is 12 m north of the truth (the world origin): ENU y = +12 m
    assert math.isclose(tfs["base_link"].translation.y, 12.0, rel_tol=1e-3)
    # the JSON channels are stamped with simulated time too; wall time is the publish time
    js = {t: lt for t, s, lt, _d in messages if s not in _FOX}
    assert js[key("v1", Topic.ESTIMATE)] == 5_000_000_000


def _free_tcp_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


async def _foxglove_client(url: str, want: int, timeout_s: float) -> tuple[list[dict], list]:
    """Connect (retrying until the server is up), subscribe to the LocationFix channels, return
    the advertised channels and the decoded LocationFix messages, until ``want`` of them are
    estimates (the estimate starts after the filter's alignment, after the truth)."""
    deadline = time.monotonic() + timeout_s
    while True:
        try:
            ws = await connect(url, subprotocols=["foxglove.sdk.v1"], max_size=None)  # type: ignore[list-item]
            break
        except OSError:
            if time.monotonic() > deadline:
                raise
            await asyncio.sleep(0.5)
    channels: dict[int, dict] = {}
    subscribed: dict[int, dict] = {}
    fixes: list = []
    async with ws:
        assert ws.subprotocol == "foxglove.sdk.v1"  # foxglove-sdk 0.30: the v1 protocol renamed
        while (sum(f[0] == FIX_TOPICS[Topic.ESTIMATE] for f in fixes) < want
               and time.monotonic() < deadline):
            try:
                frame = await asyncio.wait_for(ws.recv(), max(0.1, deadline - time.monotonic()))
            except TimeoutError:
                break
            if isinstance(frame, str):
                op = json.loads(frame)
                if op.get("op") == "advertise":
                    new = [c for c in op["channels"] if c["schemaName"] == "foxglove.LocationFix"
                           and c["id"] not in channels]
                    for c in op["channels"]:
                        channels[c["id"]] = c
                    subs = [{"id": 100 + c["id"], "channelId": c["id"]} for c in new]
                    for s, c in zip(subs, new, strict=True):
                        subscribed[s["id"]] = c
                    if subs:
                        await ws.send(json.dumps({"op": "subscribe", "subscriptions": subs}))
                continue
            assert frame[0] == 0x01  # message data
            sub_id, log_time_ns = struct.unpack_from("<IQ", frame, 1)
            c = subscribed[sub_id]
            assert c["encoding"] == "protobuf"
            schema = c["schema"]
            import base64

            cls = decoder("foxglove.LocationFix", base64.b64decode(schema))
            fixes.append((c["topic"], log_time_ns, cls.FromString(frame[13:])))
    return list(channels.values()), fixes


def test_up_serves_foxglove_and_records_sim_time(tmp_path: Path) -> None:
    port = _free_tcp_port()
    out = tmp_path / "up"
    log = tmp_path / "up.log"
    proc = subprocess.Popen(
        [sys.executable, "-m", "scenarios.cli", "up", "--duration", "20", "--speed", "10",
         "--out", str(out), "--foxglove", str(port)],
        stdout=log.open("wb"), stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
        start_new_session=True,
    )
    try:
        channels, fixes = asyncio.run(_foxglove_client(f"ws://127.0.0.1:{port}", 20, 90.0))
        code = proc.wait(timeout=150)
    finally:
        stop_process(proc)
    text = log.read_text()
    assert code == 0, text
    assert f"ws://127.0.0.1:{port}" in text
    pids = [int(p) for p in __import__("re").findall(r"pid (\d+):", text)]
    assert pids and wait_gone(pids)
    advertised = {c["topic"]: c["schemaName"] for c in channels}
    assert advertised.get(FIX_TOPICS[Topic.ESTIMATE]) == "foxglove.LocationFix", advertised
    assert advertised.get(TF_TOPIC) == "foxglove.FrameTransform"
    assert sum(f[0] == FIX_TOPICS[Topic.ESTIMATE] for f in fixes) == 20
    for _topic, log_time_ns, fix in fixes:
        # the racetrack flies near its origin; the message time is the simulated time
        assert -90 <= fix.latitude <= 90 and fix.latitude != 0.0
        assert log_time_ns == fix.timestamp.seconds * 1_000_000_000 + fix.timestamp.nanos
        assert log_time_ns < 60 * 1_000_000_000  # simulated seconds since the epoch, not wall
    schemas, messages = read_mcap(out / "live.mcap")
    assert {schemas[t] for t in (FIX_TOPICS[Topic.ESTIMATE], FIX_TOPICS[Topic.TRUTH],
                                 FIX_TOPICS[Topic.GNSS], TF_TOPIC)} == {
        "foxglove.LocationFix", "foxglove.FrameTransform"}
    n = 0
    for topic, schema, log_time, decoded in messages:
        if schema == "foxglove.LocationFix":
            assert log_time == decoded.timestamp.seconds * 10**9 + decoded.timestamp.nanos
            n += 1
        elif schema not in _FOX and "time_us" in decoded:
            assert log_time == sim_time_ns(decoded["time_us"]), topic
    assert n > 100


def test_shipped_layout_names_channels_and_fields_that_exist() -> None:
    from hil.bus import SCHEMAS

    layout = json.loads(
        (Path(__file__).parents[2] / "docs/foxglove/hilnav_layout.json").read_text()
    )
    panels = set(layout["configById"])
    assert {p.split("!")[0] for p in panels} >= {"map", "Plot", "RosOut", "3D", "StateTransitions"}
    text = json.dumps(layout["layout"])
    assert all(p in text for p in panels)  # every configured panel is placed
    fox_topics = {*FIX_TOPICS.values(), LOG_TOPIC, TF_TOPIC}
    conf = layout["configById"]
    assert set(conf["map!hilnav"]["topicColors"]) <= fox_topics
    assert conf["RosOut!hilnav-log"]["topicToRender"] in fox_topics
    for pid, c in conf.items():
        for path in c.get("paths", []):
            # '"hilnav/sim1/<topic>".<field>[i]': the topic is ours and its schema has the field
            quoted, field = path["value"][1:].split('".', 1)
            topic = Topic(quoted.split("/", 2)[2])
            assert field.split("[")[0] in SCHEMAS[topic]["properties"], (pid, path)
