"""MAVLink 2 links of the live service: UDP, TCP and serial, with heartbeats, source filtering,
optional signing and counters.

This is the only hilnav package that opens MAVLink connections (sockets and serial ports are
touched in :mod:`hil.link.transport` alone). It does not use
``pymavlink.mavutil`` (2.4.50): its connection classes pick a process-global dialect from
environment variables, can cut a frame in two on a partial non-blocking TCP send
(``mavtcp.write`` ignores what ``send()`` returns), parse through pymavlink's signature check
(which lets one forged frame block a signed stream, see :mod:`hil.signing`), and after a bad
frame resynchronise by discarding the bytes its header claimed (the good frame right behind a
truncated one is lost too). Instead the link frames bytes itself on plain non-blocking
sockets (``socket`` + ``selectors``) and serial ports (pyserial opens and configures the port;
reads and writes go straight to its file descriptor), checks CRCs and signatures itself, and
hands only accepted frames to the dialect's ``MAVLink.decode`` (:data:`hil.codec.mavlink2`).

URLs (:class:`LinkUrl`)
    ============================  ==========================================================
    ``udpin:HOST:PORT``           bind and listen; replies go to the sender of the last
                                  *accepted* frame (UDP peer learning: a sender that comes
                                  back from a new port is followed, garbage cannot redirect)
    ``udpout:HOST:PORT``          send to HOST:PORT from an ephemeral port; receive replies
    ``tcp:HOST:PORT``             client; reconnects with exponential backoff
    ``tcpin:HOST:PORT``           server; one client at a time, a new client replaces the old
                                  one (a peer that reboots is not locked out by a dead
                                  half-open connection)
    ``serial:DEVICE:BAUD``        e.g. ``serial:/dev/ttyACM0:921600``; reopened with backoff
                                  after an error (USB unplugged)
    ============================  ==========================================================

    Port 0 in ``udpin`` / ``tcpin`` binds a free port (see :attr:`MavlinkLink.local_address`).

Receive pipeline (every frame is counted in exactly one place; see :class:`LinkCounters`)
    1. Framing (:class:`FrameParser`): find ``0xFD``, check the CRC with the dialect's
       CRC_EXTRA. A frame whose CRC fails is counted and scanning resumes one byte after its
       start, so a truncated frame never swallows the good frame behind it. Frames of message
       ids the dialect does not know cannot be CRC-checked: they are dropped and counted, and
       skipped whole only when the next byte starts a frame (otherwise the 0xFD is treated as
       garbage). MAVLink 1 frames (``0xFE``) are framed, CRC-checked and dropped.
       UDP datagrams are parsed one by one (a frame never spans datagrams): a truncated
       datagram cannot corrupt the next.
    2. Signature (only with a :class:`~hil.signing.Signer`): the signature is verified before
       any stream timestamp is touched; unsigned, badly signed, replayed, stale and
       far-future frames are dropped. A link without a key accepts signed frames unchecked
       and sends unsigned ones.
    3. Source: frames from our own (system, component) (an echo) or from a source not in
       :attr:`LinkRole.accept_sources` are dropped. Sequence gaps of accepted sources are
       counted (``lost_seq``).
    4. Message id: HEARTBEAT is always accepted from an accepted source (peer detection);
       other ids must be in :attr:`LinkRole.accept_msg_ids`.
    5. Decode with the dialect; accepted messages are returned in arrival order. Nothing
       accepted is ever dropped or reordered by the link. Unsigned frames of the ids given in
       ``fast_msg_ids`` come back as light records with the same fields
       (:mod:`hil.link.fast_messages`; the fusion's input).

Sending
    :meth:`MavlinkLink.send` takes whole MAVLink 2 frames, e.g. from
    :class:`hil.codec.Encoder`. The link owns outgoing sequence numbers: every frame leaving
    it from one (system, component) continues that component's sequence, so heartbeats packed
    by the link and frames packed by an encoder of the same component do not make the peer
    count losses. With a signer every frame is signed. Sends never block: UDP datagrams the
    kernel will not take, and stream frames that would overflow the transmit buffer
    (``tx_buffer_bytes``) are dropped whole and counted; a frame is never cut. Frames still
    queued when a stream connection drops are discarded with it.

Heartbeats and peers
    :meth:`MavlinkLink.tick` (also run by :meth:`MavlinkLink.recv`) sends HEARTBEAT every
    :attr:`LinkRole.heartbeat_period_s` (1 s) with the role's type, autopilot and ids, and
    declares a peer (system, component) lost after ``peer_timeout_heartbeats`` (5) heartbeat
    periods without its heartbeat. All schedules (heartbeats, peer loss, reconnect backoff)
    use the injected ``clock``; the ``timeout`` of :meth:`MavlinkLink.recv` is real time (how
    long the process may block).

A link is not thread-safe: one thread owns it.

Modules
    ``roles`` (:class:`LinkRole`, message id sets, the lockstep constants), ``counters``
    (:class:`LinkCounters`), ``fast_messages`` (records of high-rate frames), ``transport``
    (:class:`LinkUrl`, UDP / TCP / serial byte transports), ``endpoint``
    (:class:`MavlinkLink`). The framing (:class:`FrameParser`, no I/O) is
    :mod:`hil.codec.framing`, shared with the decoder.
    Signing lives in :mod:`hil.signing`.
"""

from hil.codec.framing import FrameParser
from hil.link.counters import LinkCounters
from hil.link.endpoint import MavlinkLink
from hil.link.fast_messages import FAST_MSG_IDS
from hil.link.roles import (
    FC_SENSOR_MSG_IDS,
    HIL_MSG_IDS,
    LOCKSTEP_CUSTOM_MODE,
    TIMESYNC_ID,
    LinkRole,
)
from hil.link.transport import LinkUrl

__all__ = [
    "FAST_MSG_IDS",
    "FC_SENSOR_MSG_IDS",
    "HIL_MSG_IDS",
    "LOCKSTEP_CUSTOM_MODE",
    "TIMESYNC_ID",
    "FrameParser",
    "LinkCounters",
    "LinkRole",
    "LinkUrl",
    "MavlinkLink",
]
