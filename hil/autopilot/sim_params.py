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

A step of the denial that is not acknowledged in time (``ack_timeout_s`` of simulated time and
at least ``ack_wall_s`` wall seconds after it was due, or by the end of the flight) did not
reach ArduPilot: it is one sentence of :meth:`SimParamSender.problems` naming the parameter
and the link, and the run that flew with it has failed (a port held by another program, a
MAVProxy in between that swallows our PARAM_SET, a wrong address all end there). Every step's
outcome is :meth:`SimParamSender.steps`, from which the scorecard knows which GNSS windows
ArduPilot was really denied.

The link also hears ArduPilot's HEARTBEAT (every MAVLink port gets it): its armed flag is
:attr:`SimParamSender.armed`, what the JSON backend holds the trim on.
"""

from __future__ import annotations

import math
import time
from collections import deque
from collections.abc import Sequence

from hil.autopilot.backend import DenialStep
from hil.codec import mavlink2
from hil.link import LinkRole, MavlinkLink
from sim.faults.ardupilot import ParamSet

__all__ = ["SimParamSender"]

_GCS_SYSTEM_ID = 255
_GCS_COMPONENT_ID = int(mavlink2.MAV_COMP_ID_MISSIONPLANNER)
_PARAM_VALUE_ID = int(mavlink2.MAVLINK_MSG_ID_PARAM_VALUE)
_HEARTBEAT_ID = int(mavlink2.MAVLINK_MSG_ID_HEARTBEAT)
_ARMED = int(mavlink2.MAV_MODE_FLAG_SAFETY_ARMED)


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
    ack_timeout_s : float
        Simulated seconds after a change is due by which its PARAM_VALUE must have come.
    ack_wall_s : float
        ... and wall seconds (a loaded machine answers late, not never).
    """

    def __init__(self, url: str, schedule: Sequence[ParamSet], *, target_system: int = 1,
                 target_component: int = 1, ack_timeout_s: float = 5.0,
                 ack_wall_s: float = 2.0) -> None:
        role = LinkRole(
            system_id=_GCS_SYSTEM_ID, component_id=_GCS_COMPONENT_ID,
            mav_type=int(mavlink2.MAV_TYPE_GCS), autopilot=int(mavlink2.MAV_AUTOPILOT_INVALID),
            accept_sources=frozenset({(target_system, target_component)}),
            accept_msg_ids=frozenset({_PARAM_VALUE_ID}),
        )
        self.url = url
        self.link = MavlinkLink(url, role)
        self.ack_timeout_s = ack_timeout_s
        self.ack_wall_s = ack_wall_s
        self._schedule = list(schedule)
        self._status = ["not due"] * len(self._schedule)
        self._due_wall: list[float | None] = [None] * len(self._schedule)
        self._next = 0
        self._target = (target_system, target_component)
        self._pending: dict[str, deque[int]] = {}  # steps set, not acknowledged yet
        self._failed_at = -1
        self._late: list[int] = []  # steps that missed their deadline, in order
        self.sent = self.acked = self.rejected = self.send_failed = 0
        self.armed: bool | None = None
        """ArduPilot's armed flag from its latest HEARTBEAT on this link (None: none yet)."""

    def close(self) -> None:
        self.link.close()

    def advance(self, time_s: float) -> None:
        """Send everything due at or before ``time_s``; read acknowledgements (no waiting)."""
        self.poll()
        now = time.monotonic()
        for i in range(self._next, len(self._schedule)):
            if self._schedule[i].time_s > time_s:
                break
            if self._due_wall[i] is None:
                self._due_wall[i] = now
                self._status[i] = "not sent"
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
            self._status[self._next] = "unacknowledged"
            self._pending.setdefault(p.name, deque()).append(self._next)
            self._next += 1
        self._check_deadlines(time_s, now)

    def poll(self, timeout_s: float = 0.0) -> None:
        """Read PARAM_VALUE acknowledgements and HEARTBEATs (waiting up to ``timeout_s``
        for the first)."""
        for msg in self.link.recv(timeout_s):
            msg_id = msg.get_msgId()
            if msg_id == _HEARTBEAT_ID:
                if (msg.get_srcSystem(), msg.get_srcComponent()) == self._target:
                    self.armed = bool(int(msg.base_mode) & _ARMED)
                continue
            if msg_id != _PARAM_VALUE_ID:
                continue
            name = msg.param_id.rstrip("\x00") if isinstance(msg.param_id, str) else \
                bytes(msg.param_id).rstrip(b"\x00").decode("ascii", "replace")
            queue = self._pending.get(name)
            if not queue:
                continue  # not ours (a ground station's read, a duplicate)
            i = queue.popleft()  # TCP keeps the order: the oldest set is answered first
            wanted = self._schedule[i].value
            if math.isclose(float(msg.param_value), wanted, rel_tol=1e-6, abs_tol=1e-9):
                self.acked += 1
                self._status[i] = "acknowledged"
            else:
                self.rejected += 1
                self._status[i] = "rejected"
                if i not in self._late:
                    self._late.append(i)

    def finish(self, wall_timeout_s: float | None = None) -> None:
        """The flight is over: wait up to ``wall_timeout_s`` (default ``ack_wall_s``) for the
        acknowledgements still owed; what is still unanswered then did not reach ArduPilot."""
        deadline = time.monotonic() + (self.ack_wall_s if wall_timeout_s is None
                                       else wall_timeout_s)
        while any(self._pending.values()):
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                break
            self.poll(min(remaining, 0.1))
        for i, status in enumerate(self._status):
            if status in ("unacknowledged", "not sent") and i not in self._late:
                self._late.append(i)

    def _check_deadlines(self, time_s: float, now: float) -> None:
        for i in range(len(self._schedule)):
            due_wall = self._due_wall[i]
            if due_wall is None:
                break  # the schedule is in time order: nothing later is due
            if self._status[i] not in ("unacknowledged", "not sent") or i in self._late:
                continue
            if (time_s - self._schedule[i].time_s >= self.ack_timeout_s
                    and now - due_wall >= self.ack_wall_s):
                self._late.append(i)

    @property
    def remaining(self) -> int:
        """Parameter changes not sent yet."""
        return len(self._schedule) - self._next

    def steps(self) -> list[DenialStep]:
        """Every change of the schedule and what became of it."""
        return [DenialStep(p.time_s, p.name, p.value, status)
                for p, status in zip(self._schedule, self._status, strict=True)]

    def problems(self) -> list[str]:
        """One sentence per change that did not reach ArduPilot in time, in order."""
        out = []
        for i in self._late:
            p, status = self._schedule[i], self._status[i]
            change = f"{p.name} = {p.value:g} (due at {p.time_s:g} s)"
            head = {
                "not sent": f"{change} could not be sent",
                "rejected": f"ArduPilot answered another value to {change}",
                "acknowledged": f"ArduPilot acknowledged {change} only after "
                                f"{self.ack_timeout_s:g} s",
            }.get(status, f"ArduPilot did not acknowledge {change}")
            out.append(f"{head} on {self.url}: that step of the scenario's denial did not "
                       "reach ArduPilot in time (is another program holding that port?)")
        return out

    def counters(self) -> dict[str, int]:
        return {"params_sent": self.sent, "params_acked": self.acked,
                "params_rejected": self.rejected, "params_send_failed": self.send_failed,
                "params_late": len(self._late)}
