"""A mission for the autopilot and its upload with the MAVLink mission protocol.

Items (:class:`MissionItem`, built by :func:`takeoff`, :func:`waypoint`, :func:`loiter`,
:func:`return_to_launch`) carry absolute positions: latitude / longitude in degrees and the
altitude above mean sea level, sent as MISSION_ITEM_INT in ``MAV_FRAME_GLOBAL`` (AMSL), so the
mission does not depend on where the autopilot puts its home (ArduPilot and PX4 both reset home
when they arm, which for an aircraft started in the air is wherever it was then). Commands:
NAV_TAKEOFF (22, ``param1`` the minimum / takeoff pitch in degrees), NAV_WAYPOINT (16),
NAV_LOITER_TURNS (18, ``param1`` turns, ``param3`` radius m, positive = clockwise),
NAV_LOITER_TIME (19, ``param1`` seconds, ``param3`` radius m), NAV_RETURN_TO_LAUNCH (20).

ArduPilot keeps its home in mission slot 0: the list it is sent starts with a home item (the
scenario's start) that it replaces with its own; PX4's list starts with the first item
(:func:`mission_list`).

The upload (:class:`MissionUpload`, driven by :class:`hil.autopilot.commander.Commander`):
MISSION_COUNT -> the autopilot asks for every item by sequence number with MISSION_REQUEST_INT
(or the legacy MISSION_REQUEST, which older firmware sends; both are answered with
MISSION_ITEM_INT) -> after the last item it answers MISSION_ACK. A request for an item already
sent (its answer was lost) is answered again. When nothing comes for ``retry_s`` the upload
repeats what it sent last (MISSION_COUNT before the first request, else the last item), as a
ground station does; an ACK other than MAV_MISSION_ACCEPTED ends it as failed, naming the
result and the item last asked for.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Final

from hil.codec import mavlink2

__all__ = ["MissionItem", "MissionUpload", "loiter", "mission_list", "return_to_launch",
           "takeoff", "waypoint"]

_NAV_WAYPOINT: Final = int(mavlink2.MAV_CMD_NAV_WAYPOINT)
_NAV_TAKEOFF: Final = int(mavlink2.MAV_CMD_NAV_TAKEOFF)
_NAV_LOITER_TURNS: Final = int(mavlink2.MAV_CMD_NAV_LOITER_TURNS)
_NAV_LOITER_TIME: Final = int(mavlink2.MAV_CMD_NAV_LOITER_TIME)
_NAV_RTL: Final = int(mavlink2.MAV_CMD_NAV_RETURN_TO_LAUNCH)
_FRAME_GLOBAL: Final = int(mavlink2.MAV_FRAME_GLOBAL)
_FRAME_MISSION: Final = int(mavlink2.MAV_FRAME_MISSION)
_REQUEST_INT: Final = int(mavlink2.MAVLINK_MSG_ID_MISSION_REQUEST_INT)
_REQUEST: Final = int(mavlink2.MAVLINK_MSG_ID_MISSION_REQUEST)
_ACK: Final = int(mavlink2.MAVLINK_MSG_ID_MISSION_ACK)
_ACCEPTED: Final = int(mavlink2.MAV_MISSION_ACCEPTED)
_NO_SPACE: Final = int(mavlink2.MAV_MISSION_NO_SPACE)
MISSION_MSG_IDS: Final = frozenset({_REQUEST_INT, _REQUEST, _ACK})
"""What the autopilot answers an upload with."""


@dataclass(frozen=True)
class MissionItem:
    """One mission command (``command`` a MAV_CMD) at ``lat_deg`` / ``lon_deg`` /
    ``alt_msl_m`` (None: the command has no position), with ``param1..4`` and a ``label``
    for messages (``"waypoint 2"``)."""

    command: int
    label: str
    lat_deg: float | None = None
    lon_deg: float | None = None
    alt_msl_m: float | None = None
    param1: float = 0.0
    param2: float = 0.0
    param3: float = 0.0
    param4: float = 0.0

    def message(self, seq: int, target: tuple[int, int]) -> Any:
        """The MISSION_ITEM_INT of this item at ``seq`` for ``target`` (system, component)."""
        has_position = self.lat_deg is not None and self.lon_deg is not None
        return mavlink2.MAVLink_mission_item_int_message(
            target[0], target[1], seq, _FRAME_GLOBAL if has_position else _FRAME_MISSION,
            self.command, 0, 1, self.param1, self.param2, self.param3, self.param4,
            round((self.lat_deg or 0.0) * 1e7), round((self.lon_deg or 0.0) * 1e7),
            float(self.alt_msl_m or 0.0), int(mavlink2.MAV_MISSION_TYPE_MISSION))


def takeoff(lat_deg: float, lon_deg: float, alt_msl_m: float, *, pitch_deg: float = 15.0,
            label: str = "takeoff") -> MissionItem:
    """Climb out to ``alt_msl_m`` (towards ``lat_deg``, ``lon_deg``), pitch ``pitch_deg``."""
    return MissionItem(_NAV_TAKEOFF, label, lat_deg, lon_deg, alt_msl_m, param1=pitch_deg)


def waypoint(lat_deg: float, lon_deg: float, alt_msl_m: float, *,
             label: str = "waypoint") -> MissionItem:
    """Fly to a point."""
    return MissionItem(_NAV_WAYPOINT, label, lat_deg, lon_deg, alt_msl_m)


def loiter(lat_deg: float, lon_deg: float, alt_msl_m: float, *, radius_m: float,
           turns: float | None = None, time_s: float | None = None,
           label: str = "loiter") -> MissionItem:
    """Circle a point for ``turns`` turns or ``time_s`` seconds (exactly one of them);
    ``radius_m`` > 0 clockwise, < 0 counter-clockwise."""
    if (turns is None) == (time_s is None):
        raise ValueError("a loiter takes turns or time_s (one of them)")
    if not (math.isfinite(radius_m) and radius_m != 0.0):
        raise ValueError(f"loiter radius must be a non-zero number of metres, got {radius_m}")
    if turns is not None:
        return MissionItem(_NAV_LOITER_TURNS, label, lat_deg, lon_deg, alt_msl_m,
                           param1=turns, param3=radius_m)
    assert time_s is not None
    return MissionItem(_NAV_LOITER_TIME, label, lat_deg, lon_deg, alt_msl_m, param1=time_s,
                       param3=radius_m)


def return_to_launch(label: str = "return to launch") -> MissionItem:
    """Fly home (the autopilot's own return-to-launch behaviour and altitude)."""
    return MissionItem(_NAV_RTL, label)


def mission_list(autopilot: str, items: Sequence[MissionItem],
                 home: tuple[float, float, float]) -> list[MissionItem]:
    """What is uploaded to ``autopilot``: ArduPilot's list starts with its home slot
    (``home`` = lat deg, lon deg, alt MSL m; it replaces it with its own), PX4's does not."""
    if autopilot == "ardupilot":
        return [waypoint(*home, label="home"), *items]
    return list(items)


class MissionUpload:
    """One upload of ``items`` to ``target`` (see the module docstring). The caller feeds
    the autopilot's answers to :meth:`on_message`, calls :meth:`tick` with its clock, and
    sends what :meth:`outgoing` returns; :attr:`done` / :attr:`error` tell the outcome."""

    def __init__(self, items: Sequence[MissionItem], target: tuple[int, int], *,
                 retry_s: float = 1.0) -> None:
        if not items:
            raise ValueError("a mission needs at least one item")
        self.items = list(items)
        self.target = target
        self.retry_s = retry_s
        self.done = False
        self.error: str | None = None
        self.requested: set[int] = set()
        self.legacy_requests = 0
        """MISSION_REQUEST (not _INT) messages the autopilot sent."""
        self.repeats = 0
        """Messages sent again after ``retry_s`` of silence."""
        self.not_ready = 0
        """MISSION_COUNTs refused with NO_SPACE before any item was asked for: ArduPilot's
        answer while its mission storage is not set up yet (early in its boot); the count
        is sent again after ``retry_s`` until the step's timeout."""
        self._out: list[Any] = []
        self._last: Any = None
        self._last_at_s = -math.inf
        self._asked = -1  # the item last asked for

    def start(self, now_s: float) -> None:
        """Send MISSION_COUNT."""
        self._send(mavlink2.MAVLink_mission_count_message(
            self.target[0], self.target[1], len(self.items),
            int(mavlink2.MAV_MISSION_TYPE_MISSION)), now_s)

    def outgoing(self) -> list[Any]:
        """Messages to send now (each returned once)."""
        out, self._out = self._out, []
        return out

    def on_message(self, msg: Any, now_s: float) -> None:
        """An answer of the autopilot (other messages are ignored)."""
        if self.done or self.error is not None:
            return
        msg_id = msg.get_msgId()
        if int(getattr(msg, "mission_type", 0) or 0) != int(mavlink2.MAV_MISSION_TYPE_MISSION):
            return
        if msg_id in (_REQUEST_INT, _REQUEST):
            seq = int(msg.seq)
            if msg_id == _REQUEST:
                self.legacy_requests += 1
            if not 0 <= seq < len(self.items):
                self.error = (f"the autopilot asked for mission item {seq} of a "
                              f"{len(self.items)}-item mission")
                return
            self.requested.add(seq)
            self._asked = seq
            self._send(self.items[seq].message(seq, self.target), now_s)
        elif msg_id == _ACK:
            result = int(msg.type)
            if result == _ACCEPTED and len(self.requested) == len(self.items):
                self.done = True
            elif result == _ACCEPTED:
                missing = sorted(set(range(len(self.items))) - self.requested)
                self.error = (f"the autopilot accepted the mission without asking for "
                              f"item(s) {missing}")
            elif result == _NO_SPACE and self._asked < 0:
                self.not_ready += 1  # :meth:`tick` sends the count again
            else:
                name = _mission_result_name(result)
                after = ("before asking for any item" if self._asked < 0 else
                         f"after item {self._asked} ({self.items[self._asked].label})")
                self.error = f"the autopilot refused the mission with {name} {after}"

    def tick(self, now_s: float) -> None:
        """Repeat the last message after ``retry_s`` without an answer."""
        if self.done or self.error is not None or self._last is None:
            return
        if now_s - self._last_at_s >= self.retry_s:
            self.repeats += 1
            self._send(self._last, now_s)

    def waiting_for(self) -> str:
        """What the upload waits for, for a timeout sentence."""
        if self._asked < 0 and self.not_ready:
            return (f"the autopilot refused MISSION_COUNT ({len(self.items)} items) with "
                    f"MAV_MISSION_NO_SPACE {self.not_ready} times and never asked for an item")
        if self._asked < 0:
            return "the autopilot never asked for an item after MISSION_COUNT"
        if len(self.requested) < len(self.items):
            nxt = min(set(range(len(self.items))) - self.requested)
            return (f"the autopilot asked for {len(self.requested)} of {len(self.items)} items "
                    f"and never for item {nxt} ({self.items[nxt].label})")
        return "every item was sent but the autopilot never answered MISSION_ACK"

    def _send(self, msg: Any, now_s: float) -> None:
        self._out.append(msg)
        self._last = msg
        self._last_at_s = now_s


def _mission_result_name(result: int) -> str:
    enum = mavlink2.enums.get("MAV_MISSION_RESULT", {})
    entry = enum.get(result)
    return entry.name if entry is not None else f"MAV_MISSION_RESULT {result}"
