"""Light message records for the link's high-rate input (live latency).

:meth:`hil.link.MavlinkLink.recv` hands accepted frames to pymavlink's ``MAVLink.decode``,
which checks again the CRC the link's framing already checked and builds a message object with
a dozen bookkeeping attributes: about a third of the link's receive time per HIL_SENSOR frame
on the fusion's input. For the message ids a link is given in ``fast_msg_ids`` (those of
:data:`hil.codec.fast_frames.FAST_LAYOUTS`), unsigned MAVLink 2 frames are returned instead as
a :func:`fast_message`: the named tuple of :meth:`hil.codec.fast_frames.FastLayout.unpack`
(pymavlink's field names and values, bit-exact: ``tests/hil/test_fast_frames.py``) plus the
``MAVLink_message`` methods that read the header: ``get_msgId``, ``get_type``,
``get_srcSystem``, ``get_srcComponent``, ``get_seq``, ``get_msgbuf``, ``get_signed``. Signed
frames always go through pymavlink.
"""

from __future__ import annotations

from typing import Any, Final

from hil.codec.fast_frames import FAST_LAYOUTS, FastLayout
from hil.codec.wire import mavlink2

__all__ = ["FAST_MSG_IDS", "fast_message"]

FAST_MSG_IDS: Final = frozenset(FAST_LAYOUTS)
"""Message ids a link can return as light records."""

_tuple_new = tuple.__new__


def _message_class(layout: FastLayout, name: str) -> type:
    msg_id = layout.msg_id

    def get_msgId(self: Any) -> int:  # pymavlink's names
        return msg_id

    def get_type(self: Any) -> str:
        return name

    def get_srcSystem(self: Any) -> int:
        return int(self.frame[5])

    def get_srcComponent(self: Any) -> int:
        return int(self.frame[6])

    def get_seq(self: Any) -> int:
        return int(self.frame[4])

    def get_msgbuf(self: Any) -> bytearray:
        return bytearray(self.frame)

    def get_signed(self: Any) -> bool:
        return False

    # a subclass of the layout's named tuple without __slots__: instances carry ``frame``
    return type(layout.fields.__name__.replace("Fields", "Message"), (layout.fields,), {
        "get_msgId": get_msgId, "get_type": get_type, "get_srcSystem": get_srcSystem,
        "get_srcComponent": get_srcComponent, "get_seq": get_seq, "get_msgbuf": get_msgbuf,
        "get_signed": get_signed, "__doc__": f"{name} fields and header of one frame.",
    })


_CLASSES: Final = {
    msg_id: (layout, _message_class(layout, str(mavlink2.mavlink_map[msg_id].msgname)))
    for msg_id, layout in FAST_LAYOUTS.items()
}


def fast_message(frame: bytes, msg_id: int) -> Any:
    """The record of a CRC-checked, unsigned MAVLink 2 frame of a :data:`FAST_MSG_IDS` id.

    Parameters
    ----------
    frame : bytes
        The whole frame, header to CRC.
    msg_id : int
        Its message id (a key of :data:`FAST_MSG_IDS`).
    """
    layout, cls = _CLASSES[msg_id]
    msg: Any = _tuple_new(cls, layout.unpack(frame))
    msg.frame = frame
    return msg
