"""PX4 in the loop: the simulator side of PX4's simulator MAVLink interface.

What PX4 does (``src/modules/simulation/simulator_mavlink/SimulatorMavlink.cpp``)
    * SITL: PX4 is the TCP *client*; it dials the simulator (port 4560, host
      ``PX4_SIM_HOSTNAME`` or localhost), retrying until accepted, with ``TCP_NODELAY``. So the
      simulator listens: ``tcpin:127.0.0.1:4560`` (``tcpin:0.0.0.0:4560`` for a PX4 on another
      machine). HITL: the board's USB serial port (``serial:/dev/ttyACM0:921600``).
    * After connecting, PX4 sends one HEARTBEAT (``autopilot`` = 12, PX4) and a COMMAND_LONG
      asking for HIL_STATE_QUATERNION every 5 ms (ground truth, only logged), then one
      HIL_ACTUATOR_CONTROLS each time its mixer publishes outputs: ``controls[i]`` = output
      ``i`` (``PWM_MAIN_FUNC{i+1}`` in SITL; motors 0..1, servos -1..1), all zero while
      disarmed; ``mode`` has ``MAV_MODE_FLAG_SAFETY_ARMED`` (128) when armed; ``flags`` bit 0
      is set by a lockstep build.
    * HIL_SENSOR with ``id`` 0 sets PX4's clock to its ``time_usec`` and advances its lockstep
      scheduler; the fields are taken per ``fields_updated`` group (accel bits 0-2, gyro 3-5,
      mag 6-8 in gauss, baro = bits 9, 11, 12 with ``abs_pressure`` hPa and ``temperature``,
      ``diff_pressure`` bit 10 in hPa). HIL_GPS: lat/lon degE7, alt mm, ``eph``/``epv`` cm,
      vel/vn/ve/vd cm/s, cog cdeg, fix type, satellites, ``id`` (one GPS instance per id).
      hilnav's HIL_SENSOR / HIL_GPS are these (``hil.codec.encoder``): no frame change was
      needed. HIL_STATE_QUATERNION is PX4's ground truth (logged, never fused).

The lockstep exchange (``fly_with_autopilot(speed=None)``)
    PX4's clock only moves when HIL_SENSOR arrives, so PX4 cannot send controls before it has
    been fed. Until PX4's first HIL_ACTUATOR_CONTROLS on a connection (its boot), the
    simulator flies the trim and steps at real time (as Gazebo's PX4 plugin runs its world
    before the first actuator message); from then on every step waits for PX4's next
    HIL_ACTUATOR_CONTROLS: the simulator never runs ahead of PX4. No controls for the stall
    timeout (boot included) ends the run as stalled. Paced (HITL, ``speed=1``): the newest
    controls are flown each step.

    While PX4 reports itself disarmed its controls are all zero; since our aircraft starts in
    the air, the backend then holds the trim (:class:`hil.autopilot.arming.TrimHold`,
    ``hold_trim_disarmed``, counted in ``disarmed_controls``) until PX4 is armed (the
    ``mode`` of its HIL_ACTUATOR_CONTROLS); :attr:`Px4Backend.trim_released_s` is the simulated
    time it first was.

Reconnects and bad input
    A PX4 that restarts connects again: the new connection replaces the old one (counted in
    ``reconnects``) and boots as above; in lockstep the simulator holds meanwhile (the stall
    timeout bounds the wait). Non-finite channel values are counted (``nonfinite_channels``)
    and reach the flight as non-finite controls, which it ignores and counts. A peer that
    speaks another protocol (an ArduPilot SITL servo packet, any non-MAVLink-2 byte stream,
    an ArduPilot HEARTBEAT) raises :class:`WrongProtocol`: one line naming what was expected.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Sequence
from typing import Any, Final

from hil.autopilot.actuators import ActuatorMap
from hil.autopilot.arming import TrimHold
from hil.codec import SENSOR_COMPONENT_ID, SIM_SYSTEM_ID, mavlink2
from hil.codec.wire import frame_msg_id
from hil.link import LinkRole, MavlinkLink
from hil.pipeline import SimStep
from hil.signing import Signer

__all__ = ["DEFAULT_PX4_URL", "Px4Backend", "WrongProtocol"]

DEFAULT_PX4_URL: Final = "tcpin:127.0.0.1:4560"
"""Where PX4 SITL's simulator_mavlink connects by default (TCP port 4560, localhost)."""

_CONTROLS_ID: Final = int(mavlink2.MAVLINK_MSG_ID_HIL_ACTUATOR_CONTROLS)
_COMMAND_LONG_ID: Final = int(mavlink2.MAVLINK_MSG_ID_COMMAND_LONG)
_TO_PX4: Final = frozenset({
    int(mavlink2.MAVLINK_MSG_ID_HIL_SENSOR),
    int(mavlink2.MAVLINK_MSG_ID_HIL_GPS),
    int(mavlink2.MAVLINK_MSG_ID_HIL_STATE_QUATERNION),
    int(mavlink2.MAVLINK_MSG_ID_RAW_RPM),
})
"""Frames of a step PX4 is sent; our own HIL_ACTUATOR_CONTROLS report (what the flight flew,
for the log and the fusion) is not."""
_ARMED: Final = int(mavlink2.MAV_MODE_FLAG_SAFETY_ARMED)
_LOCKSTEP_FLAG: Final = 1
_ARDUPILOT: Final = int(mavlink2.MAV_AUTOPILOT_ARDUPILOTMEGA)
_ARDUPILOT_SERVO_MAGICS: Final = {18458: "16", 29569: "32"}
_NO_FRAME_BYTES: Final = 280  # the longest MAVLink 2 frame: this much without one is not MAVLink
_EXPECTED: Final = ("expected PX4's simulator interface (MAVLink 2 HEARTBEAT and "
                    "HIL_ACTUATOR_CONTROLS from PX4's simulator_mavlink)")


class WrongProtocol(ValueError):
    """The peer speaks another protocol than PX4's simulator interface (one line)."""


class Px4Backend:
    """The simulator side of PX4's simulator MAVLink interface (see the module docstring).

    Parameters
    ----------
    url : str
        ``tcpin:HOST:PORT`` (SITL; PX4 connects) or ``serial:DEVICE:BAUD`` (HITL).
    actuator_map : ActuatorMap, optional
        HIL_ACTUATOR_CONTROLS channels -> aircraft controls (default: the legacy HIL order).
    signer : hil.signing.Signer, optional
        MAVLink 2 signing on the link (PX4's simulator interface does not sign: SITL leaves it
        off).
    hold_trim_disarmed : bool
        Fly the trim while PX4 reports itself disarmed (its controls are then all zero).

    Raises
    ------
    ValueError
        Bad URL, a port that cannot be bound, a serial device that cannot be opened.
    """

    name = "PX4"

    def __init__(self, url: str = DEFAULT_PX4_URL, *, actuator_map: ActuatorMap | None = None,
                 signer: Signer | None = None, hold_trim_disarmed: bool = True) -> None:
        self.actuator_map = actuator_map or ActuatorMap.default()
        self.trim_hold = TrimHold(enabled=hold_trim_disarmed)
        role = LinkRole(
            system_id=SIM_SYSTEM_ID, component_id=SENSOR_COMPONENT_ID,
            mav_type=mavlink2.MAV_TYPE_GENERIC, autopilot=mavlink2.MAV_AUTOPILOT_INVALID,
            accept_msg_ids=frozenset({_CONTROLS_ID, _COMMAND_LONG_ID}),
            lock_to_first_source=False,  # a restarted PX4 may come back with another id
        )
        self.link = MavlinkLink(url, role, signer=signer)
        self.url = str(self.link.url)
        self._connects_seen = 0
        self._booted = False  # PX4 sent controls on this connection
        self._pending: Any = None  # the newest HIL_ACTUATOR_CONTROLS not yet flown
        self._boot_wall0 = 0.0
        self._last_send_wall = 0.0
        self._step_wall_s = 0.0
        self._last_step_us: int | None = None
        self._base = self._prev = self.link.counters()
        self._protocol_ok = False
        self._c = {"controls": 0, "lockstep_controls": 0, "disarmed_controls": 0,
                   "nonfinite_channels": 0, "reconnects": 0, "steps_sent": 0,
                   "frames_sent": 0, "boot_steps": 0, "interval_requests": 0}

    # -- the AutopilotBackend protocol --
    def wait_connected(self, timeout_s: float, stop: threading.Event) -> bool:
        """Until PX4 has connected and sent its first message (a HEARTBEAT)."""
        deadline = time.monotonic() + timeout_s
        while not stop.is_set():
            if self._pump(min(0.05, max(0.0, deadline - time.monotonic()))):
                self._boot_wall0 = time.monotonic()
                return True
            if time.monotonic() >= deadline:
                return False
        return False

    def controls(self, timeout_s: float) -> Sequence[float] | None:
        """PX4's next controls through the actuator map (see the module docstring)."""
        now = time.monotonic()
        deadline = now + timeout_s
        while True:
            self._pump(0.0)
            if self._pending is not None:
                return self._take()
            now = time.monotonic()
            if timeout_s == 0.0:
                return None  # paced: the loop holds the last controls and times the stall
            if not self._booted and self._connected():
                if now - self._boot_wall0 > timeout_s:
                    return None  # PX4 never started sending controls
                due = self._last_send_wall + self._step_wall_s
                if now >= due:
                    self._c["boot_steps"] += 1
                    return []  # PX4 boots on our sensors: hold the trim, real-time paced
                self._pump(min(due, deadline) - now)
                continue
            if now >= deadline:
                return None
            self._pump(min(0.05, deadline - now))

    def send(self, step: SimStep) -> None:
        """The step's HIL_SENSOR, HIL_GPS, HIL_STATE_QUATERNION and RAW_RPM frames."""
        link = self.link
        n = 0
        for _t, frame in step.frames:
            if frame_msg_id(frame) in _TO_PX4:
                link.send(frame)
                n += 1
        self._c["steps_sent"] += 1
        self._c["frames_sent"] += n
        now = time.monotonic()
        t_us = step.truth.time_us
        if self._last_step_us is not None:
            self._step_wall_s = (t_us - self._last_step_us) * 1e-6
        self._last_step_us = t_us
        self._last_send_wall = now

    def counters(self) -> dict[str, int]:
        """Protocol counters and the link's (bytes, frames, drops, connections)."""
        link = self.link.counters()
        out = dict(self._c)
        out["disarmed_controls"] = self.trim_hold.held
        for key in ("bytes_received", "bytes_sent", "garbage_bytes", "dropped", "accepted",
                    "sent", "connects", "disconnects", "tx_buffer_full"):
            out[f"link_{key}"] = link[key]
        return out

    @property
    def trim_released_s(self) -> float | None:
        """Simulated time (s) PX4 first reported itself armed (the trim hold ended)."""
        return self.trim_hold.released_s

    # -- lifetime --
    def close(self) -> None:
        """Close the link (idempotent)."""
        self.link.close()

    def __enter__(self) -> Px4Backend:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    @property
    def local_address(self) -> Any:
        """(host, port) the ``tcpin`` link listens on (port 0 in the URL: a free port)."""
        return self.link.local_address

    # -- internals --
    def _connected(self) -> bool:
        c = self.link.counters()
        return c["connects"] > c["disconnects"]

    def _pump(self, timeout_s: float) -> bool:
        """Receive for up to ``timeout_s``; True when something was accepted."""
        msgs = self.link.recv(max(0.0, timeout_s))
        self._check_connection()
        for msg in msgs:
            msg_id = msg.get_msgId()
            if msg_id == _CONTROLS_ID:
                self._pending = msg
            elif msg_id == _COMMAND_LONG_ID:
                self._c["interval_requests"] += 1
            elif int(msg.autopilot) == _ARDUPILOT:
                raise WrongProtocol(
                    f"{self.url}: an ArduPilot MAVLink HEARTBEAT arrived; {_EXPECTED}. "
                    "ArduPilot SITL speaks the JSON interface: use --ardupilot")
        return bool(msgs)

    def _check_connection(self) -> None:
        c = self.link.counters()
        if c["connects"] != self._connects_seen:
            if self._connects_seen > 0:
                self._c["reconnects"] += c["connects"] - self._connects_seen
            self._connects_seen = c["connects"]
            self._booted = False
            self._pending = None
            self._boot_wall0 = time.monotonic()
            # what came before this receive belongs to the old connection
            self._base, self._protocol_ok = self._prev, False
        self._prev = c
        if not self._protocol_ok:
            self._check_protocol(c)

    def _check_protocol(self, c: dict[str, int]) -> None:
        frames = c["received"] - self._base["received"]
        v1 = c["mavlink1"] - self._base["mavlink1"]
        if frames > v1:
            self._protocol_ok = True  # MAVLink 2 frames came on this connection
            return
        first = self.link.first_bytes
        magic = int.from_bytes(first[:2], "little") if len(first) >= 2 else -1
        if magic in _ARDUPILOT_SERVO_MAGICS:
            raise WrongProtocol(
                f"{self.url}: got an ArduPilot SITL {_ARDUPILOT_SERVO_MAGICS[magic]}-channel "
                f"servo packet (magic {magic}); {_EXPECTED}. For ArduPilot use --ardupilot")
        got = c["bytes_received"] - self._base["bytes_received"]
        if got < _NO_FRAME_BYTES:
            return
        if v1 > 0:
            raise WrongProtocol(f"{self.url}: got MAVLink 1 frames only; {_EXPECTED}")
        raise WrongProtocol(
            f"{self.url}: got {got} bytes without a MAVLink frame (first bytes "
            f"{first.hex(' ')}); {_EXPECTED}")

    def _take(self) -> list[float]:
        msg, self._pending = self._pending, None
        self._c["controls"] += 1
        self._booted = True
        if int(msg.flags) & _LOCKSTEP_FLAG:
            self._c["lockstep_controls"] += 1
        raw = [float(x) for x in msg.controls]
        bad = sum(1 for x in raw if not math.isfinite(x))
        self._c["nonfinite_channels"] += bad
        armed = bool(int(msg.mode) & _ARMED)
        return list(self.trim_hold.apply(self.actuator_map.apply(raw), armed,
                                         self._last_step_us or 0))
