"""The MAVLink link: a transport, a role, optional signing, heartbeats and counters."""

from __future__ import annotations

import math
import selectors
import time
from collections.abc import Callable
from typing import Any, Final

from hil.codec import mavlink2
from hil.codec.framing import FrameParser
from hil.codec.wire import MAGIC_V2, check_frame, crc_extra, frame_msg_id
from hil.link.counters import LinkCounters
from hil.link.fast_messages import FAST_MSG_IDS, fast_message
from hil.link.roles import HEARTBEAT_ID, LinkRole
from hil.link.transport import Handler, LinkUrl, Transport, open_transport
from hil.signing import Signer, Verdict, reframe

__all__ = ["MavlinkLink"]

_IDLE_WAKE_S: Final = 0.05  # longest real-time sleep inside recv() between housekeeping runs
_FIRST_BYTES: Final = 16  # kept of each connection's first bytes, to name a wrong protocol


#: Sequence numbers this far behind the last one count as reordered, not lost.
_REORDER_WINDOW = 16
#: Heartbeat periods a ``udpin`` reply address must have been silent before another sender's
#: address replaces it (one period of slack over the peer's own heartbeat).
PEER_HOLD_HEARTBEATS: Final = 2

class MavlinkLink:
    """One MAVLink 2 link: a transport, a role, optional signing, heartbeats and counters.

    Opening happens in the constructor (bind, listen, start connecting, open the serial
    port); a TCP client that cannot connect yet keeps retrying. Use as a context manager or
    call :meth:`close`.

    Parameters
    ----------
    url : str
        Where to (see :class:`LinkUrl`), e.g. ``"udpin:127.0.0.1:14550"``.
    role : LinkRole
        Our ids, heartbeat contents and what we accept.
    signer : hil.signing.Signer, optional
        Sign outgoing frames and accept only correctly signed incoming ones.
    clock : callable
        Monotonic time in seconds (default ``time.monotonic``); drives heartbeats, peer loss
        and reconnect backoff. Inject a fake to test those without sleeping.
    tx_buffer_bytes : int
        Stream transmit buffer; frames beyond it are dropped whole (default 64 KiB).
    reconnect_min_s, reconnect_max_s : float
        Backoff between reconnect attempts of a TCP client / serial port: starts at the
        minimum and doubles per failure up to the maximum, s.
    connect_timeout_s : float
        A TCP connection attempt still pending after this long is abandoned, s.
    fast_msg_ids : set of int
        Message ids (of :data:`hil.link.fast_messages.FAST_MSG_IDS`) whose unsigned frames
        :meth:`recv` returns as light records (:func:`hil.link.fast_messages.fast_message`:
        the same field values, the header methods of a pymavlink message) instead of
        pymavlink messages; the fusion's input uses it. Default: none.

    Raises
    ------
    ValueError
        Bad URL, unresolvable host, a port that cannot be bound, a serial device that cannot
        be opened.
    """

    def __init__(
        self,
        url: str,
        role: LinkRole,
        *,
        signer: Signer | None = None,
        clock: Callable[[], float] = time.monotonic,
        tx_buffer_bytes: int = 1 << 16,
        reconnect_min_s: float = 0.5,
        reconnect_max_s: float = 5.0,
        connect_timeout_s: float = 5.0,
        fast_msg_ids: frozenset[int] = frozenset(),
    ) -> None:
        if tx_buffer_bytes < 280:
            raise ValueError("tx_buffer_bytes must hold at least one frame (>= 280)")
        if not 0 < reconnect_min_s <= reconnect_max_s:
            raise ValueError("reconnect backoff needs 0 < reconnect_min_s <= reconnect_max_s")
        if not connect_timeout_s > 0:
            raise ValueError("connect_timeout_s must be > 0")
        if not fast_msg_ids <= FAST_MSG_IDS:
            raise ValueError(f"fast_msg_ids must be among {sorted(FAST_MSG_IDS)}")
        self._fast_msg_ids = fast_msg_ids
        self.url = LinkUrl.parse(url)
        self.role = role
        self._signer = signer
        self._clock = clock
        self._counters = LinkCounters()
        self._sel = selectors.DefaultSelector()
        # Packs our own messages (heartbeats) and decodes accepted frames. Its signing state
        # stays empty: signatures are checked by our Signer before decode() sees a frame.
        self._mav = mavlink2.MAVLink(None, srcSystem=role.system_id, srcComponent=role.component_id)
        self._stream_parser = FrameParser(self._counters, self._counters.count_mavlink1)
        self._datagram_parser = FrameParser(self._counters, self._counters.count_mavlink1)
        self._tx_seq: dict[tuple[int, int], int] = {}
        self._rx_seq: dict[tuple[int, int], int] = {}
        self._last_heartbeat: dict[tuple[int, int], float] = {}
        self._alive: set[tuple[int, int]] = set()
        self._locked_system: int | None = None
        self._reply_address: Any = None  # udpin: the sender replies go to (see _learn_peer)
        self._reply_heard = 0.0
        self._heartbeat_state = (0, 0, int(mavlink2.MAV_STATE_ACTIVE))
        self._next_heartbeat = clock()
        self._closed = False
        self._first_bytes = bytearray()
        try:
            self._transport: Transport = open_transport(
                self.url,
                self._sel,
                self._counters,
                clock,
                tx_buffer_bytes=tx_buffer_bytes,
                reconnect_min_s=reconnect_min_s,
                reconnect_max_s=reconnect_max_s,
                connect_timeout_s=connect_timeout_s,
            )
        except BaseException:
            self._sel.close()
            raise
        self._generation = self._transport.generation

    # -- context manager --
    def __enter__(self) -> MavlinkLink:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        """Close sockets / the device. Idempotent."""
        if not self._closed:
            self._closed = True
            self._transport.close()
            self._sel.close()

    def __repr__(self) -> str:
        return f"MavlinkLink({str(self.url)!r}, system={self.role.system_id}, " + (
            f"component={self.role.component_id}, signed={self._signer is not None})"
        )

    # -- introspection --
    def fileno(self) -> int:
        """A descriptor that becomes readable when the link has I/O to handle (the link's
        epoll / kqueue descriptor; stable across reconnects). Wait on it in an outer
        select loop, then call ``recv(0)``; still call :meth:`recv` or :meth:`tick` at least
        every ~0.1 s so heartbeats and reconnects run."""
        fileno: Callable[[], int] = getattr(self._sel, "fileno")  # noqa: B009
        return fileno()

    @property
    def local_address(self) -> Any:
        """Bound (host, port) of a ``udpin`` / ``udpout`` / ``tcpin`` link, else None."""
        return self._transport.local_address

    @property
    def first_bytes(self) -> bytes:
        """The first bytes (up to 16) received since the link opened or its stream last
        (re)connected: what a peer speaking another protocol sent, for the error message."""
        return bytes(self._first_bytes)

    @property
    def peer_alive(self) -> bool:
        """Whether any accepted source sent a heartbeat within the peer timeout."""
        self._check_peers(self._clock())
        return bool(self._alive)

    def peers(self) -> dict[tuple[int, int], bool]:
        """Every (system, component) that sent us a heartbeat, and whether it is alive."""
        self._check_peers(self._clock())
        return {key: key in self._alive for key in self._last_heartbeat}

    def counters(self) -> dict[str, int]:
        """A snapshot of :class:`LinkCounters` as a flat dict, plus ``dropped`` (all drop
        reasons) and ``peers_alive``."""
        out = self._counters.as_dict()
        out["peers_alive"] = len(self._alive)
        return out

    # -- sending --
    def send(self, frame: bytes) -> bool:
        """Send one MAVLink 2 frame without blocking.

        The frame gets the next sequence number of its (system, component) on this link and,
        with a signer, a signature (its CRC is recomputed when anything changed).

        Parameters
        ----------
        frame : bytes
            One whole MAVLink 2 frame of a message in hilnav's dialect (e.g. from
            :class:`hil.codec.Encoder`).

        Returns
        -------
        bool
            True when handed to the transport; False when dropped (counted: no peer yet,
            buffer full, socket error).

        Raises
        ------
        ValueError
            Not a whole MAVLink 2 frame, or a message id unknown to the dialect.
        """
        check_frame(frame)
        if crc_extra(frame_msg_id(frame)) is None:
            raise ValueError(f"message id {frame_msg_id(frame)} is not in hilnav's dialect")
        key = (frame[5], frame[6])
        seq = self._tx_seq.get(key, frame[4])
        if self._signer is not None:
            out = self._signer.sign(frame, seq=seq)
        else:
            out = reframe(frame, seq=seq)
        self._tx_seq[key] = (seq + 1) & 0xFF
        reason = self._transport.send(out)
        if reason is not None:
            setattr(self._counters, reason, getattr(self._counters, reason) + 1)
            return False
        self._counters.sent += 1
        self._counters.bytes_sent += len(out)
        return True

    def send_message(self, msg: Any) -> bool:
        """Pack a pymavlink message of the dialect from our (system, component), send it.

        Returns
        -------
        bool
            As :meth:`send`.
        """
        return self.send(bytes(msg.pack(self._mav)))

    def set_heartbeat_state(
        self, *, base_mode: int = 0, custom_mode: int = 0, system_status: int | None = None
    ) -> None:
        """Fields of our next heartbeats (``MAV_MODE_FLAG`` bits, custom mode, ``MAV_STATE``;
        default ``MAV_STATE_ACTIVE``)."""
        status = int(mavlink2.MAV_STATE_ACTIVE) if system_status is None else system_status
        if not (0 <= base_mode <= 0xFF and 0 <= custom_mode <= 0xFFFF_FFFF and 0 <= status <= 0xFF):
            raise ValueError("heartbeat base_mode, system_status must be uint8; custom_mode uint32")
        self._heartbeat_state = (base_mode, custom_mode, status)

    # -- receiving and housekeeping --
    def recv(self, timeout: float = 0.0) -> list[Any]:
        """Receive accepted messages; also runs :meth:`tick`.

        Parameters
        ----------
        timeout : float
            Longest real time to wait for the first accepted message, s (0: do not wait).

        Returns
        -------
        list of pymavlink MAVLink_message
            Accepted messages in arrival order (possibly empty). ``msg.get_msgbuf()`` is the
            whole frame as received (with its signature); ``msg.get_srcSystem()`` /
            ``get_srcComponent()`` tell the sender.
        """
        if not (math.isfinite(timeout) and timeout >= 0.0):
            raise ValueError(f"timeout must be a finite number >= 0, got {timeout!r}")
        if self._closed:
            raise ValueError("link is closed")
        deadline = time.monotonic() + timeout
        out: list[Any] = []
        wait = 0.0
        while True:
            for key, events in self._sel.select(wait):
                handler: Handler = key.data
                for data, address in handler(events):
                    self._on_bytes(data, address, out)
            self.tick()
            remaining = deadline - time.monotonic()
            if out or remaining <= 0.0:
                return out
            wait = min(remaining, _IDLE_WAKE_S)

    def tick(self) -> None:
        """Housekeeping: reconnect, heartbeat when due, detect lost peers. Cheap; call it at
        least every ~0.1 s when not calling :meth:`recv`."""
        if self._closed:
            return
        now = self._clock()
        self._transport.tick(now)
        self._check_generation()
        if now >= self._next_heartbeat:
            base_mode, custom_mode, status = self._heartbeat_state
            heartbeat = mavlink2.MAVLink_heartbeat_message(
                self.role.mav_type, self.role.autopilot, base_mode, custom_mode, status, 3
            )
            if self.send_message(heartbeat):
                self._counters.heartbeats_sent += 1
            period = self.role.heartbeat_period_s
            self._next_heartbeat += period
            if self._next_heartbeat <= now:  # late (clock jump, long pause): no burst
                self._next_heartbeat = now + period
        self._check_peers(now)

    def _check_generation(self) -> None:
        if self._transport.generation != self._generation:
            # A new stream: a partial frame of the old one must not glue onto it, and the
            # peer's sequence numbers start afresh.
            self._generation = self._transport.generation
            self._stream_parser.reset()
            self._rx_seq.clear()
            self._first_bytes.clear()

    def _check_peers(self, now: float) -> None:
        timeout = self.role.peer_timeout_s
        for key in [k for k in self._alive if now - self._last_heartbeat[k] > timeout]:
            self._alive.discard(key)
            self._rx_seq.pop(key, None)
            self._counters.peer_losses += 1

    def _on_bytes(self, data: bytes, address: Any, out: list[Any]) -> None:
        self._counters.bytes_received += len(data)
        if address is None:
            self._check_generation()
        if len(self._first_bytes) < _FIRST_BYTES:
            self._first_bytes += data[: _FIRST_BYTES - len(self._first_bytes)]
        if address is None:
            frames = self._stream_parser.feed(data)
        else:
            frames = self._datagram_parser.feed(data, final=True)
        for frame in frames:
            msg = self._accept(frame)
            if msg is not None:
                if address is not None:
                    self._learn_peer(address)
                out.append(msg)

    def _learn_peer(self, address: Any) -> None:
        """Reply to the sender of accepted frames, but keep the current one while it talks: a
        new address takes over only after the current one has been silent for
        :data:`PEER_HOLD_HEARTBEATS` heartbeat periods (a restarted simulator on a new port),
        so a second sender that forges an accepted source address cannot pull the replies
        (heartbeats, lockstep acknowledgements) away from a live peer by interleaving."""
        now = self._clock()
        if address == self._reply_address:
            self._reply_heard = now
            return
        hold_s = PEER_HOLD_HEARTBEATS * self.role.heartbeat_period_s
        if self._reply_address is None or now - self._reply_heard >= hold_s:
            self._reply_address, self._reply_heard = address, now
            self._transport.learn_peer(address)

    def _accept(self, frame: bytes) -> Any:
        c = self._counters
        c.received += 1
        if self._signer is not None:
            verdict = self._signer.verify(frame)
            if verdict is not Verdict.OK:
                setattr(c, verdict.value, getattr(c, verdict.value) + 1)
                return None
        source = (frame[5], frame[6])
        if not self.role.accepts_source(*source) or (
            self._locked_system is not None and source[0] != self._locked_system
        ):
            c.wrong_source += 1
            return None
        self._track_seq(source, frame[4])
        msg_id = frame_msg_id(frame)
        if not self.role.accepts_msg_id(msg_id):
            c.wrong_msg_id += 1
            return None
        if msg_id in self._fast_msg_ids and frame[0] == MAGIC_V2 and frame[2] == 0:
            msg = fast_message(frame, msg_id)  # the same fields, a third of the time
        else:
            try:
                msg = self._mav.decode(bytearray(frame))
            except Exception:  # pymavlink raises MAVError or struct.error on odd payloads
                c.undecodable += 1
                return None
        if msg_id == HEARTBEAT_ID:
            self._last_heartbeat[source] = self._clock()
            self._alive.add(source)
        elif self._locked_system is None and self.role.lock_to_first_source:
            self._locked_system = source[0]
        c.accepted += 1
        return msg

    @property
    def signed(self) -> bool:
        """MAVLink 2 signing is on: outgoing frames signed, unsigned incoming ones dropped."""
        return self._signer is not None

    @property
    def locked_system(self) -> int | None:
        """The system id a ``lock_to_first_source`` link bound to (None: not yet, or no lock)."""
        return self._locked_system

    def _track_seq(self, source: tuple[int, int], seq: int) -> None:
        last = self._rx_seq.get(source)
        if last is not None:
            gap = (seq - last - 1) & 0xFF
            # Up to _REORDER_WINDOW behind the last: a duplicate or a late frame. Anything else
            # is a forward jump (frames lost), also after a burst of more than 128 losses; an
            # 8-bit sequence cannot see losses of whole multiples of 256 frames.
            if gap >= 256 - _REORDER_WINDOW:
                self._counters.seq_out_of_order += 1
                return
            self._counters.lost_seq += gap
        self._rx_seq[source] = seq
