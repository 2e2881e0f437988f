"""Counters of a MAVLink link (published as the link's status)."""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import ClassVar

__all__ = ["LinkCounters"]


@dataclass(slots=True)
class LinkCounters:
    """What a link saw and did. All counts since the link was opened.

    Every CRC-valid frame of a known message id is counted in ``received`` and then in exactly
    one of ``accepted`` or the drop reasons ``mavlink1`` .. ``undecodable``. ``bad_crc``,
    ``unknown_msg_id`` and ``truncated`` count frames that never reach ``received``.

    Attributes
    ----------
    bytes_received, bytes_sent : raw bytes read / handed to the transport.
    garbage_bytes : bytes outside any CRC-valid frame (noise, corrupted and truncated frames).
    bad_crc : candidate frames of a known id whose CRC failed.
    unknown_msg_id : frames of ids the dialect does not know (no CRC check possible).
    truncated : frames cut short by the end of a UDP datagram.
    received : CRC-valid frames of known ids.
    accepted : frames returned by :meth:`MavlinkLink.recv`.
    mavlink1 : MAVLink 1 frames (the link speaks MAVLink 2 only).
    unsigned, bad_signature, replayed, stale_stream, future_timestamp : signing rejections
        (see :class:`hil.signing.Verdict`).
    wrong_source : frames from a source not accepted by the role, or our own echo.
    wrong_msg_id : frames of a message id the role does not accept.
    undecodable : CRC-valid frames the dialect could not unpack.
    lost_seq : sequence numbers skipped by accepted sources.
    seq_out_of_order : frames of accepted sources whose sequence went backwards (duplicates,
        reordering, a restarted sender); they are still delivered.
    sent : frames handed to the transport. heartbeats_sent : of which heartbeats.
    tx_no_peer : frames not sent because there is no peer or connection yet.
    tx_buffer_full : frames dropped because the socket / transmit buffer was full.
    tx_errors, rx_errors : other socket or device errors.
    connects, disconnects, connect_failures : stream (TCP / serial) connections.
    udp_peer_changes : times ``udpin`` learned a new reply address.
    peer_losses : peers declared lost (missed heartbeats).
    """

    bytes_received: int = 0
    bytes_sent: int = 0
    garbage_bytes: int = 0
    bad_crc: int = 0
    unknown_msg_id: int = 0
    truncated: int = 0
    received: int = 0
    accepted: int = 0
    mavlink1: int = 0
    unsigned: int = 0
    bad_signature: int = 0
    replayed: int = 0
    stale_stream: int = 0
    future_timestamp: int = 0
    wrong_source: int = 0
    wrong_msg_id: int = 0
    undecodable: int = 0
    lost_seq: int = 0
    seq_out_of_order: int = 0
    sent: int = 0
    heartbeats_sent: int = 0
    tx_no_peer: int = 0
    tx_buffer_full: int = 0
    tx_errors: int = 0
    rx_errors: int = 0
    connects: int = 0
    disconnects: int = 0
    connect_failures: int = 0
    udp_peer_changes: int = 0
    peer_losses: int = 0

    DROP_REASONS: ClassVar[tuple[str, ...]] = (
        "bad_crc",
        "unknown_msg_id",
        "truncated",
        "mavlink1",
        "unsigned",
        "bad_signature",
        "replayed",
        "stale_stream",
        "future_timestamp",
        "wrong_source",
        "wrong_msg_id",
        "undecodable",
    )

    def count_mavlink1(self) -> None:
        """A CRC-valid MAVLink 1 frame was received and dropped (the links speak MAVLink 2)."""
        self.received += 1
        self.mavlink1 += 1

    @property
    def dropped(self) -> int:
        """Frames dropped for any reason in :attr:`DROP_REASONS`."""
        return sum(getattr(self, name) for name in self.DROP_REASONS)

    def as_dict(self) -> dict[str, int]:
        """All counters plus ``dropped`` as a flat dict (JSON status)."""
        out = {f.name: getattr(self, f.name) for f in fields(self)}
        out["dropped"] = self.dropped
        return out
