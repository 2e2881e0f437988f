"""hil.signing: MAVLink 2 signatures interoperate with pymavlink, rejections never touch stream
state (the pymavlink 2.4.50 forged-future-timestamp flaw), keys load from files / environment."""

from __future__ import annotations

import base64
import hashlib
import subprocess
import sys
from importlib.metadata import version
from pathlib import Path
from typing import Any

import pytest

from hil.codec import mavlink2
from hil.codec.wire import check_frame
from hil.signing import (
    MAVLINK_EPOCH_UNIX_S,
    TICKS_PER_S,
    Signer,
    Verdict,
    key_from_passphrase,
    load_key,
    mavlink_timestamp,
    parse_key,
    reframe,
)

KEY = bytes(range(32))
OTHER_KEY = bytes(range(1, 33))
NOW_UNIX_S = 1_750_000_000.0  # a fixed "now" (2025) for every signer in this file


class Wall:
    """Injectable wall clock."""

    def __init__(self, t: float = NOW_UNIX_S) -> None:
        self.t = t

    def __call__(self) -> float:
        return self.t


def attitude_frame(i: int, system_id: int = 1, component_id: int = 1) -> bytes:
    mav = mavlink2.MAVLink(None, srcSystem=system_id, srcComponent=component_id)
    mav.seq = i & 0xFF
    msg = mavlink2.MAVLink_attitude_message(i, 0.1 * i, 0.2, 0.3, 0.0, 0.0, 0.0)
    return bytes(msg.pack(mav))


def timestamp_of(frame: bytes) -> int:
    return int.from_bytes(frame[-12:-6], "little")


def with_timestamp(frame: bytes, ticks: int) -> bytes:
    """A copy with another signature timestamp and the old signature (i.e. forged)."""
    return frame[:-12] + ticks.to_bytes(6, "little") + frame[-6:]


def pymavlink_receiver(key: bytes) -> Any:
    mav = mavlink2.MAVLink(None, srcSystem=255, srcComponent=190)
    mav.robust_parsing = True
    mav.signing.secret_key = key
    mav.signing.timestamp = mavlink_timestamp(NOW_UNIX_S)  # as mavutil.setup_signing does
    return mav


def pymavlink_accepts(mav: Any, frame: bytes) -> bool:
    msgs = mav.parse_buffer(frame) or []
    return any(m.get_msgId() == mavlink2.MAVLINK_MSG_ID_ATTITUDE for m in msgs)


# --- signing and verification --------------------------------------------------------------
def test_signed_frame_verifies_and_decodes() -> None:
    tx, rx = Signer(KEY, link_id=3, wall_clock=Wall()), Signer(KEY, wall_clock=Wall())
    signed = tx.sign(attitude_frame(7))
    assert check_frame(signed) == (len(signed) - 10 - 2 - 13, True)
    assert signed[-13] == 3
    assert rx.verify(signed) is Verdict.OK
    assert rx.streams == {(3, 1, 1): timestamp_of(signed)}
    msg = mavlink2.MAVLink(None).decode(bytearray(signed))
    assert msg.get_type() == "ATTITUDE" and msg.time_boot_ms == 7


def test_interoperates_with_pymavlink_both_ways() -> None:
    # ours -> pymavlink
    rx = pymavlink_receiver(KEY)
    tx = Signer(KEY, wall_clock=Wall())
    assert all(pymavlink_accepts(rx, tx.sign(attitude_frame(i))) for i in range(3))
    assert rx.signing.goodsig_count == 3
    # pymavlink -> ours
    mav = mavlink2.MAVLink(None, srcSystem=9, srcComponent=1)
    mav.signing.secret_key = KEY
    mav.signing.sign_outgoing = True
    mav.signing.link_id = 4
    mav.signing.timestamp = mavlink_timestamp(NOW_UNIX_S)
    ours = Signer(KEY, wall_clock=Wall())
    for i in range(3):
        frame = bytes(mavlink2.MAVLink_attitude_message(i, 0, 0, 0, 0, 0, 0).pack(mav))
        assert ours.verify(frame) is Verdict.OK
    assert set(ours.streams) == {(4, 9, 1)}


def test_outgoing_timestamps_increase_and_follow_the_wall_clock() -> None:
    wall = Wall()
    tx = Signer(KEY, wall_clock=wall)
    stamps = [timestamp_of(tx.sign(attitude_frame(i))) for i in range(5)]  # frozen clock
    assert stamps == list(range(stamps[0], stamps[0] + 5))
    assert stamps[0] == (NOW_UNIX_S - MAVLINK_EPOCH_UNIX_S) * TICKS_PER_S
    wall.t += 10.0
    assert timestamp_of(tx.sign(attitude_frame(9))) == stamps[0] + 10 * TICKS_PER_S


@pytest.mark.parametrize(
    ("make", "verdict"),
    [
        (lambda f: f, Verdict.UNSIGNED),
        (lambda f: Signer(OTHER_KEY, wall_clock=Wall()).sign(f), Verdict.BAD_SIGNATURE),
        # valid signature, far-future timestamp: a key holder with a wrong clock
        (
            lambda f: Signer(KEY, wall_clock=Wall(NOW_UNIX_S + 3600.0)).sign(f),
            Verdict.FUTURE,
        ),
        # valid signature on a new stream, timestamp 2 minutes old: captured frames
        (lambda f: Signer(KEY, wall_clock=Wall(NOW_UNIX_S - 120.0)).sign(f), Verdict.STALE_STREAM),
    ],
    ids=["unsigned", "wrong-key", "signed-future", "stale-new-stream"],
)
def test_rejections_leave_stream_state_untouched(make: Any, verdict: Verdict) -> None:
    rx = Signer(KEY, wall_clock=Wall())
    assert rx.verify(make(attitude_frame(0))) is verdict
    assert rx.streams == {}
    assert rx.verify(Signer(KEY, wall_clock=Wall()).sign(attitude_frame(1))) is Verdict.OK


def test_replayed_and_older_frames_are_rejected() -> None:
    tx, rx = Signer(KEY, wall_clock=Wall()), Signer(KEY, wall_clock=Wall())
    first, second = tx.sign(attitude_frame(0)), tx.sign(attitude_frame(1))
    assert rx.verify(second) is Verdict.OK
    assert rx.verify(second) is Verdict.REPLAY  # the same frame again
    assert rx.verify(first) is Verdict.REPLAY  # an older one of the same stream
    assert rx.streams == {(0, 1, 1): timestamp_of(second)}
    # another stream (component) is independent
    assert rx.verify(tx.sign(attitude_frame(2, component_id=2))) is Verdict.OK


def test_tampered_payload_is_rejected() -> None:
    signed = Signer(KEY, wall_clock=Wall()).sign(attitude_frame(5))
    tampered = bytearray(signed)
    tampered[12] ^= 0x01
    assert Signer(KEY, wall_clock=Wall()).verify(bytes(tampered)) is Verdict.BAD_SIGNATURE


def test_forged_future_frame_never_blocks_the_legitimate_stream() -> None:
    """GIVEN a legitimate signed stream, WHEN an attacker injects a copy of one of its frames
    with the timestamp moved ~1 year ahead (signature not recomputable without the key),
    THEN it is rejected as badly signed and every later legitimate frame is still accepted."""
    tx, rx = Signer(KEY, wall_clock=Wall()), Signer(KEY, wall_clock=Wall())
    year = 365 * 24 * 3600 * TICKS_PER_S
    legit = [tx.sign(attitude_frame(i)) for i in range(6)]
    assert rx.verify(legit[0]) is Verdict.OK
    forged = with_timestamp(legit[0], timestamp_of(legit[0]) + year)
    assert rx.verify(forged) is Verdict.BAD_SIGNATURE
    assert [rx.verify(f) for f in legit[1:]] == [Verdict.OK] * 5
    # also as the very first frame of a stream
    rx2 = Signer(KEY, wall_clock=Wall())
    assert rx2.verify(with_timestamp(legit[1], timestamp_of(legit[1]) + year)) is (
        Verdict.BAD_SIGNATURE
    )
    assert [rx2.verify(f) for f in legit[1:]] == [Verdict.OK] * 5


@pytest.mark.skipif(
    tuple(int(p) for p in version("pymavlink").split(".")[:3]) > (2, 4, 50),
    reason="flaw documented for pymavlink <= 2.4.50; re-check newer releases by hand",
)
def test_pymavlink_itself_is_blocked_by_a_forged_future_frame() -> None:
    """Why hilnav verifies signatures itself: pymavlink 2.4.50 stores the stream timestamp
    before checking the signature, so the same forged frame blocks its stream."""
    tx = Signer(KEY, wall_clock=Wall())
    legit = [tx.sign(attitude_frame(i)) for i in range(4)]
    rx = pymavlink_receiver(KEY)
    assert pymavlink_accepts(rx, legit[0])
    forged = with_timestamp(legit[0], timestamp_of(legit[0]) + 365 * 24 * 3600 * TICKS_PER_S)
    assert not pymavlink_accepts(rx, forged)
    assert [pymavlink_accepts(rx, f) for f in legit[1:]] == [False, False, False]
    ours = Signer(KEY, wall_clock=Wall())
    assert [ours.verify(f) for f in (legit[0], forged, *legit[1:])] == [
        Verdict.OK,
        Verdict.BAD_SIGNATURE,
        Verdict.OK,
        Verdict.OK,
        Verdict.OK,
    ]


def test_future_check_can_be_disabled() -> None:
    ahead = Signer(KEY, wall_clock=Wall(NOW_UNIX_S + 3600.0)).sign(attitude_frame(0))
    assert Signer(KEY, wall_clock=Wall(), max_future_s=None).verify(ahead) is Verdict.OK


def test_accepted_timestamps_advance_our_signing_clock() -> None:
    # The specification: the local timestamp follows the newest accepted one.
    rx = Signer(KEY, wall_clock=Wall())
    ahead = Signer(KEY, wall_clock=Wall(NOW_UNIX_S + 30.0)).sign(attitude_frame(0))
    assert rx.verify(ahead) is Verdict.OK
    assert timestamp_of(rx.sign(attitude_frame(1, system_id=2))) == timestamp_of(ahead)


def test_reframe_renumbers_and_unsigns() -> None:
    signed = Signer(KEY, wall_clock=Wall()).sign(attitude_frame(3))
    plain = reframe(signed, seq=200)
    assert check_frame(plain)[1] is False and plain[4] == 200
    msg = mavlink2.MAVLink(None).decode(bytearray(plain))  # CRC checked by pymavlink
    assert msg.get_seq() == 200 and msg.time_boot_ms == 3
    unchanged = attitude_frame(4)
    assert reframe(unchanged, seq=4) == unchanged


def test_bad_frames_and_arguments_raise() -> None:
    frame = attitude_frame(0)
    with pytest.raises(ValueError, match="header says"):
        Signer(KEY).sign(frame[:-1])
    with pytest.raises(ValueError, match="MAVLink 2"):
        Signer(KEY).verify(b"\xfe" + frame[1:])
    unknown = bytearray(frame)
    unknown[7:10] = (0xEF, 0xBE, 0xAD)
    with pytest.raises(ValueError, match="not in hilnav's dialect"):
        Signer(KEY).sign(bytes(unknown))
    with pytest.raises(ValueError, match="32 bytes"):
        Signer(KEY[:31])
    with pytest.raises(ValueError, match="link_id"):
        Signer(KEY, link_id=256)
    assert "hidden" in repr(Signer(KEY)) and KEY.hex() not in repr(Signer(KEY))


# --- keys ----------------------------------------------------------------------------------
def test_load_key_from_files(tmp_path: Path) -> None:
    raw = tmp_path / "raw.key"
    raw.write_bytes(KEY)
    assert load_key(raw, environ={}) == KEY
    hexfile = tmp_path / "hex.key"
    hexfile.write_text(KEY.hex().upper() + "\n")
    assert load_key(hexfile, environ={}) == KEY
    b64 = tmp_path / "b64.key"
    b64.write_text(base64.b64encode(KEY).decode() + "\n")
    # the file wins over the environment
    assert load_key(b64, environ={"HILNAV_MAVLINK_KEY": OTHER_KEY.hex()}) == KEY


def test_load_key_from_environment() -> None:
    assert load_key(environ={"HILNAV_MAVLINK_KEY": KEY.hex()}) == KEY
    assert load_key(environ={"HILNAV_MAVLINK_KEY": base64.b64encode(KEY).decode()}) == KEY
    assert load_key(env="MY_KEY", environ={"MY_KEY": f"  {KEY.hex()}\n"}) == KEY
    assert load_key(environ={}) is None
    assert load_key(environ={"HILNAV_MAVLINK_KEY": "  "}) is None
    assert load_key(env=None, environ={"HILNAV_MAVLINK_KEY": KEY.hex()}) is None


def test_bad_keys_give_clear_errors_without_echoing_the_secret(tmp_path: Path) -> None:
    secretish = "ab" * 31  # 62 hex digits: one byte short
    with pytest.raises(ValueError, match="environment variable HILNAV_MAVLINK_KEY") as err:
        load_key(environ={"HILNAV_MAVLINK_KEY": secretish})
    assert secretish not in str(err.value)
    short = tmp_path / "short.key"
    short.write_bytes(b"\x00\xff" * 10)
    with pytest.raises(ValueError, match="exactly 32 bytes"):
        load_key(short, environ={})
    with pytest.raises(ValueError, match="cannot read"):
        load_key(tmp_path / "missing.key", environ={})
    with pytest.raises(ValueError, match="64 hex digits or as base64"):
        parse_key(base64.b64encode(KEY[:16]).decode(), "test")


def test_passphrase_key_matches_mavproxy() -> None:
    assert key_from_passphrase("hilnav") == hashlib.sha256(b"hilnav").digest()
    with pytest.raises(ValueError):
        key_from_passphrase("")


def test_timestamp_epoch() -> None:
    assert mavlink_timestamp(MAVLINK_EPOCH_UNIX_S) == 0
    assert mavlink_timestamp(MAVLINK_EPOCH_UNIX_S + 1.0) == TICKS_PER_S
    assert mavlink_timestamp(0.0) == 0  # before 2015: clamped, never negative


@pytest.mark.parametrize("first", ["hil.signing", "hil.link", "hil.codec"])
def test_each_module_imports_on_its_own(first: str) -> None:
    """No import cycle between hil.codec and hil.signing: a process that loads either first
    starts (hilnav monitor loading the key once crashed on ``import hil.signing``)."""
    done = subprocess.run([sys.executable, "-c", f"import {first}"], capture_output=True,
                          text=True, timeout=120, cwd=Path(__file__).resolve().parents[2])
    assert done.returncode == 0, done.stderr
