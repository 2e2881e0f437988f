"""hil.tlog: .tlog round trips, damaged files, logs written by other tools, and pymavlink's own
mavlogdump reading a file we wrote."""

from __future__ import annotations

import json
import math
import os
import shutil
import struct
import subprocess
import sys
from pathlib import Path

import numpy as np
import pymavlink
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hil.codec import SENSOR_COMPONENT_ID, TRUTH_COMPONENT_ID, Decoder, Encoder, mavlink2
from hil.tlog import (
    TlogReader,
    TlogWriter,
    frame_length,
    iter_decoded,
    iter_messages,
    read_tlog,
)
from sim.samples import BaroSample, GnssFix, ImuSample, MagSample, Truth


def _records() -> list[tuple[int, bytes]]:
    """One second of simulated traffic at 50 Hz: IMU+mag every tick, baro every other, GNSS and
    truth every 10th. Record timestamps are simulated time."""
    enc = Encoder(system_id=2)
    out: list[tuple[int, bytes]] = []
    for k in range(50):
        t = 20_000 * k
        imu = ImuSample(t, 0.02, np.array([0.2, 0.0, -9.8]), np.array([0.0, 0.01 * k, 0.0]))
        mag = MagSample(t, np.array([2e-5, 1e-6, 4.5e-5]))
        baro = BaroSample(t, 95_461.0 - k, 281.65) if k % 2 == 0 else None
        out.append((t, enc.sensors(imu, baro, mag)))
        if k % 10 == 0:
            v = np.array([40.0, 3.0, -1.0])
            out.append((t, enc.gnss(GnssFix(t, 0.83, 0.15, 540.0 + k, v, 1.2, 2.0, 0.1))))
            q = np.array([0.9, 0.1, 0.0, np.sqrt(1 - 0.82)])
            truth = Truth(
                t,
                0.83,
                0.15,
                540.0 + k,
                v,
                q,
                np.zeros(3),
                np.array([0.0, 0.0, -9.8]),
                95_461.0,
                281.65,
                40.1,
                38.0,
            )
            out.append((t, enc.truth(truth)))
    return out


def _write(path: Path, records: list[tuple[int, bytes]]) -> None:
    with TlogWriter(path) as w:
        for t, frame in records:
            w.write(frame, t)


def test_round_trip(tmp_path: Path) -> None:
    records = _records()
    path = tmp_path / "run.tlog"
    _write(path, records)
    assert path.stat().st_size == sum(8 + len(f) for _, f in records)
    with TlogReader(path) as reader:
        assert list(reader) == records
        assert (reader.stats.records, reader.stats.truncated_records) == (len(records), 0)
    # The timestamp is big-endian, as ground stations write it.
    assert path.read_bytes()[:8] == struct.pack(">Q", records[0][0])


def test_decoded_iteration_matches_direct_decoding(tmp_path: Path) -> None:
    records = _records()
    path = tmp_path / "run.tlog"
    _write(path, records)
    direct = Decoder().feed(b"".join(f for _, f in records))
    from_file = list(iter_decoded(path))
    assert [repr(d) for _, d in from_file] == [repr(d) for d in direct]
    assert len(direct) == 50 * 2 + 25 + 5 * 2
    msgs = list(iter_messages(path))
    assert len(msgs) == len(records)
    assert {m.get_type() for _, m in msgs} == {"HIL_SENSOR", "HIL_GPS", "HIL_STATE_QUATERNION"}


@settings(max_examples=40, deadline=None)
@given(cut=st.integers(1, 400))
def test_truncated_file_stops_cleanly_and_counts(
    tmp_path_factory: pytest.TempPathFactory, cut: int
) -> None:
    records = _records()
    data = b"".join(struct.pack(">Q", t) + f for t, f in records)
    path = tmp_path_factory.mktemp("cut") / "cut.tlog"
    path.write_bytes(data[: len(data) - cut])
    # Records that survive the cut intact.
    sizes = np.cumsum([8 + len(f) for _, f in records])
    n_whole = int(np.searchsorted(sizes, len(data) - cut, side="right"))
    reader = TlogReader(path)
    got = list(reader)
    reader.close()
    assert got == records[:n_whole]
    at_boundary = n_whole > 0 and sizes[n_whole - 1] == len(data) - cut
    assert reader.stats.truncated_records == (0 if at_boundary else 1)
    assert reader.stats.skipped_bytes == 0


def test_garbage_inside_a_log_is_skipped_and_counted(tmp_path: Path) -> None:
    records = _records()
    blobs = [struct.pack(">Q", t) + f for t, f in records]
    junk = b"\x00\x01\x02 not a record \xfd\x03"  # contains a frame marker that fails the CRC
    path = tmp_path / "junk.tlog"
    path.write_bytes(b"".join(blobs[:7]) + junk + b"".join(blobs[7:]))
    with TlogReader(path) as reader:
        got = list(reader)
    assert got == records
    assert reader.stats.skipped_bytes == len(junk)


def test_empty_file(tmp_path: Path) -> None:
    path = tmp_path / "empty.tlog"
    path.write_bytes(b"")
    assert list(read_tlog(path)) == []


def test_foreign_log_with_mavlink1_signed_and_unknown_frames(tmp_path: Path) -> None:
    """A log as MAVProxy writes it (``struct.pack('>Q', usec) + msg.get_msgbuf()``) from a mixed
    link: MAVLink 1 heartbeats, signed MAVLink 2 frames, and an id our dialect does not know."""
    autopilot = mavlink2.MAVLink(None, srcSystem=1, srcComponent=1)
    heartbeat = mavlink2.MAVLink_heartbeat_message(1, 3, 0, 0, 4, 3)
    v1 = heartbeat.pack(autopilot, force_mavlink1=True)
    signer = mavlink2.MAVLink(None, srcSystem=1, srcComponent=1)
    signer.signing.secret_key = b"s" * 32
    signer.signing.sign_outgoing = True
    signer.signing.timestamp = 5
    signed = mavlink2.MAVLink_scaled_pressure_message(1200, 1002.5, 0.0, 2100).pack(signer)
    payload = bytes(range(20))
    unknown = (
        bytes([0xFD, len(payload), 0, 0, 0, 1, 1])
        + (61_000).to_bytes(3, "little")
        + payload
        + b"\x12\x34"
    )
    records = [
        (1_700_000_000_000_000, v1),
        (1_700_000_000_010_000, signed),
        (1_700_000_000_020_000, unknown),
        (1_700_000_000_030_000, v1),
    ]
    assert v1[0] == 0xFE and signed[2] & 0x01
    assert [frame_length(f) for _, f in records] == [len(f) for _, f in records]
    path = tmp_path / "mavproxy.tlog"
    path.write_bytes(b"".join(struct.pack(">Q", t) + f for t, f in records))
    assert list(read_tlog(path)) == records
    dec = Decoder()
    decoded = list(iter_decoded(path, dec))
    assert len(decoded) == 1
    baro = decoded[0][1].sample
    assert isinstance(baro, BaroSample) and baro.pressure_pa == pytest.approx(100_250.0)
    assert dec.counters.unknown_msg_id == 1
    assert dec.counters.ignored_msgs == 2  # the heartbeats


def test_writer_rejects_what_is_not_one_frame(tmp_path: Path) -> None:
    frame = _records()[0][1]
    with TlogWriter(tmp_path / "w.tlog") as w:
        with pytest.raises(ValueError, match="exactly one MAVLink frame"):
            w.write(frame + frame, 0)
        with pytest.raises(ValueError, match="exactly one MAVLink frame"):
            w.write(frame[:-1], 0)
        with pytest.raises(ValueError, match="marker"):
            w.write(b"\x00" + frame[1:], 0)
        with pytest.raises(ValueError, match="time_us"):
            w.write(frame, -1)
        w.write(frame, 7)
        assert w.records == 1
    with pytest.raises(ValueError, match="closed"):
        w.write(frame, 8)
    assert list(read_tlog(tmp_path / "w.tlog")) == [(7, frame)]


def _mavlogdump() -> Path:
    """pymavlink's own mavlogdump.py, from the installed package (or the venv's bin)."""
    script = Path(pymavlink.__file__).parent / "tools" / "mavlogdump.py"
    if script.is_file():
        return script
    found = shutil.which("mavlogdump.py", path=str(Path(sys.executable).parent))
    if found is None:
        pytest.fail("pymavlink's mavlogdump.py not found")
    return Path(found)


def test_pymavlink_mavlogdump_reads_our_log(tmp_path: Path) -> None:
    records = _records()
    path = tmp_path / "run.tlog"
    _write(path, records)
    env = {k: v for k, v in os.environ.items() if k not in ("MAVLINK_DIALECT", "MAVLINK20")}
    result = subprocess.run(
        [
            sys.executable,
            str(_mavlogdump()),
            "--format",
            "json",
            "--show-source",
            "--dialect",
            "ardupilotmega",
            str(path),
        ],
        capture_output=True,
        text=True,
        timeout=120,
        env=env,
        check=False,
    )
    assert result.returncode == 0, result.stderr
    rows = [json.loads(line) for line in result.stdout.splitlines() if line.startswith("{")]
    assert len(rows) == len(records)
    for (t, _), row in zip(records, rows, strict=True):
        assert row["meta"]["timestamp"] == pytest.approx(t * 1e-6)
    types = [row["meta"]["type"] for row in rows]
    assert types.count("HIL_SENSOR") == 50
    assert types.count("HIL_GPS") == 5 and types.count("HIL_STATE_QUATERNION") == 5

    first = rows[0]
    assert first["meta"]["srcSystem"] == 2 and first["meta"]["srcComponent"] == SENSOR_COMPONENT_ID
    d = first["data"]
    assert d["fields_updated"] == 0x1FFF & ~(1 << 10)  # everything but diff_pressure
    assert d["abs_pressure"] == pytest.approx(954.61, abs=1e-4)  # hPa on the wire
    assert d["temperature"] == pytest.approx(8.5, abs=1e-5)  # degC
    assert d["xmag"] == pytest.approx(0.2, abs=1e-7)  # gauss
    assert d["zacc"] == pytest.approx(-9.8, abs=1e-6)

    gps = rows[types.index("HIL_GPS")]
    assert gps["data"]["lat"] == round(math.degrees(0.83) * 1e7)
    assert gps["data"]["alt"] == 540_000 and gps["data"]["vn"] == 4000 and gps["data"]["eph"] == 120
    truth = rows[types.index("HIL_STATE_QUATERNION")]
    assert truth["meta"]["srcComponent"] == TRUTH_COMPONENT_ID
    assert truth["data"]["zacc"] == round(-9.8 / 9.80665e-3)  # mG
    assert truth["data"]["true_airspeed"] == 4010
