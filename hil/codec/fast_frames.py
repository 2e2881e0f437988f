"""Fast MAVLink 2 framing of the simulator's high-rate messages: HIL_SENSOR (107), HIL_GPS
(113), HIL_STATE_QUATERNION (115), HIL_ACTUATOR_CONTROLS (93) and RAW_RPM (339).

pymavlink stays the reference and the path for every other message. For these five, which
carry every IMU sample, GNSS fix, truth sample and control output of a lockstep run, building
a message object to pack it, and decoding a frame through :meth:`MAVLink.decode` (which
checks again the CRC the framing parser already checked, and builds a message object with
a dozen bookkeeping attributes), cost most of the codec's time. :class:`FastLayout` does the
same work from pymavlink's own description of the message (its ``struct`` format, field order
and array lengths), with one ``struct`` call and one CRC:

- :meth:`FastLayout.payload` + :func:`pack_frame`: field values (in the order of pymavlink's
  constructor, arrays as sequences) -> an unsigned MAVLink 2 frame, as pymavlink's
  ``MAVLink_message._pack`` builds it (trailing zero bytes of the payload cut, at least one
  kept; header ``FD len 0 0 seq sys comp id``; X.25/MCRF4XX CRC over header, payload and
  CRC_EXTRA), so the bytes are identical.
- :func:`unpack_fields`: a CRC-checked, unsigned MAVLink 2 frame -> a named tuple with
  pymavlink's field names and values (arrays as lists; the truncated payload zero-padded to
  the message length, bytes beyond it ignored, as pymavlink does).

Bit-exactness against pymavlink, for every field of the five messages, is a property test
(``tests/hil/test_fast_frames.py``). Signed frames are not handled here: the decoder gives
them to pymavlink, which checks the signature.
"""

from __future__ import annotations

import struct
from collections import namedtuple
from collections.abc import Callable, Sequence
from operator import itemgetter
from typing import Any, Final

from hil.codec.wire import mavlink2
from hil.codec.wire import mcrf4xx as _mcrf4xx

__all__ = [
    "FAST_LAYOUTS",
    "HIL_ACTUATOR_CONTROLS",
    "HIL_GPS",
    "HIL_SENSOR",
    "HIL_STATE_QUATERNION",
    "RAW_RPM",
    "FastLayout",
    "pack_frame",
    "unpack_fields",
]

_MAGIC_V2: Final = 0xFD
_HEADER: Final = struct.Struct("<BBBBBBBHB")
_HEADER_LEN: Final = 10
_tuple_new = tuple.__new__


class FastLayout:
    """The wire layout of one fixed-size MAVLink message, read off its pymavlink class.

    Parameters
    ----------
    cls : pymavlink message class
        Without string (char array) fields.

    Attributes
    ----------
    msg_id : int
    wire_fields : tuple of str
        Field names in wire order (pymavlink's ``ordered_fieldnames``).
    pack_fields : callable
        Field values (constructor order) -> the untruncated payload, as :meth:`payload`.
    fields : type
        Named tuple (a ``collections.namedtuple``) of the message's fields in pymavlink's
        constructor order.
    """

    def __init__(self, cls: Any) -> None:
        if "s" in cls.unpacker.format or "c" in cls.unpacker.format:
            raise ValueError(f"{cls.msgname} has string fields: not a fast-path message")
        self.msg_id: int = int(cls.id)
        self.crc_extra_byte = bytes((int(cls.crc_extra),))
        self._struct: struct.Struct = cls.unpacker
        self._size: int = cls.unpacker.size
        self.fields: Any = namedtuple(  # type: ignore[misc]  # a layout read at run time
            cls.msgname.title().replace("_", "") + "Fields", cls.fieldnames
        )
        lengths: list[int] = list(cls.lengths)
        # constructor field i sits at wire position orders[i], its values at flat index tip
        self._plan = tuple(
            (sum(lengths[: cls.orders[i]]), lengths[cls.orders[i]])
            for i in range(len(cls.fieldnames))
        )
        self._wire_order = tuple(cls.fieldnames.index(n) for n in cls.ordered_fieldnames)
        self._arrays = any(n > 1 for _, n in self._plan)
        self._identity = not self._arrays and self._wire_order == tuple(range(len(lengths)))
        # constructor field i is struct value orders[i] when there are no arrays
        self._reorder: Callable[[tuple[Any, ...]], tuple[Any, ...]] | None = (
            None if self._arrays or len(self._plan) < 2  # (one index: not a tuple)
            else itemgetter(*(tip for tip, _ in self._plan))
        )
        self._pad = tuple(bytes(self._size - n) for n in range(self._size))  # by payload length
        self.wire_fields: tuple[str, ...] = tuple(cls.ordered_fieldnames)
        self.pack_wire_order: Callable[..., bytes] = self._struct.pack
        """Field values in wire order (:attr:`wire_fields`, no arrays) -> the untruncated
        payload: :meth:`payload` without its reordering."""
        self.pack_fields: Callable[..., bytes] = (
            self._struct.pack if self._identity else self.payload
        )
        """:meth:`payload` itself, or the ``struct`` call it makes when the wire order is the
        field order (no Python call around it)."""

    def payload(self, *values: Any) -> bytes:
        """The untruncated payload of the fields in constructor order (arrays as sequences of
        exactly their length)."""
        if self._identity:
            return self._struct.pack(*values)
        if not self._arrays:
            return self._struct.pack(*[values[j] for j in self._wire_order])
        flat: list[Any] = []
        for j in self._wire_order:
            v = values[j]
            if self._plan[j][1] > 1:
                flat.extend(v)
            else:
                flat.append(v)
        return self._struct.pack(*flat)

    def unpack_wire(self, frame: bytes) -> tuple[Any, ...]:
        """The struct's values of a whole frame (header to CRC) of this message, in wire order
        (:attr:`wire_fields`, arrays flattened); a truncated payload is zero-filled."""
        n = frame[1]
        if n >= self._size:
            return self._struct.unpack_from(frame, _HEADER_LEN)
        return self._struct.unpack(frame[_HEADER_LEN : _HEADER_LEN + n] + self._pad[n])

    def unpack(self, frame: bytes) -> Any:
        """The fields of a whole frame (header to CRC) of this message."""
        t = self.unpack_wire(frame)
        if self._identity:  # the struct gives exactly the fields: no length check needed
            return _tuple_new(self.fields, t)
        if self._reorder is not None:  # no arrays: the fields are the struct's values reordered
            return _tuple_new(self.fields, self._reorder(t))
        return self.fields._make(
            [t[tip] if n == 1 else list(t[tip : tip + n]) for tip, n in self._plan]
        )


HIL_SENSOR: Final = FastLayout(mavlink2.MAVLink_hil_sensor_message)
HIL_GPS: Final = FastLayout(mavlink2.MAVLink_hil_gps_message)
HIL_STATE_QUATERNION: Final = FastLayout(mavlink2.MAVLink_hil_state_quaternion_message)
HIL_ACTUATOR_CONTROLS: Final = FastLayout(mavlink2.MAVLink_hil_actuator_controls_message)
RAW_RPM: Final = FastLayout(mavlink2.MAVLink_raw_rpm_message)
FAST_LAYOUTS: Final = {
    x.msg_id: x for x in (HIL_SENSOR, HIL_GPS, HIL_STATE_QUATERNION, HIL_ACTUATOR_CONTROLS,
                          RAW_RPM)
}
"""Message id -> layout of the fast-path messages."""


def pack_frame(
    layout: FastLayout, payload: bytes, seq: int, system_id: int, component_id: int
) -> bytes:
    """An unsigned MAVLink 2 frame, byte for byte as pymavlink packs it.

    Parameters
    ----------
    layout : FastLayout
        The message (e.g. :data:`HIL_SENSOR`).
    payload : bytes
        Its untruncated payload (:meth:`FastLayout.payload`).
    seq, system_id, component_id : int
        Header fields, 0..255.

    Returns
    -------
    bytes
    """
    body = payload.rstrip(b"\x00") or payload[:1]
    msg_id = layout.msg_id
    frame = _HEADER.pack(
        _MAGIC_V2, len(body), 0, 0, seq, system_id, component_id, msg_id & 0xFFFF, msg_id >> 16
    ) + body
    # one CRC call over header (without the magic), payload and CRC_EXTRA: cheaper than three
    return frame + _mcrf4xx(frame[1:] + layout.crc_extra_byte).to_bytes(2, "little")


def unpack_fields(frame: bytes, msg_id: int) -> Sequence[Any] | None:
    """The fields of a CRC-checked unsigned MAVLink 2 frame as a named tuple, or None when
    ``msg_id`` is not a fast-path message.

    Parameters
    ----------
    frame : bytes
        A whole frame, header to CRC, as :class:`hil.codec.framing.FrameParser` returns it.
    msg_id : int
        Its message id.
    """
    layout = FAST_LAYOUTS.get(msg_id)
    return None if layout is None else layout.unpack(frame)
