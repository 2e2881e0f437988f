"""MAVLink 2 message signing: keys, signing outgoing frames, verifying incoming ones.

Pure bytes in, bytes out (no sockets); the wall clock is injected. Used by :mod:`hil.link`.

Signature (MAVLink 2 signing specification)
    A signed frame has bit 0 of ``incompat_flags`` set and 13 bytes appended after the CRC:
    ``link_id`` (1 byte), ``timestamp`` (6 bytes, little endian, units of 10 µs since
    2015-01-01T00:00:00Z) and ``signature`` = the first 6 bytes of
    ``SHA-256(secret_key + header + payload + CRC + link_id + timestamp)``. The CRC covers the
    header with the signed flag, so signing an unsigned frame recomputes it.

Why not pymavlink's verification
    pymavlink 2.4.50's ``MAVLink.check_signature`` stores a stream's timestamp *before* it
    compares the signature. One forged frame (any content, wrong signature) carrying a
    far-future timestamp therefore moves the stream ``(link_id, system, component)`` into the
    future, and every later legitimate frame of that stream is rejected as a replay: a
    single unauthenticated packet blocks the link until the attacker's timestamp is reached.
    :meth:`Signer.verify` checks the signature first and touches stream state only for frames
    whose signature is valid. Two more properties of pymavlink 2.4.50's check, from its
    source: frames of message ids unknown to the dialect are returned (as ``MAVLink_unknown``)
    before any CRC or signature check; and a bare ``MAVLink`` object's signing timestamp starts
    at 0 (only ``mavutil``'s ``setup_signing`` sets it), so its "new stream at most one minute
    old" rule accepts captured frames of any age on a new stream.

Timestamp policy of :meth:`Signer.verify` (checked in this order, after the signature)
    1. future: a timestamp more than ``max_future_s`` (default 60 s) ahead of the local wall
       clock is rejected (:attr:`Verdict.FUTURE`) even when correctly signed: a key holder
       whose clock is far ahead would otherwise push the stream (and our own signing
       timestamp) into the future. ``max_future_s=None`` disables the check, for peers whose
       clocks cannot be trusted to within a minute (a flight controller without GNSS time).
    2. replay: within a known stream the timestamp must increase strictly
       (:attr:`Verdict.REPLAY` otherwise).
    3. new stream: accepted only if not more than ``new_stream_window_s`` (60 s, the
       specification's value) behind the local signing timestamp
       (:attr:`Verdict.STALE_STREAM`): captured old frames cannot open a stream.
    The local signing timestamp is ``max(wall clock, last timestamp sent + 1, newest accepted
    timestamp)`` as the specification asks; outgoing frames use it and increase it by one.

Keys
    32 bytes. :func:`load_key` reads them from a file (32 raw bytes, or 64 hex digits / base64
    text) or from an environment variable (hex or base64), never from the command line where
    ``ps`` would show them. :func:`key_from_passphrase` gives the key MAVProxy's
    ``signing setup PASSPHRASE`` and QGroundControl derive (SHA-256 of the passphrase). A key
    is never printed: :class:`Signer`'s ``repr`` hides it and no error message quotes it.
"""

from __future__ import annotations

import base64
import binascii
import hashlib
import hmac
import math
import os
import string
import struct
import time
from collections.abc import Callable, Mapping
from enum import Enum
from pathlib import Path
from typing import Final

from hil.codec.wire import (
    HEADER_LEN,
    IFLAG_SIGNED,
    SIGNATURE_BLOCK_LEN,
    check_frame,
    crc_extra,
    frame_crc,
    frame_msg_id,
)

__all__ = [
    "DEFAULT_KEY_ENV",
    "KEY_LEN",
    "MAVLINK_EPOCH_UNIX_S",
    "TICKS_PER_S",
    "TIMESTAMP_MAX",
    "Signer",
    "Verdict",
    "key_from_passphrase",
    "load_key",
    "mavlink_timestamp",
    "parse_key",
    "reframe",
]

KEY_LEN: Final = 32
MAVLINK_EPOCH_UNIX_S: Final = 1_420_070_400
"""2015-01-01T00:00:00Z as a Unix time."""
TICKS_PER_S: Final = 100_000
"""Signing timestamps count 10 µs ticks."""
TIMESTAMP_MAX: Final = (1 << 48) - 1
DEFAULT_KEY_ENV: Final = "HILNAV_MAVLINK_KEY"

_SEQ_OFFSET: Final = 4
def mavlink_timestamp(unix_s: float) -> int:
    """Signing timestamp (10 µs ticks since 2015-01-01) of a Unix time in seconds."""
    ticks = math.floor((unix_s - MAVLINK_EPOCH_UNIX_S) * TICKS_PER_S)
    return min(max(ticks, 0), TIMESTAMP_MAX)


# --- keys -----------------------------------------------------------------------------------
_HEX_DIGITS: Final = frozenset(string.hexdigits)


def parse_key(text: str, source: str) -> bytes:
    """Decode a 32-byte key written as 64 hex digits or as base64.

    Parameters
    ----------
    text : str
        The encoded key; surrounding whitespace is ignored.
    source : str
        Where it came from, for the error message (the key itself is never quoted).

    Returns
    -------
    bytes
        The 32-byte key.

    Raises
    ------
    ValueError
        Neither 64 hex digits nor base64 of exactly 32 bytes.
    """
    s = text.strip()
    if len(s) == 2 * KEY_LEN and set(s) <= _HEX_DIGITS:
        return bytes.fromhex(s)
    try:
        key = base64.b64decode(s, validate=True)
    except (binascii.Error, ValueError):
        key = b""
    if len(key) == KEY_LEN:
        return key
    raise ValueError(
        f"{source}: a MAVLink signing key must be {KEY_LEN} bytes written as "
        f"{2 * KEY_LEN} hex digits or as base64 (got {len(s)} characters that are neither)"
    )


def load_key(
    file: Path | None = None,
    env: str | None = DEFAULT_KEY_ENV,
    *,
    environ: Mapping[str, str] | None = None,
) -> bytes | None:
    """Load the MAVLink signing key from a file or an environment variable.

    Parameters
    ----------
    file : Path or None
        Key file: exactly 32 bytes are taken as the raw key; anything else must be text with
        64 hex digits or base64 (surrounding whitespace ignored). Takes precedence over
        ``env``.
    env : str or None
        Name of an environment variable holding the key as hex or base64. An unset or blank
        variable means "no key". None: do not look at the environment.
    environ : Mapping or None
        The environment to read (default ``os.environ``; for tests).

    Returns
    -------
    bytes or None
        The 32-byte key, or None when neither source gives one (signing off).

    Raises
    ------
    ValueError
        The file cannot be read or holds no valid key, or the variable holds no valid key.
    """
    if file is not None:
        path = Path(file)
        try:
            data = path.read_bytes()
        except OSError as exc:
            raise ValueError(f"key file {path}: cannot read it ({exc.strerror})") from None
        if len(data) == KEY_LEN:
            return data
        try:
            text = data.decode("ascii")
        except UnicodeDecodeError:
            raise ValueError(
                f"key file {path}: {len(data)} bytes of binary data; a raw key file must be "
                f"exactly {KEY_LEN} bytes"
            ) from None
        return parse_key(text, f"key file {path}")
    if env is None:
        return None
    value = (os.environ if environ is None else environ).get(env, "")
    if not value.strip():
        return None
    return parse_key(value, f"environment variable {env}")


def key_from_passphrase(passphrase: str) -> bytes:
    """The 32-byte key MAVProxy (``signing setup``) and QGroundControl derive: SHA-256."""
    if not passphrase:
        raise ValueError("passphrase must not be empty")
    return hashlib.sha256(passphrase.encode("utf-8")).digest()


# --- signing and verification ---------------------------------------------------------------
class Verdict(Enum):
    """Outcome of :meth:`Signer.verify` (values are the link's drop-counter names)."""

    OK = "ok"
    UNSIGNED = "unsigned"
    BAD_SIGNATURE = "bad_signature"
    REPLAY = "replayed"
    STALE_STREAM = "stale_stream"
    FUTURE = "future_timestamp"


StreamKey = tuple[int, int, int]
"""(link_id, system_id, component_id): one signing stream."""

_TIMESTAMP_STRUCT: Final = struct.Struct("<Q")


def reframe(frame: bytes | bytearray, *, seq: int | None = None) -> bytes:
    """An unsigned copy of a MAVLink 2 frame, optionally with a new sequence number.

    The CRC is recomputed only when something changed.

    Raises
    ------
    ValueError
        Malformed frame, or a message id unknown to the dialect (its CRC cannot be made).
    """
    payload_len, signed = check_frame(frame)
    if not signed and (seq is None or frame[_SEQ_OFFSET] == seq):
        return bytes(frame)
    body = bytearray(frame[: HEADER_LEN + payload_len])
    body[2] &= ~IFLAG_SIGNED & 0xFF
    if seq is not None:
        body[_SEQ_OFFSET] = seq & 0xFF
    extra = crc_extra(frame_msg_id(frame))
    if extra is None:
        raise ValueError(f"message id {frame_msg_id(frame)} is not in hilnav's dialect")
    return bytes(body) + frame_crc(body, payload_len, extra).to_bytes(2, "little")


class Signer:
    """Signs outgoing MAVLink 2 frames and verifies incoming ones with one 32-byte key.

    Stateful: it keeps the newest accepted timestamp of every stream and the local signing
    timestamp. One :class:`Signer` per link (the ``link_id`` is part of every stream key).

    Parameters
    ----------
    key : bytes
        32-byte secret key.
    link_id : int
        Link id written into outgoing signatures, 0..255.
    wall_clock : callable
        Unix time in seconds (default ``time.time``); signing timestamps derive from it.
    max_future_s : float or None
        Reject signed timestamps more than this far ahead of the wall clock, s (default 60;
        None disables).
    new_stream_window_s : float
        A new stream may start at most this far behind the local signing timestamp, s
        (default 60, the specification's value).

    Attributes
    ----------
    link_id : int
    """

    def __init__(
        self,
        key: bytes,
        *,
        link_id: int = 0,
        wall_clock: Callable[[], float] = time.time,
        max_future_s: float | None = 60.0,
        new_stream_window_s: float = 60.0,
    ) -> None:
        if not isinstance(key, bytes | bytearray) or len(key) != KEY_LEN:
            raise ValueError(f"key must be {KEY_LEN} bytes")
        if not 0 <= int(link_id) <= 0xFF or int(link_id) != link_id:
            raise ValueError(f"link_id must be an integer in [0, 255], got {link_id!r}")
        if max_future_s is not None and not (math.isfinite(max_future_s) and max_future_s >= 0):
            raise ValueError(f"max_future_s must be >= 0 or None, got {max_future_s!r}")
        if not (math.isfinite(new_stream_window_s) and new_stream_window_s >= 0):
            raise ValueError(f"new_stream_window_s must be >= 0, got {new_stream_window_s!r}")
        self._key = bytes(key)
        self.link_id = int(link_id)
        self._wall_clock = wall_clock
        self._max_future_ticks = None if max_future_s is None else round(max_future_s * TICKS_PER_S)
        self._new_stream_ticks = round(new_stream_window_s * TICKS_PER_S)
        self._timestamp = 0  # local signing timestamp: next one we may send
        self._streams: dict[StreamKey, int] = {}

    def __repr__(self) -> str:
        return f"Signer(key=<hidden>, link_id={self.link_id}, streams={len(self._streams)})"

    @property
    def streams(self) -> dict[StreamKey, int]:
        """Newest accepted timestamp per (link_id, system_id, component_id) (a copy)."""
        return dict(self._streams)

    def _now(self) -> int:
        return mavlink_timestamp(self._wall_clock())

    def _signature(self, signed_part: bytes | bytearray) -> bytes:
        return hashlib.sha256(self._key + bytes(signed_part)).digest()[:6]

    def sign(self, frame: bytes | bytearray, *, seq: int | None = None) -> bytes:
        """Sign a MAVLink 2 frame (a signature already on it is replaced).

        Parameters
        ----------
        frame : bytes
            One whole MAVLink 2 frame of a message id in hilnav's dialect.
        seq : int, optional
            New sequence number to write into the header before signing.

        Returns
        -------
        bytes
            The frame with the signed flag, a recomputed CRC and the 13-byte signature block;
            its timestamp is the local signing timestamp, which then increases by one.

        Raises
        ------
        ValueError
            Malformed frame or unknown message id.
        """
        payload_len, _ = check_frame(frame)
        body = bytearray(frame[: HEADER_LEN + payload_len])
        body[2] |= IFLAG_SIGNED
        if seq is not None:
            body[_SEQ_OFFSET] = seq & 0xFF
        extra = crc_extra(frame_msg_id(body))
        if extra is None:
            raise ValueError(f"message id {frame_msg_id(body)} is not in hilnav's dialect")
        body += frame_crc(body, payload_len, extra).to_bytes(2, "little")
        timestamp = max(self._timestamp, self._now())
        self._timestamp = timestamp + 1
        body.append(self.link_id)
        body += _TIMESTAMP_STRUCT.pack(timestamp)[:6]
        body += self._signature(body)
        return bytes(body)

    def verify(self, frame: bytes | bytearray) -> Verdict:
        """Verify an incoming frame's signature, then its timestamp (see module docstring).

        Stream state changes only when the verdict is :attr:`Verdict.OK`.

        Parameters
        ----------
        frame : bytes
            One whole MAVLink 2 frame whose CRC was already checked.

        Returns
        -------
        Verdict
        """
        _, signed = check_frame(frame)
        if not signed:
            return Verdict.UNSIGNED
        # Signature first: nothing an unauthenticated frame carries may change our state.
        if not hmac.compare_digest(self._signature(frame[:-6]), bytes(frame[-6:])):
            return Verdict.BAD_SIGNATURE
        link_id = frame[-SIGNATURE_BLOCK_LEN]
        timestamp = int.from_bytes(frame[-12:-6], "little")
        now = self._now()
        if self._max_future_ticks is not None and timestamp > now + self._max_future_ticks:
            return Verdict.FUTURE
        key: StreamKey = (link_id, frame[5], frame[6])
        last = self._streams.get(key)
        if last is not None:
            if timestamp <= last:
                return Verdict.REPLAY
        elif timestamp + self._new_stream_ticks < max(self._timestamp, now):
            return Verdict.STALE_STREAM
        self._streams[key] = timestamp
        self._timestamp = max(self._timestamp, timestamp)
        return Verdict.OK
