"""The scenario drives the autopilot: a script of MAVLink commands run in order over its link.

A :class:`Script` says what a ground station operator would do; :class:`Commander` does it,
step by step, each confirmed by what the autopilot itself reports:

1. ``heartbeat``: wait for the autopilot's HEARTBEAT (its system and component are the target
   of everything after).
2. ``params``: PARAM_SET of every parameter of the file (a few in flight at once), each
   confirmed by the PARAM_VALUE the autopilot answers with its stored value: equal to the value
   set as a float32 (ArduPilot sends every value as a float; PX4's integer parameters travel
   byte-wise, the int32's bits in the float field, and are compared as integers). An answer
   with another value is a rejection; no answer after ``retry_s`` sends the PARAM_SET again.
3. ``mission``: the upload of :mod:`hil.autopilot.mission` (MISSION_COUNT,
   MISSION_REQUEST_INT / MISSION_REQUEST, MISSION_ITEM_INT, MISSION_ACK).
4. ``arm``: MAV_CMD_COMPONENT_ARM_DISARM (param1 = 1), repeated every ``arm_retry_s`` while
   the autopilot refuses (its pre-arm checks fail: ArduPilot answers FAILED, PX4
   TEMPORARILY_REJECTED / DENIED, each with STATUSTEXTs saying why) or does not answer; done
   when its HEARTBEAT says armed.
5. ``mode``: MAV_CMD_DO_SET_MODE (:func:`hil.autopilot.modes.set_mode_params`), repeated
   until its HEARTBEAT ``custom_mode`` is the mode asked for.

Steps the script does not ask for are skipped. Each step has its own timeout
(:class:`StepTimeouts`); a step that is not confirmed in time ends the script with one sentence
naming the step and what the autopilot last did (:attr:`Commander.failure`): a parameter named
with its file and line, the refused arming with the last STATUSTEXT the autopilot sent (its
pre-arm reason), the mode it reports instead.

Time and threads
    The commander is a state machine polled with the simulated time (:meth:`Commander.poll`,
    once per simulator step): it never blocks, so the lockstep loop keeps stepping while it
    waits. Timeouts count simulated seconds, the autopilot's own clock in lockstep, and at
    least ``wall_min_s`` wall seconds, so that a loaded machine answering late is not taken
    for an autopilot that never answers. The link belongs to the thread that reads it (the
    telemetry recorder, :meth:`hil.autopilot.telemetry.AutopilotTelemetry.attach`): it hands
    each received message to :meth:`Commander.deliver` and sends what
    :meth:`Commander.take_outgoing` returns; the two queues are the only shared state.
"""

from __future__ import annotations

import math
import struct
import time
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, Final

from hil.autopilot.mission import MissionItem, MissionUpload, mission_list
from hil.autopilot.modes import custom_mode, mode_name, set_mode_params
from hil.autopilot.param_file import PARAM_TYPE_REAL32, ParamValue
from hil.codec import mavlink2

__all__ = ["STEPS", "Commander", "Script", "StepRecord", "StepTimeouts"]

STEPS: Final = ("heartbeat", "params", "mission", "arm", "mode")
_HEARTBEAT: Final = int(mavlink2.MAVLINK_MSG_ID_HEARTBEAT)
_PARAM_VALUE: Final = int(mavlink2.MAVLINK_MSG_ID_PARAM_VALUE)
_COMMAND_ACK: Final = int(mavlink2.MAVLINK_MSG_ID_COMMAND_ACK)
_STATUSTEXT: Final = int(mavlink2.MAVLINK_MSG_ID_STATUSTEXT)
_ARM_CMD: Final = int(mavlink2.MAV_CMD_COMPONENT_ARM_DISARM)
_MODE_CMD: Final = int(mavlink2.MAV_CMD_DO_SET_MODE)
_ARMED: Final = int(mavlink2.MAV_MODE_FLAG_SAFETY_ARMED)
_ACCEPTED: Final = int(mavlink2.MAV_RESULT_ACCEPTED)
_IN_PROGRESS: Final = int(mavlink2.MAV_RESULT_IN_PROGRESS)
_NO_AUTOPILOT: Final = int(mavlink2.MAV_AUTOPILOT_INVALID)
_NAMES: Final = {"ardupilot": "ArduPilot", "px4": "PX4"}


@dataclass(frozen=True)
class StepTimeouts:
    """Simulated seconds each step may take (see the module docstring)."""

    heartbeat_s: float = 60.0
    params_s: float = 60.0
    mission_s: float = 60.0
    arm_s: float = 120.0
    mode_s: float = 30.0

    def of(self, step: str) -> float:
        return float(getattr(self, f"{step}_s"))


@dataclass(frozen=True)
class Script:
    """What the autopilot is told to do, in :data:`STEPS` order: ``params`` (from
    ``params_file``, named in messages), a ``mission``, ``arm``, a ``mode`` by name."""

    params: tuple[ParamValue, ...] = ()
    params_file: str | None = None
    mission: tuple[MissionItem, ...] = ()
    arm: bool = False
    mode: str | None = None
    timeouts: StepTimeouts = field(default_factory=StepTimeouts)
    aiding: bool = False
    """hilnav's estimate is sent as the autopilot's navigation (:mod:`hil.autopilot.aiding`;
    its parameters are among ``params``)."""
    aiding_off: bool = False
    """The autopilot flies unaided: the parameters that would take hilnav's estimate are set
    off (among ``params``)."""

    @property
    def empty(self) -> bool:
        """Nothing to command (no step besides waiting for the heartbeat)."""
        return not (self.params or self.mission or self.arm or self.mode)

    def asks(self, step: str) -> bool:
        return {"heartbeat": not self.empty, "params": bool(self.params),
                "mission": bool(self.mission), "arm": self.arm,
                "mode": self.mode is not None}[step]


@dataclass
class StepRecord:
    """One step and what became of it: ``status`` ``pending`` / ``running`` / ``done`` /
    ``failed`` / ``skipped``; simulated times it started and was confirmed."""

    name: str
    status: str = "pending"
    started_s: float | None = None
    done_s: float | None = None

    def as_dict(self) -> dict[str, Any]:
        return {"step": self.name, "status": self.status, "started_s": self.started_s,
                "done_s": self.done_s}


@dataclass
class _Sent:
    param: ParamValue
    at_s: float
    wall: float
    tries: int = 1


class Commander:
    """Runs a :class:`Script` against one autopilot (see the module docstring).

    Parameters
    ----------
    autopilot : ``"ardupilot"`` or ``"px4"``
    script : Script
    home : (lat deg, lon deg, alt MSL m)
        The scenario's start: ArduPilot's home slot of the mission.
    retry_s : float
        Simulated seconds without an answer before a message is sent again.
    arm_retry_s : float
        Simulated seconds between arming attempts while the autopilot refuses.
    wall_min_s : float
        Least wall seconds a step waits before it times out.
    retry_wall_s : float
        Least wall seconds before a PARAM_SET is sent again.
    param_window : int
        PARAM_SETs in flight at once.
    clock : callable
        Wall clock (monotonic seconds).
    """

    def __init__(self, autopilot: str, script: Script, home: tuple[float, float, float], *,
                 retry_s: float = 1.0, arm_retry_s: float = 2.0, wall_min_s: float = 2.0,
                 retry_wall_s: float = 0.2,
                 param_window: int = 8, clock: Callable[[], float] = time.monotonic) -> None:
        if autopilot not in _NAMES:
            raise ValueError(f"the commander drives ardupilot or px4, not {autopilot!r}")
        self.autopilot = autopilot
        self.name = _NAMES[autopilot]
        self.script = script
        self.home = home
        self.retry_s = retry_s
        self.arm_retry_s = arm_retry_s
        self.wall_min_s = wall_min_s
        self.retry_wall_s = retry_wall_s
        self.param_window = param_window
        self._clock = clock
        self.steps = [StepRecord(s) for s in STEPS]
        for record in self.steps:
            if not script.asks(record.name):
                record.status = "skipped"
        self.failure: str | None = None
        """The sentence that failed the script (None: none failed)."""
        self.armed_s: float | None = None
        """Simulated time the autopilot's HEARTBEAT first said armed."""
        self.mode_reached_s: float | None = None
        """Simulated time its HEARTBEAT first reported the scripted mode."""
        self._want_mode = None if script.mode is None else custom_mode(autopilot, script.mode)
        self._inbox: deque[Any] = deque()
        self._outbox: deque[Any] = deque()
        self._target: tuple[int, int] | None = None
        self._armed: bool | None = None
        self._custom_mode: int | None = None
        self._texts: deque[str] = deque(maxlen=20)
        self._chunks: dict[int, list[str]] = {}
        self._text_mark = 0  # texts heard before the running step began
        self._texts_heard = 0
        self._current = 0
        self._step_t0 = (0.0, 0.0)  # (simulated s, wall s) the running step began
        self._time_s = 0.0
        # step state
        self._to_send: deque[ParamValue] = deque()
        self._in_flight: dict[str, _Sent] = {}
        self.params_confirmed = 0
        self._upload: MissionUpload | None = None
        self._mission_sent: list[dict[str, Any]] | None = None
        """The list uploaded (seq, label, altitude MSL m): what MISSION_CURRENT's ``seq``
        names."""
        self._last_cmd_at = -math.inf
        self._cmd_tries = 0
        self._last_ack: int | None = None
        self._last_ack_cmd: int | None = None
        self.counters: dict[str, int] = dict.fromkeys(
            ("param_sets", "param_values", "mission_items_sent", "mission_legacy_requests",
             "commands_sent", "command_acks", "statustexts"), 0)

    # -- the thread boundary --
    def deliver(self, msg: Any) -> None:
        """A message received on the autopilot's link (any thread)."""
        self._inbox.append(msg)

    def take_outgoing(self) -> list[Any]:
        """Messages to send on the link now (any thread; each returned once)."""
        out = []
        while self._outbox:
            out.append(self._outbox.popleft())
        return out

    # -- state --
    @property
    def finished(self) -> bool:
        """Every step done or skipped, or one failed."""
        return self.failure is not None or self._current >= len(STEPS)

    @property
    def running_step(self) -> str | None:
        return None if self.finished else STEPS[self._current]

    @property
    def time_s(self) -> float:
        """The simulated time of the latest :meth:`poll`."""
        return self._time_s

    @property
    def custom_mode(self) -> int | None:
        """The autopilot's latest HEARTBEAT ``custom_mode`` (None: none heard)."""
        return self._custom_mode

    def report(self) -> dict[str, Any]:
        """Steps, times, the mission list sent (None: no mission step began) and counters for
        the scorecard."""
        return {"steps": [s.as_dict() for s in self.steps], "failure": self.failure,
                "armed_s": self.armed_s, "mode_reached_s": self.mode_reached_s,
                "mode": self.script.mode, "params_confirmed": self.params_confirmed,
                "mission": self._mission_sent, "counters": dict(self.counters)}

    def end(self, time_s: float) -> None:
        """The flight ended at ``time_s``: a step still waiting fails the script."""
        self.poll(time_s)
        if not self.finished:
            step = STEPS[self._current]
            self._fail(f"the flight ended at {time_s:.1f} s while {self.name} was still "
                       f"{_DOING[step]}{self._waiting(step)}")

    # -- the loop --
    def poll(self, time_s: float) -> None:
        """Handle what arrived, advance the running step; ``time_s`` simulated seconds."""
        self._time_s = time_s
        while self._inbox:
            self._on_message(self._inbox.popleft())
        while not self.finished:
            step = STEPS[self._current]
            record = self.steps[self._current]
            if record.status == "skipped":
                self._current += 1
                continue
            if record.status == "pending":
                self._begin(record)
            if getattr(self, f"_tick_{step}")():
                record.status, record.done_s = "done", time_s
                self._current += 1
                continue
            if self.failure is None and self._timed_out(step):
                self._fail(f"{self.name} did not {_GOAL[step]} within "
                           f"{self.script.timeouts.of(step):g} s{self._waiting(step)}")
            break

    def _begin(self, record: StepRecord) -> None:
        record.status, record.started_s = "running", self._time_s
        self._step_t0 = (self._time_s, self._clock())
        self._text_mark = self._texts_heard
        if record.name == "params":
            self._to_send = deque(self.script.params)
        elif record.name == "mission":
            assert self._target is not None
            items = mission_list(self.autopilot, self.script.mission, self.home)
            self._mission_sent = [{"seq": seq, "label": item.label,
                                   "alt_msl_m": item.alt_msl_m}
                                  for seq, item in enumerate(items)]
            self._upload = MissionUpload(items, self._target, retry_s=self.retry_s)
            self._upload.start(self._time_s)
            self._flush_upload()
        elif record.name in ("arm", "mode"):
            self._last_cmd_at, self._cmd_tries, self._last_ack = -math.inf, 0, None

    def _timed_out(self, step: str) -> bool:
        t0, wall0 = self._step_t0
        return (self._time_s - t0 >= self.script.timeouts.of(step)
                and self._clock() - wall0 >= self.wall_min_s)

    def _fail(self, sentence: str) -> None:
        self.failure = sentence
        self.steps[self._current].status = "failed"

    # -- receiving --
    def _on_message(self, msg: Any) -> None:
        msg_id = msg.get_msgId()
        source = (msg.get_srcSystem(), msg.get_srcComponent())
        if msg_id == _HEARTBEAT:
            if int(msg.autopilot) == _NO_AUTOPILOT:
                return
            if self._target is None:
                self._target = source
            if source != self._target:
                return
            self._armed = bool(int(msg.base_mode) & _ARMED)
            self._custom_mode = int(msg.custom_mode)
            if self._armed and self.armed_s is None:
                self.armed_s = self._time_s
            if (self._want_mode is not None and self._custom_mode == self._want_mode
                    and self._armed and self.mode_reached_s is None
                    and self.running_step in (None, "mode")):
                self.mode_reached_s = self._time_s
            return
        if self._target is not None and source != self._target:
            return
        if msg_id == _STATUSTEXT:
            self._on_text(msg)
        elif msg_id == _PARAM_VALUE:
            self.counters["param_values"] += 1
            self._on_param_value(msg)
        elif msg_id == _COMMAND_ACK:
            self.counters["command_acks"] += 1
            self._last_ack_cmd, self._last_ack = int(msg.command), int(msg.result)
        elif self._upload is not None:
            self._upload.on_message(msg, self._time_s)
            self._flush_upload()

    def _on_text(self, msg: Any) -> None:
        raw = msg.text if isinstance(msg.text, str) else bytes(msg.text).decode(
            "utf-8", "replace")
        text = raw.split("\x00", 1)[0]
        text_id = int(getattr(msg, "id", 0) or 0)
        if text_id:
            parts = self._chunks.setdefault(text_id, [])
            parts.append(text)
            if len(text) >= 50 and "\x00" not in raw:
                return  # more chunks follow
            text = "".join(self._chunks.pop(text_id))
        self._texts.append(text)
        self._texts_heard += 1
        self.counters["statustexts"] += 1

    def _last_text(self) -> str | None:
        """The autopilot's latest STATUSTEXT since the running step began."""
        if self._texts_heard <= self._text_mark or not self._texts:
            return None
        return self._texts[-1]

    # -- the steps: True when confirmed --
    def _tick_heartbeat(self) -> bool:
        return self._target is not None

    def _tick_params(self) -> bool:
        now_wall = self._clock()
        for sent in self._in_flight.values():
            if (self._time_s - sent.at_s >= self.retry_s
                    and now_wall - sent.wall >= self.retry_wall_s):
                sent.at_s, sent.wall, sent.tries = self._time_s, now_wall, sent.tries + 1
                self._send_param(sent.param)
        while self._to_send and len(self._in_flight) < self.param_window:
            p = self._to_send.popleft()
            self._in_flight[p.name] = _Sent(p, self._time_s, now_wall)
            self._send_param(p)
        return self.failure is None and not self._to_send and not self._in_flight

    def _send_param(self, p: ParamValue) -> None:
        assert self._target is not None
        self.counters["param_sets"] += 1
        self._outbox.append(mavlink2.MAVLink_param_set_message(
            self._target[0], self._target[1], p.name.encode("ascii"),
            _wire_value(self.autopilot, p), p.param_type))

    def _on_param_value(self, msg: Any) -> None:
        name = msg.param_id if isinstance(msg.param_id, str) else bytes(msg.param_id).decode(
            "ascii", "replace")
        sent = self._in_flight.pop(name.rstrip("\x00"), None)
        if sent is None or self.failure is not None:
            return  # not ours, or answered twice
        p = sent.param
        got = _value_of(self.autopilot, p.param_type, float(msg.param_value))
        if _same(p.value, got):
            self.params_confirmed += 1
            return
        said = self._last_text()
        self._fail(f"{self.name} rejected parameter {p.name} = {p.value:g}"
                   f"{self._where(p)}: it answered {got:g}"
                   + (f" and said {said!r}" if said else ""))

    def _where(self, p: ParamValue) -> str:
        if p.line == 0:
            return (" (set for aiding: hilnav)" if self.script.aiding
                    else " (set for aiding: disabled)" if self.script.aiding_off else "")
        if self.script.params_file is None:
            return ""
        return f" ({self.script.params_file}:{p.line})" if p.line else \
            f" ({self.script.params_file})"

    def _tick_mission(self) -> bool:
        upload = self._upload
        assert upload is not None
        upload.tick(self._time_s)
        self._flush_upload()
        if upload.error is not None:
            self._fail(f"{self.name} did not take the mission: {upload.error}")
            return False
        return upload.done

    def _flush_upload(self) -> None:
        if self._upload is None:
            return
        for msg in self._upload.outgoing():
            if msg.get_msgId() == int(mavlink2.MAVLINK_MSG_ID_MISSION_ITEM_INT):
                self.counters["mission_items_sent"] += 1
            self._outbox.append(msg)
        self.counters["mission_legacy_requests"] = self._upload.legacy_requests

    def _tick_arm(self) -> bool:
        if self._armed:
            return True
        refused = self._last_ack is not None and self._last_ack not in (_ACCEPTED, _IN_PROGRESS)
        wait = self.arm_retry_s if refused or self._cmd_tries == 0 else self.retry_s
        if self._cmd_tries == 0 or self._time_s - self._last_cmd_at >= wait:
            self._command(_ARM_CMD, (1.0, 0.0, 0.0))
        return False

    def _tick_mode(self) -> bool:
        assert self._want_mode is not None
        if self._custom_mode == self._want_mode:
            if self.mode_reached_s is None:
                self.mode_reached_s = self._time_s
            return True
        if self._cmd_tries == 0 or self._time_s - self._last_cmd_at >= self.retry_s:
            self._command(_MODE_CMD, set_mode_params(self.autopilot, self._want_mode))
        return False

    def _command(self, command: int, params: Sequence[float]) -> None:
        assert self._target is not None
        p = [*params, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0][:7]
        self._outbox.append(mavlink2.MAVLink_command_long_message(
            self._target[0], self._target[1], command, min(self._cmd_tries, 255), *p))
        self._cmd_tries += 1
        self._last_cmd_at = self._time_s
        self.counters["commands_sent"] += 1

    # -- sentences --
    def _waiting(self, step: str) -> str:
        """``: <what the autopilot last did>`` for a step's failure sentence."""
        said = self._last_text()
        text = f"; its last message: {said!r}" if said else ""
        if step == "heartbeat":
            return ": no HEARTBEAT came on its link"
        if step == "params":
            if not self._in_flight and self._to_send:
                return f": {len(self._to_send)} parameters not sent{text}"
            missing = next(iter(self._in_flight.values()), None)
            if missing is None:
                return text
            return (f": parameter {missing.param.name}{self._where(missing.param)} was never "
                    f"echoed back ({missing.tries} PARAM_SET sent){text}")
        if step == "mission":
            return f": {self._upload.waiting_for() if self._upload else 'not started'}{text}"
        ack = self._ack_words()
        if step == "arm":
            return f": {ack}{text}"
        now = ("no mode reported" if self._custom_mode is None
               else f"it reports {mode_name(self.autopilot, self._custom_mode)}")
        return f" ({now}): {ack}{text}"

    def _ack_words(self) -> str:
        if self._last_ack is None:
            return f"no COMMAND_ACK to {self._cmd_tries} commands"
        entry = mavlink2.enums.get("MAV_RESULT", {}).get(self._last_ack)
        name = entry.name if entry is not None else str(self._last_ack)
        return f"last COMMAND_ACK {name} after {self._cmd_tries} commands"


_GOAL: Final = {"heartbeat": "send a HEARTBEAT", "params": "confirm its parameters",
                "mission": "take the mission", "arm": "arm", "mode": "reach the mode"}
_DOING: Final = {"heartbeat": "silent", "params": "confirming parameters",
                 "mission": "taking the mission", "arm": "not armed",
                 "mode": "not in the scripted mode"}


def _bytewise(autopilot: str, param_type: int) -> bool:
    """PX4 sends integer parameters byte-wise (the int32's bits in the float field)."""
    return autopilot == "px4" and param_type != PARAM_TYPE_REAL32 and param_type <= 8


def _wire_value(autopilot: str, p: ParamValue) -> float:
    if _bytewise(autopilot, p.param_type):
        return float(struct.unpack("<f", struct.pack("<i", round(p.value)))[0])
    return p.value


def _value_of(autopilot: str, param_type: int, wire: float) -> float:
    if _bytewise(autopilot, param_type):
        return float(struct.unpack("<i", struct.pack("<f", wire))[0])
    return wire


def _float32(x: float) -> float:
    return float(struct.unpack("<f", struct.pack("<f", x))[0])


def _same(wanted: float, got: float) -> bool:
    """Whether the autopilot stored ``wanted``: equal once both are float32, within the
    float32 rounding of a value that went through another unit or type on the way."""
    return math.isclose(_float32(wanted), _float32(got), rel_tol=1e-6, abs_tol=1e-12)
