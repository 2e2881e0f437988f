"""Byte transports of MAVLink links: UDP, TCP client / server, serial (non-blocking).

The only place in hilnav that opens sockets or serial ports for MAVLink. A transport moves
bytes and nothing else: framing, signing and filtering are :class:`hil.link.MavlinkLink`'s.
"""

from __future__ import annotations

import errno
import math
import os
import selectors
import socket
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Final, Literal

from hil.link.counters import LinkCounters

__all__ = ["Chunk", "Handler", "LinkUrl", "Transport", "open_transport"]

Scheme = Literal["udpin", "udpout", "tcp", "tcpin", "serial"]
_SCHEMES: Final = ("udpin", "udpout", "tcp", "tcpin", "serial")


@dataclass(frozen=True, slots=True)
class LinkUrl:
    """A parsed link URL (see the module docstring).

    Attributes
    ----------
    scheme : {"udpin", "udpout", "tcp", "tcpin", "serial"}
    host : str
        Host name or address (serial: the device path).
    port : int
        Port (serial: the baud rate).
    """

    scheme: Scheme
    host: str
    port: int

    @classmethod
    def parse(cls, text: str) -> LinkUrl:
        """Parse ``SCHEME:HOST:PORT`` (IPv6 hosts in brackets) or ``serial:DEVICE:BAUD``.

        Raises
        ------
        ValueError
            Unknown scheme, missing part, or a port / baud rate out of range.
        """
        scheme, sep, rest = text.partition(":")
        if not sep or scheme not in _SCHEMES:
            raise ValueError(
                f"link URL {text!r}: scheme must be one of {', '.join(_SCHEMES)} "
                "(e.g. udpin:127.0.0.1:14550, serial:/dev/ttyACM0:921600)"
            )
        host, sep, number = rest.rpartition(":")
        what = "baud rate" if scheme == "serial" else "port"
        if not sep or not host or not number.isdigit():
            raise ValueError(f"link URL {text!r}: expected {scheme}:HOST:{what.upper()}")
        value = int(number)
        if scheme == "serial":
            if value <= 0:
                raise ValueError(f"link URL {text!r}: baud rate must be > 0")
        else:
            if host.startswith("[") and host.endswith("]"):
                host = host[1:-1]
            lowest = 0 if scheme in ("udpin", "tcpin") else 1
            if not lowest <= value <= 0xFFFF:
                raise ValueError(f"link URL {text!r}: port must be in [{lowest}, 65535]")
        return cls(scheme, host, value)  # type: ignore[arg-type]

    def __str__(self) -> str:
        host = f"[{self.host}]" if ":" in self.host and self.scheme != "serial" else self.host
        return f"{self.scheme}:{host}:{self.port}"


# A transport moves bytes and nothing else. Its file objects are registered in the link's
# selector with a handler as data; a handler returns the chunks it read as (bytes, address)
# with address None for streams. ``generation`` changes whenever a stream (re)connects, so the
# link can forget a partial frame and the peers' sequence numbers.
Chunk = tuple[bytes, Any]
Handler = Callable[[int], list[Chunk]]

_READ: Final = selectors.EVENT_READ
_WRITE: Final = selectors.EVENT_WRITE
_MAX_READS: Final = 256  # per readiness event: a flood cannot starve the caller
_READ_SIZE: Final = 65536
_RCVBUF_BYTES: Final = 4 << 20  # ~1 s of 20x HIL traffic; capped by net.core.rmem_max


class Transport:
    """Interface of the link's byte transports."""

    generation: int = 0

    @property
    def local_address(self) -> Any:
        return None

    def send(self, data: bytes) -> str | None:
        """Queue or send one frame without blocking; None, or the counter name of the drop."""
        raise NotImplementedError

    def tick(self, now: float) -> None:
        """Time-driven work (reconnects)."""

    def learn_peer(self, address: Any) -> None:
        """An accepted frame came from ``address`` (UDP only)."""

    def close(self) -> None:
        raise NotImplementedError


def _resolve(host: str, port: int, kind: socket.SocketKind) -> tuple[int, Any]:
    try:
        infos = socket.getaddrinfo(host, port, type=kind)
    except socket.gaierror as exc:
        raise ValueError(f"cannot resolve host {host!r}: {exc.strerror}") from None
    family, _, _, _, address = infos[0]
    return family, address


class _Udp(Transport):
    def __init__(self, url: LinkUrl, sel: selectors.BaseSelector, counters: LinkCounters) -> None:
        self._c = counters
        self._sel = sel
        family, address = _resolve(url.host, url.port, socket.SOCK_DGRAM)
        self._inbound = url.scheme == "udpin"
        sock = socket.socket(family, socket.SOCK_DGRAM)
        try:
            sock.setblocking(False)
            try:
                sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, _RCVBUF_BYTES)
            except OSError:
                pass  # the kernel's limit then applies; a flood beyond it is lost before us
            if self._inbound:
                sock.bind(address)
                self._peer: Any = None
            else:
                sock.bind(("::" if family == socket.AF_INET6 else "0.0.0.0", 0))
                self._peer = address
        except OSError as exc:
            sock.close()
            raise ValueError(f"{url}: cannot open UDP socket ({exc.strerror})") from None
        self._sock = sock
        sel.register(sock, _READ, self._on_event)

    @property
    def local_address(self) -> Any:
        return self._sock.getsockname()

    def _on_event(self, events: int) -> list[Chunk]:
        out: list[Chunk] = []
        for _ in range(_MAX_READS):
            try:
                data, address = self._sock.recvfrom(_READ_SIZE)
            except BlockingIOError:
                break
            except OSError:
                self._c.rx_errors += 1  # e.g. ICMP port unreachable from an earlier send
                continue
            out.append((data, address))
        return out

    def send(self, data: bytes) -> str | None:
        if self._peer is None:
            return "tx_no_peer"
        try:
            self._sock.sendto(data, self._peer)
        except BlockingIOError:
            return "tx_buffer_full"
        except OSError:
            return "tx_errors"
        return None

    def learn_peer(self, address: Any) -> None:
        if self._inbound and address != self._peer:
            self._peer = address
            self._c.udp_peer_changes += 1

    def close(self) -> None:
        self._sel.unregister(self._sock)
        self._sock.close()


class _Stream(Transport):
    """A byte stream (TCP connection, serial port) with a bounded transmit buffer."""

    def __init__(
        self,
        sel: selectors.BaseSelector,
        counters: LinkCounters,
        clock: Callable[[], float],
        *,
        tx_buffer_bytes: int,
        reconnect_min_s: float,
        reconnect_max_s: float,
    ) -> None:
        self._sel = sel
        self._c = counters
        self._clock = clock
        self._tx_limit = tx_buffer_bytes
        self._backoff_min = reconnect_min_s
        self._backoff_max = reconnect_max_s
        self._backoff = reconnect_min_s
        self._retry_at = -math.inf
        self._io: Any = None  # the registered socket or fd while connected or connecting
        self._connecting = False
        self._tx = bytearray()
        self.generation = 0

    # -- subclass hooks --
    def _read(self) -> bytes:
        raise NotImplementedError

    def _write(self, data: bytearray) -> int:
        raise NotImplementedError

    def _close_io(self) -> None:
        raise NotImplementedError

    def _reopen(self, now: float) -> None:
        """Start connecting / reopen (called when the retry time has come)."""

    # -- connection state --
    @property
    def connected(self) -> bool:
        return self._io is not None and not self._connecting

    def _attach(self, io: Any) -> None:
        self._io = io
        self._connecting = False
        self._backoff = self._backoff_min
        self.generation += 1
        self._c.connects += 1
        self._tx.clear()
        self._sel.register(io, _READ, self._on_event)

    def _detach(self, *, failed_attempt: bool = False) -> None:
        if self._io is None:
            return
        if failed_attempt:
            self._c.connect_failures += 1
        else:
            self._c.disconnects += 1
        self._sel.unregister(self._io)
        self._close_io()
        self._io = None
        self._connecting = False
        self._tx.clear()  # the rest of a frame must never start a new connection
        self._schedule_retry()

    def _schedule_retry(self) -> None:
        self._retry_at = self._clock() + self._backoff
        self._backoff = min(2.0 * self._backoff, self._backoff_max)

    def _want_write(self, want: bool) -> None:
        if self._io is not None:
            self._sel.modify(self._io, _READ | _WRITE if want else _READ, self._on_event)

    # -- I/O --
    def _on_event(self, events: int) -> list[Chunk]:
        out: list[Chunk] = []
        if events & _READ and self._io is not None:
            for attempt in range(_MAX_READS // 16):
                try:
                    data = self._read()
                except BlockingIOError:
                    break
                except OSError:
                    self._c.rx_errors += 1
                    self._detach()
                    break
                if not data:
                    # Readable yet nothing to read on the first attempt: the peer closed (TCP
                    # end of stream, serial hang-up). Later in the loop it only means "no
                    # more now": a tty in raw mode returns b"" instead of EAGAIN.
                    if attempt == 0:
                        self._detach()
                    break
                out.append((data, None))
        if events & _WRITE and self._io is not None and not self._flush():
            self._c.tx_errors += 1
        return out

    def _flush(self) -> bool:
        """Write what the socket takes now; False if the connection failed (then dropped)."""
        while self._tx and self._io is not None:
            try:
                n = self._write(self._tx)
            except BlockingIOError:
                break
            except OSError:
                self._detach()
                return False
            if n <= 0:
                break
            del self._tx[:n]
        self._want_write(bool(self._tx))
        return True

    def send(self, data: bytes) -> str | None:
        if not self.connected:
            return "tx_no_peer"
        if len(self._tx) + len(data) > self._tx_limit:
            return "tx_buffer_full"
        self._tx += data
        # A write error drops the connection, this frame and any queued with it.
        return None if self._flush() else "tx_errors"

    def tick(self, now: float) -> None:
        if self._io is None and now >= self._retry_at:
            self._reopen(now)

    def close(self) -> None:
        if self._io is not None:
            self._sel.unregister(self._io)
            self._close_io()
            self._io = None


class _TcpClient(_Stream):
    def __init__(self, url: LinkUrl, *, connect_timeout_s: float, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self._family, self._address = _resolve(url.host, url.port, socket.SOCK_STREAM)
        self._connect_timeout_s = connect_timeout_s
        self._deadline = math.inf
        self._reopen(self._clock())

    def _reopen(self, now: float) -> None:
        sock = socket.socket(self._family, socket.SOCK_STREAM)
        sock.setblocking(False)
        err = sock.connect_ex(self._address)
        if err not in (0, errno.EINPROGRESS, errno.EWOULDBLOCK, errno.EALREADY):
            sock.close()
            self._c.connect_failures += 1
            self._schedule_retry()
            return
        # Completion (or refusal) is reported as writability; see _on_connect_event.
        self._io = sock
        self._connecting = True
        self._deadline = now + self._connect_timeout_s
        self._sel.register(sock, _WRITE, self._on_connect_event)

    def _on_connect_event(self, events: int) -> list[Chunk]:
        sock = self._io
        err = sock.getsockopt(socket.SOL_SOCKET, socket.SO_ERROR)
        if err:
            self._detach(failed_attempt=True)
            return []
        self._sel.unregister(sock)
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self._attach(sock)
        return []

    def tick(self, now: float) -> None:
        if self._connecting and now > self._deadline:
            self._detach(failed_attempt=True)
        super().tick(now)

    def _read(self) -> bytes:
        return bytes(self._io.recv(_READ_SIZE))

    def _write(self, data: bytearray) -> int:
        return int(self._io.send(data))

    def _close_io(self) -> None:
        self._io.close()


class _TcpServer(_Stream):
    def __init__(self, url: LinkUrl, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        family, address = _resolve(url.host, url.port, socket.SOCK_STREAM)
        listener = socket.socket(family, socket.SOCK_STREAM)
        try:
            # A restarted server must be able to bind while old connections are in TIME_WAIT.
            listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            listener.bind(address)
            listener.listen(1)
            listener.setblocking(False)
        except OSError as exc:
            listener.close()
            raise ValueError(f"{url}: cannot listen ({exc.strerror})") from None
        self._listener = listener
        self._retry_at = math.inf  # a server never dials out
        self._sel.register(listener, _READ, self._on_accept)

    @property
    def local_address(self) -> Any:
        return self._listener.getsockname()

    def _on_accept(self, events: int) -> list[Chunk]:
        while True:
            try:
                conn, _ = self._listener.accept()
            except BlockingIOError:
                return []
            except OSError:
                self._c.rx_errors += 1
                return []
            if self._io is not None:
                self._detach()  # the newest client wins
            conn.setblocking(False)
            conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            self._attach(conn)

    def _schedule_retry(self) -> None:
        self._retry_at = math.inf

    def _read(self) -> bytes:
        return bytes(self._io.recv(_READ_SIZE))

    def _write(self, data: bytearray) -> int:
        return int(self._io.send(data))

    def _close_io(self) -> None:
        self._io.close()

    def close(self) -> None:
        super().close()
        self._sel.unregister(self._listener)
        self._listener.close()


class _Serial(_Stream):
    def __init__(self, url: LinkUrl, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        import serial  # pyserial; imported here so that socket-only users do not need it

        self._serial_module = serial
        self._device = url.host
        self._baud = url.port
        self._port: Any = None
        if not self._open():
            raise ValueError(f"{url}: cannot open serial device {self._device!r}")

    def _open(self) -> bool:
        serial = self._serial_module
        port = serial.Serial()
        port.port = self._device
        port.baudrate = self._baud
        port.timeout = 0
        port.write_timeout = 0
        try:
            port.open()
        except (serial.SerialException, OSError, ValueError):
            return False
        self._port = port
        # pyserial opens O_NONBLOCK and sets raw mode; plain os.read / os.write on its fd keep
        # EAGAIN visible (pyserial's own non-blocking write spins on it).
        self._attach(port.fileno())
        return True

    def _reopen(self, now: float) -> None:
        if not self._open():
            self._c.connect_failures += 1
            self._schedule_retry()

    def _read(self) -> bytes:
        return os.read(self._io, _READ_SIZE)

    def _write(self, data: bytearray) -> int:
        return os.write(self._io, data)

    def _close_io(self) -> None:
        if self._port is not None:
            self._port.close()
            self._port = None


def open_transport(
    url: LinkUrl,
    sel: selectors.BaseSelector,
    counters: LinkCounters,
    clock: Callable[[], float],
    *,
    tx_buffer_bytes: int,
    reconnect_min_s: float,
    reconnect_max_s: float,
    connect_timeout_s: float,
) -> Transport:
    """Open the transport a URL names and register it in ``sel``.

    Parameters
    ----------
    url : LinkUrl
    sel : selectors.BaseSelector
        The link's selector; key data are :data:`Handler` callables.
    counters : LinkCounters
        Receives transport counts (connects, tx drops, errors).
    clock : callable
        Monotonic time, s (reconnect backoff).
    tx_buffer_bytes, reconnect_min_s, reconnect_max_s, connect_timeout_s
        See :class:`hil.link.MavlinkLink`.

    Returns
    -------
    Transport

    Raises
    ------
    ValueError
        Unresolvable host, a port that cannot be bound, a serial device that cannot be opened.
    """
    if url.scheme in ("udpin", "udpout"):
        return _Udp(url, sel, counters)
    stream_args: dict[str, Any] = {
        "sel": sel,
        "counters": counters,
        "clock": clock,
        "tx_buffer_bytes": tx_buffer_bytes,
        "reconnect_min_s": reconnect_min_s,
        "reconnect_max_s": reconnect_max_s,
    }
    if url.scheme == "tcp":
        return _TcpClient(url, connect_timeout_s=connect_timeout_s, **stream_args)
    if url.scheme == "tcpin":
        return _TcpServer(url, **stream_args)
    return _Serial(url, **stream_args)
