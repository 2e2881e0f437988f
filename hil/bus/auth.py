"""Authenticated payloads on the bus: an HMAC-SHA256 tag in each sample's Zenoh attachment.

Why not Zenoh's own source information: in eclipse-zenoh 1.10 ``Sample.source_info`` is None
unless the publisher sets it, and a publisher may set it to anything (``put(...,
source_info=SourceInfo(any_zid, ...))``), so it cannot tell a forged estimate from a real one.
Transport authentication and access control (:mod:`hil.bus.security`) stop unknown clients at the
router; the tag lets every *consumer* check, end to end, that a sample comes from a holder of the
shared key ``HILNAV_ZENOH_KEY`` (32 bytes, hex or base64, as the MAVLink signing key), even
through a router it does not trust.

Tag layout (attachment, 52 bytes)::

    b"HNA1" | stream id (8 random bytes per bus) | counter (8 bytes, big endian) | HMAC (32)
    HMAC = HMAC-SHA256(key, b"pub" | stream id | counter | key expression | 0x00 | payload)

A consumer drops a sample whose tag is missing or wrong, and one whose counter is not above the
last one seen on that key from that stream (a replay). Liveliness tokens carry no payload:
their owner is checked by a challenge (:meth:`PayloadAuth.reply_tag`): the consumer queries
``fusion/config`` with a fresh random nonce and only a key holder can tag the answer.
"""

from __future__ import annotations

import enum
import hashlib
import hmac
import os
import threading
from typing import Final

__all__ = ["KEY_ENV", "PayloadAuth", "Verdict"]

KEY_ENV: Final = "HILNAV_ZENOH_KEY"
"""Environment variable holding the shared payload-authentication key."""

_MAGIC: Final = b"HNA1"
_ID_LEN: Final = 8
_CTR_LEN: Final = 8
_MAC_LEN: Final = 32
TAG_LEN: Final = len(_MAGIC) + _ID_LEN + _CTR_LEN + _MAC_LEN
NONCE_LEN: Final = 16
_MAX_STREAMS: Final = 4096


class Verdict(enum.Enum):
    """What :meth:`PayloadAuth.verify` concluded about one sample."""

    OK = "ok"
    UNSIGNED = "unsigned"
    BAD_TAG = "bad tag"
    REPLAYED = "replayed"


class PayloadAuth:
    """Tags outgoing samples and checks incoming ones with one shared 32-byte key.

    Parameters
    ----------
    key : bytes
        The shared secret (at least 16 bytes; :func:`hil.signing.load_key` gives 32).
    """

    def __init__(self, key: bytes) -> None:
        if len(key) < 16:
            raise ValueError("the Zenoh payload key must be at least 16 bytes")
        self._key = bytes(key)
        self.stream_id = os.urandom(_ID_LEN)
        self._counter = 0
        self._last: dict[tuple[bytes, str], int] = {}
        self._lock = threading.Lock()

    def _mac(self, *parts: bytes) -> bytes:
        return hmac.new(self._key, b"".join(parts), hashlib.sha256).digest()

    def tag(self, key_expr: str, payload: bytes) -> bytes:
        """The attachment of the next sample published on ``key_expr``."""
        with self._lock:
            self._counter += 1
            ctr = self._counter.to_bytes(_CTR_LEN, "big")
        mac = self._mac(b"pub", self.stream_id, ctr, key_expr.encode(), b"\0", payload)
        return _MAGIC + self.stream_id + ctr + mac

    def verify(self, key_expr: str, payload: bytes, attachment: bytes | None) -> Verdict:
        """Check one received sample; remembers its counter (replays of it fail later)."""
        if attachment is None or len(attachment) != TAG_LEN or not attachment.startswith(_MAGIC):
            return Verdict.UNSIGNED
        i = len(_MAGIC)
        stream, ctr_b, mac = (attachment[i:i + _ID_LEN], attachment[i + _ID_LEN:i + _ID_LEN
                              + _CTR_LEN], attachment[i + _ID_LEN + _CTR_LEN:])
        expected = self._mac(b"pub", stream, ctr_b, key_expr.encode(), b"\0", payload)
        if not hmac.compare_digest(mac, expected):
            return Verdict.BAD_TAG
        ctr = int.from_bytes(ctr_b, "big")
        with self._lock:
            slot = (stream, key_expr)
            if ctr <= self._last.get(slot, 0):
                return Verdict.REPLAYED
            if slot not in self._last and len(self._last) >= _MAX_STREAMS:
                self._last.pop(next(iter(self._last)))  # bounded: forget the oldest stream
            self._last[slot] = ctr
        return Verdict.OK

    @staticmethod
    def nonce() -> bytes:
        """A fresh challenge for :meth:`reply_tag`."""
        return os.urandom(NONCE_LEN)

    def reply_tag(self, nonce: bytes, key_expr: str, payload: bytes) -> bytes:
        """Attachment proving that the reply ``payload`` to the challenge ``nonce`` comes from
        a key holder."""
        return self._mac(b"reply", nonce, key_expr.encode(), b"\0", payload)

    def verify_reply(self, nonce: bytes, key_expr: str, payload: bytes,
                     attachment: bytes | None) -> bool:
        """Whether a reply answers the challenge ``nonce`` with a valid tag."""
        if attachment is None:
            return False
        return hmac.compare_digest(attachment, self.reply_tag(nonce, key_expr, payload))
