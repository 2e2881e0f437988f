"""Setting an ArduPilot SITL's ``SIM_*`` parameters over its MAVLink port on simulated time.

:class:`SimParamSender` opens a MAVLink link (:mod:`hil.link`, e.g. ``tcp:127.0.0.1:5760``,
SITL's first serial port) as a ground station (system 255, component 190) and sends each
:class:`sim.faults.ardupilot.ParamSet` as PARAM_SET to the autopilot (system 1, component 1 by
default) once the simulated time reaches it. ArduPilot answers every PARAM_SET with a
PARAM_VALUE of the parameter; those acknowledgements are counted (``params_acked``), and a
PARAM_VALUE whose value differs from the one set (a parameter this ArduPilot does not have
keeps answering nothing, a read-only one answers its own value) counts as ``params_rejected``.
Sending never blocks the simulator: a PARAM_SET the link cannot take now (not connected
yet) is retried on the next step, in order (``params_send_failed`` counts each such change
once).
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Sequence

from hil.codec import mavlink2
from hil.link import LinkRole, MavlinkLink
from sim.faults.ardupilot import ParamSet

__all__ = ["SimParamSender"]

_GCS_SYSTEM_ID = 255
_GCS_COMPONENT_ID = int(mavlink2.MAV_COMP_ID_MISSIONPLANNER)
_PARAM_VALUE_ID = int(mavlink2.MAVLINK_MSG_ID_PARAM_VALUE)


class SimParamSender:
    """Sends a parameter schedule over MAVLink on simulated time (see the module docstring).

    Parameters
    ----------
    url : str
        ArduPilot's MAVLink port (a :class:`hil.link.LinkUrl`).
    schedule : sequence of ParamSet
        In time order (:func:`sim.faults.ardupilot.ardupilot_param_schedule`).
    target_system, target_component : int
        The autopilot's ids (ArduPilot SITL: 1, 1).
    """

    def __init__(self, url: str, schedule: Sequence[ParamSet], *, target_system: int = 1,
                 target_component: int = 1) -> None:
        role = LinkRole(
            system_id=_GCS_SYSTEM_ID, component_id=_GCS_COMPONENT_ID,
            mav_type=int(mavlink2.MAV_TYPE_GCS), autopilot=int(mavlink2.MAV_AUTOPILOT_INVALID),
            accept_sources=frozenset({(target_system, target_component)}),
            accept_msg_ids=frozenset({_PARAM_VALUE_ID}),
        )
        self.link = MavlinkLink(url, role)
        self._schedule = list(schedule)
        self._next = 0
        self._target = (target_system, target_component)
        self._pending: dict[str, deque[float]] = {}  # values set, not acknowledged yet
        self._failed_at = -1
        self.sent = self.acked = self.rejected = self.send_failed = 0

    def close(self) -> None:
        self.link.close()

    def advance(self, time_s: float) -> None:
        """Send everything due at or before ``time_s``; read acknowledgements (no waiting)."""
        self.poll()
        while self._next < len(self._schedule) and self._schedule[self._next].time_s <= time_s:
            p = self._schedule[self._next]
            msg = mavlink2.MAVLink_param_set_message(
                self._target[0], self._target[1], p.name.encode("ascii"), float(p.value),
                int(mavlink2.MAV_PARAM_TYPE_REAL32),
            )
            if not self.link.send_message(msg):
                if self._failed_at != self._next:  # count each change once, not each retry
                    self.send_failed += 1
                    self._failed_at = self._next
                break  # retried on the next step, in order
            self.sent += 1
            self._pending.setdefault(p.name, deque()).append(p.value)
            self._next += 1

    def poll(self, timeout_s: float = 0.0) -> None:
        """Read PARAM_VALUE acknowledgements (waiting up to ``timeout_s`` for the first)."""
        for msg in self.link.recv(timeout_s):
            if msg.get_msgId() != _PARAM_VALUE_ID:
                continue
            name = msg.param_id.rstrip("\x00") if isinstance(msg.param_id, str) else \
                bytes(msg.param_id).rstrip(b"\x00").decode("ascii", "replace")
            queue = self._pending.get(name)
            if not queue:
                continue  # not ours (a ground station's read, a duplicate)
            wanted = queue.popleft()  # TCP keeps the order: the oldest set is answered first
            if math.isclose(float(msg.param_value), wanted, rel_tol=1e-6, abs_tol=1e-9):
                self.acked += 1
            else:
                self.rejected += 1

    @property
    def remaining(self) -> int:
        """Parameter changes not sent yet."""
        return len(self._schedule) - self._next

    def counters(self) -> dict[str, int]:
        return {"params_sent": self.sent, "params_acked": self.acked,
                "params_rejected": self.rejected, "params_send_failed": self.send_failed}
