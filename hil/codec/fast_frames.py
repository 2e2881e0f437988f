"""Fast MAVLink 2 framing of the two high-rate messages, HIL_SENSOR (107) and HIL_GPS (113).

pymavlink stays the reference and the path for every other message. For these two, which
carry every IMU sample and GNSS fix, building a message object to pack it, and decoding a
frame through :meth:`MAVLink.decode` (which checks the CRC the framing parser already
checked), cost most of the codec's time. This module does the same work with one
``struct`` call and one CRC:

- :func:`pack_frame`: payload bytes -> an unsigned MAVLink 2 frame, as pymavlink's
  ``MAVLink_message._pack`` builds it (trailing zero bytes of the payload cut, at least one
  kept; header ``FD len 0 0 seq sys comp id``; X.25/MCRF4XX CRC over header, payload and
  CRC_EXTRA), so the bytes are identical.
- :func:`unpack_fields`: the payload of a CRC-checked, unsigned MAVLink 2 frame of one of the
  two ids -> a named tuple with pymavlink's field names and values (the truncated payload is
  zero-padded to the message length, extra bytes beyond it ignored, as pymavlink does).

Bit-exactness against pymavlink, for every field, signed and unsigned frames, is a property
test (``tests/hil/test_fast_frames.py``). Signed frames are not handled here: the decoder
gives them to pymavlink, which checks the signature.
"""

from __future__ import annotations

import struct
from collections.abc import Callable, Iterable
from typing import Any, Final, NamedTuple

from hil.codec.wire import mavlink2
from hil.signing import mcrf4xx as _mcrf4xx

__all__ = [
    "HIL_GPS_ID",
    "HIL_SENSOR_ID",
    "HilGpsFields",
    "HilSensorFields",
    "gps_payload",
    "pack_frame",
    "sensor_payload",
    "unpack_fields",
]

_MAGIC_V2: Final = 0xFD
_HEADER: Final = struct.Struct("<BBBBBBBHB")
_HEADER_LEN: Final = 10

HIL_SENSOR_ID: Final = int(mavlink2.MAVLINK_MSG_ID_HIL_SENSOR)
HIL_GPS_ID: Final = int(mavlink2.MAVLINK_MSG_ID_HIL_GPS)
_SENSOR_CLS: Final = mavlink2.MAVLink_hil_sensor_message
_GPS_CLS: Final = mavlink2.MAVLink_hil_gps_message
_SENSOR_STRUCT: Final[struct.Struct] = _SENSOR_CLS.unpacker
_GPS_STRUCT: Final[struct.Struct] = _GPS_CLS.unpacker


class HilSensorFields(NamedTuple):
    """HIL_SENSOR's fields in wire order (pymavlink's names and units)."""

    time_usec: int
    xacc: float
    yacc: float
    zacc: float
    xgyro: float
    ygyro: float
    zgyro: float
    xmag: float
    ymag: float
    zmag: float
    abs_pressure: float
    diff_pressure: float
    pressure_alt: float
    temperature: float
    fields_updated: int
    id: int


class HilGpsFields(NamedTuple):
    """HIL_GPS's fields in wire order (pymavlink's names and units)."""

    time_usec: int
    lat: int
    lon: int
    alt: int
    eph: int
    epv: int
    vel: int
    vn: int
    ve: int
    vd: int
    cog: int
    fix_type: int
    satellites_visible: int
    id: int
    yaw: int


# The wire order above must be pymavlink's (a dialect update that reorders fields fails here).
assert HilSensorFields._fields == tuple(_SENSOR_CLS.ordered_fieldnames)
assert HilGpsFields._fields == tuple(_GPS_CLS.ordered_fieldnames)

# msg id -> (payload struct, its size, the named tuple's constructor from a value sequence)
_FIELDS: Final[dict[int, tuple[struct.Struct, int, Callable[[Iterable[Any]], Any]]]] = {
    HIL_SENSOR_ID: (_SENSOR_STRUCT, _SENSOR_STRUCT.size, HilSensorFields._make),
    HIL_GPS_ID: (_GPS_STRUCT, _GPS_STRUCT.size, HilGpsFields._make),
}
_CRC_EXTRA: Final = {
    HIL_SENSOR_ID: bytes((_SENSOR_CLS.crc_extra,)),
    HIL_GPS_ID: bytes((_GPS_CLS.crc_extra,)),
}


def sensor_payload(*fields: float | int) -> bytes:
    """HIL_SENSOR payload (untruncated) of its 16 fields in wire order."""
    return _SENSOR_STRUCT.pack(*fields)


def gps_payload(*fields: float | int) -> bytes:
    """HIL_GPS payload (untruncated) of its 15 fields in wire order (:class:`HilGpsFields`)."""
    return _GPS_STRUCT.pack(*fields)


def pack_frame(msg_id: int, payload: bytes, seq: int, system_id: int, component_id: int) -> bytes:
    """An unsigned MAVLink 2 frame of HIL_SENSOR or HIL_GPS, byte for byte as pymavlink packs it.

    Parameters
    ----------
    msg_id : int
        :data:`HIL_SENSOR_ID` or :data:`HIL_GPS_ID`.
    payload : bytes
        The untruncated payload (:func:`sensor_payload`, :func:`gps_payload`).
    seq, system_id, component_id : int
        Header fields, 0..255.

    Returns
    -------
    bytes
    """
    body = payload.rstrip(b"\x00") or payload[:1]
    header = _HEADER.pack(
        _MAGIC_V2, len(body), 0, 0, seq, system_id, component_id, msg_id & 0xFFFF, msg_id >> 16
    )
    crc = _mcrf4xx(_CRC_EXTRA[msg_id], _mcrf4xx(body, _mcrf4xx(header[1:])))
    return b"".join((header, body, crc.to_bytes(2, "little")))


def unpack_fields(frame: bytes, msg_id: int) -> HilSensorFields | HilGpsFields | None:
    """The fields of a CRC-checked unsigned MAVLink 2 frame, or None when ``msg_id`` is not one
    of the two fast messages.

    Parameters
    ----------
    frame : bytes
        A whole frame, header to CRC, as :class:`hil.codec.framing.FrameParser` returns it.
    msg_id : int
        Its message id.
    """
    spec = _FIELDS.get(msg_id)
    if spec is None:
        return None
    unpacker, size, make = spec
    end = _HEADER_LEN + frame[1]
    if end - _HEADER_LEN >= size:
        values = unpacker.unpack_from(frame, _HEADER_LEN)
    else:
        values = unpacker.unpack(frame[_HEADER_LEN:end] + bytes(size - (end - _HEADER_LEN)))
    fields: HilSensorFields | HilGpsFields = make(values)
    return fields
