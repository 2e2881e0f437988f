"""The autopilot's side of the parameter, command and mission protocols, for the protocol peers.

Written from what ArduPilot (``libraries/GCS_MAVLink/GCS_Param.cpp``, ``GCS_Common.cpp``,
``MissionItemProtocol.cpp``, ``AP_Arming``) and PX4 (``src/modules/mavlink/
mavlink_parameters.cpp``, ``mavlink_mission.cpp``, ``commander/Commander.cpp``) do, read not
copied, independent of hilnav's commander:

* PARAM_SET of a parameter it has: stored and answered with PARAM_VALUE of the stored value
  (PX4's integer parameters byte-wise: the int32's bits in the float field). A parameter it
  does not have: no answer. A parameter it refuses (``reject_params``, e.g. read-only):
  ArduPilot says ``Param write denied (NAME)`` and answers the old value; PX4 answers the old
  value.
* MAV_CMD_COMPONENT_ARM_DISARM: while its pre-arm checks fail (before ``prearm_ok_s`` of its
  clock) it refuses with a STATUSTEXT saying why (ArduPilot ``PreArm: ...`` and COMMAND_ACK
  FAILED; PX4 ``Preflight Fail: ...`` and TEMPORARILY_REJECTED); then it arms (ACCEPTED) and
  its HEARTBEAT says so.
* MAV_CMD_DO_SET_MODE (param1 custom-mode flag; ArduPilot: param2 the mode number; PX4:
  param2 main mode, param3 sub mode): ACCEPTED, and its HEARTBEAT ``custom_mode`` is the new
  mode; an unknown mode is refused (DENIED).
* the mission upload: MISSION_COUNT -> it asks for item 0, 1, ... with MISSION_REQUEST_INT
  (``legacy_requests``: MISSION_REQUEST, as older firmware) and stores each MISSION_ITEM_INT /
  MISSION_ITEM; a request not answered within ``request_retry_s`` of its clock is sent again;
  after the last item MISSION_ACK ACCEPTED.

Misbehaviour for tests: ``reject_params``, ``never_ack_arm`` (arming commands get no answer
and do nothing), ``never_reach_mode`` (ACCEPTED, but the mode never changes), ``drop_request``
(the first request for that item is lost; it asks again), ``stall_request`` (it never asks for
that item: the upload hangs).
"""

from __future__ import annotations

import struct
from collections.abc import Callable, Collection
from dataclasses import dataclass
from typing import Any

from hil.codec import mavlink2

__all__ = ["CommandSide"]

_ARM = int(mavlink2.MAV_CMD_COMPONENT_ARM_DISARM)
_SET_MODE = int(mavlink2.MAV_CMD_DO_SET_MODE)
_INT_TYPES = frozenset(range(1, 9))


@dataclass
class _Upload:
    count: int
    next_seq: int = 0
    asked_at_s: float = -1.0
    dropped: bool = False


class CommandSide:
    """One autopilot's side of the protocols (see the module docstring).

    Parameters
    ----------
    flavour : ``"ardupilot"`` or ``"px4"``
    params : dict
        Parameter name -> value it has; ``int_params`` are PX4 INT32 parameters.
    custom_mode : int
        Its mode at boot (ArduPlane MANUAL = 0; PX4 MANUAL = 1 << 16).
    valid_modes : collection of int
        custom_mode values it accepts.
    prearm_ok_s : float
        Its clock from which its pre-arm checks pass.
    prearm_reason : str
        What its pre-arm check says until then.
    prearm_check : callable, optional
        A further pre-arm check of the autopilot (called at each arm command): the reason it
        refuses (e.g. ArduPilot's "GPS 2: Bad fix"), or None when it passes.
    """

    def __init__(self, flavour: str, params: dict[str, float], *,
                 int_params: Collection[str] = (), custom_mode: int = 0,
                 valid_modes: Collection[int] = (), prearm_ok_s: float = 0.0,
                 prearm_reason: str = "Airspeed too high - check airspeed calibration",
                 reject_params: Collection[str] = (), never_ack_arm: bool = False,
                 never_reach_mode: bool = False, drop_request: int | None = None,
                 stall_request: int | None = None, legacy_requests: bool = False,
                 request_retry_s: float = 1.0, mission_ready_s: float = 0.0,
                 prearm_check: Callable[[], str | None] | None = None) -> None:
        self.flavour = flavour
        self.prearm_check = prearm_check
        self.mission_ready_s = mission_ready_s
        """Until then a MISSION_COUNT is refused with NO_SPACE, as ArduPilot answers before its
        mission storage is set up (early in its boot)."""
        self.params = dict(params)
        self.int_params = frozenset(int_params)
        self.armed = False
        self.custom_mode = custom_mode
        self.valid_modes = frozenset(valid_modes)
        self.prearm_ok_s = prearm_ok_s
        self.prearm_reason = prearm_reason
        self.reject_params = frozenset(reject_params)
        self.never_ack_arm = never_ack_arm
        self.never_reach_mode = never_reach_mode
        self.drop_request = drop_request
        self.stall_request = stall_request
        self.legacy_requests = legacy_requests
        self.request_retry_s = request_retry_s
        self.mission: list[Any] = []
        self.mission_accepted = False
        self.param_log: list[tuple[str, float]] = []
        self.arm_attempts = 0
        self.armed_at_s: float | None = None
        self.mode_log: list[tuple[float, int]] = []
        self.requests_sent: list[int] = []
        self._upload: _Upload | None = None
        self._items: dict[int, Any] = {}

    # -- entry points --
    def handle(self, msg: Any, clock_s: float) -> list[Any]:
        """Answers to one message from the ground station."""
        kind = msg.get_type()
        if kind == "PARAM_SET":
            return self._param_set(msg)
        if kind == "COMMAND_LONG":
            return self._command(msg, clock_s)
        if kind == "MISSION_COUNT":
            if int(msg.mission_type) != int(mavlink2.MAV_MISSION_TYPE_MISSION):
                return []
            if clock_s < self.mission_ready_s:
                return [mavlink2.MAVLink_mission_ack_message(
                    255, 190, mavlink2.MAV_MISSION_NO_SPACE, mavlink2.MAV_MISSION_TYPE_MISSION)]
            self._upload = _Upload(int(msg.count))
            self._items = {}
            self.mission_accepted = False
            return self._request(clock_s)
        if kind in ("MISSION_ITEM_INT", "MISSION_ITEM"):
            return self._item(msg, clock_s)
        return []

    def tick(self, clock_s: float) -> list[Any]:
        """A request that got no item in time is sent again."""
        up = self._upload
        if up is None or up.asked_at_s < 0 or clock_s - up.asked_at_s < self.request_retry_s:
            return []
        return self._request(clock_s)

    # -- parameters --
    def _param_set(self, msg: Any) -> list[Any]:
        name = msg.param_id.rstrip("\x00") if isinstance(msg.param_id, str) else \
            bytes(msg.param_id).rstrip(b"\x00").decode()
        if name not in self.params:
            return []  # a parameter it does not have: no answer
        out: list[Any] = []
        if name in self.reject_params:
            if self.flavour == "ardupilot":
                out += _text(f"Param write denied ({name})", mavlink2.MAV_SEVERITY_WARNING)
        else:
            self.params[name] = self._decode(name, float(msg.param_value))
            self.param_log.append((name, self.params[name]))
        names = sorted(self.params)
        out.append(mavlink2.MAVLink_param_value_message(
            name.encode(), self._encode(name, self.params[name]), self._type(name),
            len(names), names.index(name)))
        return out

    def _type(self, name: str) -> int:
        return int(mavlink2.MAV_PARAM_TYPE_INT32 if name in self.int_params
                   else mavlink2.MAV_PARAM_TYPE_REAL32)

    def _encode(self, name: str, value: float) -> float:
        if self.flavour == "px4" and name in self.int_params:
            return float(struct.unpack("<f", struct.pack("<i", int(value)))[0])
        return value

    def _decode(self, name: str, wire: float) -> float:
        if self.flavour == "px4" and name in self.int_params:
            return float(struct.unpack("<i", struct.pack("<f", wire))[0])
        if name in self.int_params:
            return float(int(wire))
        return float(struct.unpack("<f", struct.pack("<f", wire))[0])

    # -- commands --
    def _command(self, msg: Any, clock_s: float) -> list[Any]:
        command = int(msg.command)
        if command == _ARM:
            if self.never_ack_arm:
                return []
            self.arm_attempts += 1
            if round(msg.param1) != 1:
                self.armed = False
                return [_ack(command, mavlink2.MAV_RESULT_ACCEPTED)]
            reason = self.prearm_reason if clock_s < self.prearm_ok_s else (
                None if self.prearm_check is None else self.prearm_check())
            if reason is not None:
                if self.flavour == "ardupilot":
                    return [*_text(f"PreArm: {reason}", mavlink2.MAV_SEVERITY_CRITICAL),
                            _ack(command, mavlink2.MAV_RESULT_FAILED)]
                return [*_text(f"Preflight Fail: {reason}",
                               mavlink2.MAV_SEVERITY_CRITICAL),
                        _ack(command, mavlink2.MAV_RESULT_TEMPORARILY_REJECTED)]
            if not self.armed:
                self.armed, self.armed_at_s = True, clock_s
            return [_ack(command, mavlink2.MAV_RESULT_ACCEPTED)]
        if command == _SET_MODE:
            if self.flavour == "px4":
                mode = int(msg.param2) << 16 | int(msg.param3) << 24
            else:
                mode = int(msg.param2)
            if self.valid_modes and mode not in self.valid_modes:
                return [_ack(command, mavlink2.MAV_RESULT_DENIED)]
            if not self.never_reach_mode and mode != self.custom_mode:
                self.custom_mode = mode
                self.mode_log.append((clock_s, mode))
            return [_ack(command, mavlink2.MAV_RESULT_ACCEPTED)]
        return [_ack(command, mavlink2.MAV_RESULT_UNSUPPORTED)]

    # -- the mission --
    def _request(self, clock_s: float) -> list[Any]:
        up = self._upload
        assert up is not None
        seq = up.next_seq
        up.asked_at_s = clock_s
        if seq == self.stall_request:
            up.asked_at_s = -1.0  # it never asks: the upload hangs
            return []
        if seq == self.drop_request and not up.dropped:
            up.dropped = True
            return []  # lost on the way; asked again after request_retry_s
        self.requests_sent.append(seq)
        cls = (mavlink2.MAVLink_mission_request_message if self.legacy_requests
               else mavlink2.MAVLink_mission_request_int_message)
        return [cls(255, 190, seq, int(mavlink2.MAV_MISSION_TYPE_MISSION))]

    def _item(self, msg: Any, clock_s: float) -> list[Any]:
        up = self._upload
        if up is None or int(msg.seq) != up.next_seq:
            return []  # not the item asked for: ignored, the request is repeated
        self._items[up.next_seq] = msg
        up.next_seq += 1
        if up.next_seq < up.count:
            return self._request(clock_s)
        self.mission = [self._items[i] for i in range(up.count)]
        self.mission_accepted = True
        self._upload = None
        return [mavlink2.MAVLink_mission_ack_message(
            255, 190, int(mavlink2.MAV_MISSION_ACCEPTED),
            int(mavlink2.MAV_MISSION_TYPE_MISSION))]


def _ack(command: int, result: int) -> Any:
    return mavlink2.MAVLink_command_ack_message(command, int(result))


_text_ids = iter(range(1, 1 << 16))


def _text(text: str, severity: int) -> list[Any]:
    """STATUSTEXT as both autopilots send it over MAVLink 2: one message of up to 50
    characters, or chunks of 50 with a common ``id`` and ``chunk_seq`` 0, 1, ... (the last
    shorter, or NUL-padded)."""
    raw = text.encode()
    if len(raw) <= 50:
        return [mavlink2.MAVLink_statustext_message(int(severity), raw)]
    text_id = next(_text_ids)
    return [mavlink2.MAVLink_statustext_message(int(severity), raw[i:i + 50], text_id, n)
            for n, i in enumerate(range(0, len(raw), 50))]
