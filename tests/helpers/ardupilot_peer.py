"""A peer that plays ArduPilot SITL's side of the JSON physics interface, for tests and benches.

Written from ArduPilot's ``libraries/SITL/SIM_JSON.cpp`` (``output_servos``, ``recv_fdm``,
``parse_sensors``), ``libraries/SITL/SIM_GPS.cpp`` (``GPS::update``) and
``libraries/SITL/examples/JSON/readme.md`` (read, not copied). What it does as ArduPilot does:

* sends one binary servo packet per frame (16 or 32 outputs, magic 18458 / 29569, frame count
  +1 per answered frame) and waits for the JSON line; without an answer within
  ``resend_s`` it sends the same packet again without counting up (ArduPilot: after 1 s);
* reads the line the way SIM_JSON does (``strstr`` for each key, the value right after
  ``"key":``, vectors ``[x,y,z]``; a line without a mandatory field is dropped);
* its clock is the JSON ``timestamp`` (``time_boot_ms`` of its telemetry = timestamp x 1000);
* simulates its own sensors from the JSON state: barometer = the position's altitude
  (+ ``SIM_BARO_GLITCH``), compass = the attitude's heading, airspeed = the ``airspeed``
  field, GPS at ``SIM_GPS1_HZ`` with ``SIM_GPS1_LAG_MS`` of delay, lock only while
  ``SIM_GPS1_ENABLE`` = 1 and ``SIM_GPS1_JAM`` = 0 (its jamming model simplified to no lock),
  ``SIM_GPS1_GLTCH_X/Y/Z`` added to latitude (deg), longitude (deg) and altitude (m);
* serves a MAVLink port (``tcpin``, like SITL's 5760): PARAM_SET of a parameter it has sets it
  and is answered with PARAM_VALUE; unknown names get no answer (as ArduPilot).

Its autopilot is simple but real, working from ITS OWN estimate, never the truth:
complementary-filter attitude (gyro integration, corrected by gravity from the accelerometer
minus the turn's centripetal term, and by the compass heading), baro altitude and climb rate,
position from its GPS, dead-reckoned through an outage with the last GPS velocity turned by
the heading change since. It holds the start altitude and airspeed and flies the headings of
its plan (a bank of at most 25 degrees), through the servo outputs of a
:class:`hil.autopilot.ServoMap` (PX4 signs: PWM above trim = roll right / nose up).

Booting: for ``disarmed_s`` of its clock it is disarmed, as ArduPlane booting in MANUAL: its
outputs are neutral (surfaces at their PWM trim, throttle at its minimum) and its HEARTBEATs
(on its MAVLink port and its telemetry, each telemetry period) have no armed flag and
``custom_mode`` 0 (MANUAL); then it arms and flies in CRUISE (7), as an operator at a console
would leave it. Given ``commands`` (:class:`tests.helpers.autopilot_commands.CommandSide`) it
never arms by itself: the ground station's PARAM_SET, COMMAND_LONG and mission messages on its
telemetry link are answered there, and it flies only while armed in a mode other than MANUAL
(MANUAL with nobody at the sticks is neutral surfaces). Its GPS has no fix before
``fix_after_s`` of its clock; until its first fix its GLOBAL_POSITION_INT says lat/lon 0/0
at -1000 m (ArduPilot before its EKF has an origin) and its EKF_STATUS_REPORT has no absolute
position.

Its estimate goes out as telemetry on ``telemetry_url`` (a ``udpout`` MAVLink link, as SITL's
``--out``): GLOBAL_POSITION_INT, ATTITUDE and EKF_STATUS_REPORT at ``telemetry_hz`` of its
clock, system 1, component 1, ArduPilot's HEARTBEAT.
"""

from __future__ import annotations

import math
import re
import socket
import threading
import time
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

from hil.autopilot.servos import ServoMap
from hil.autopilot.sitl_json import LATLON_TO_M, encode_servo_packet
from hil.codec import mavlink2
from hil.link import LinkRole, MavlinkLink
from hil.pipeline import SimSetup
from sim.faults.ardupilot import ARDUPILOT_DEFAULTS
from sim.flight import Flight
from tests.helpers.autopilot_commands import CommandSide

__all__ = ["ArduPilotPeer", "PeerPlan", "parse_sim_json", "trimmed_controls"]

_ARMED = int(mavlink2.MAV_MODE_FLAG_SAFETY_ARMED)
_MANUAL, _CRUISE = 0, 7  # ArduPlane's mode numbers
_FROM_GCS = frozenset(int(getattr(mavlink2, f"MAVLINK_MSG_ID_{name}")) for name in (
    "PARAM_SET", "COMMAND_LONG", "MISSION_COUNT", "MISSION_ITEM_INT", "MISSION_ITEM",
    "GPS_INPUT"))

# SIM_JSON's key table: (section, key, number of values, required)
_KEYS = (
    ("", "timestamp", 1, True),
    ("imu", "gyro", 3, True),
    ("imu", "accel_body", 3, True),
    ("", "position", 3, True),
    ("", "attitude", 3, False),
    ("", "quaternion", 4, False),
    ("", "velocity", 3, True),
    ("", "airspeed", 1, False),
)
_NUMBER = re.compile(r"\s*([-+]?(?:\d+\.?\d*(?:[eE][-+]?\d+)?|\.\d+(?:[eE][-+]?\d+)?|nan|inf))")


def parse_sim_json(line: str) -> dict[str, tuple[float, ...]] | None:
    """The fields of one state line as SIM_JSON's parser reads them, or None when a mandatory
    field is missing or unreadable (ArduPilot drops such a line)."""
    out: dict[str, tuple[float, ...]] = {}
    for section, key, n, required in _KEYS:
        p = line.find(section)
        if p < 0:
            if required:
                return None
            continue
        p = line.find(key, p + len(section) + 1)
        if p < 0:
            if required:
                return None
            continue
        p += len(key) + 2
        values: list[float] = []
        if n > 1:
            if line[p:p + 1] != "[":
                return None
            p += 1
        for i in range(n):
            m = _NUMBER.match(line, p)
            if m is None:
                return None
            values.append(float(m.group(1)))
            p = m.end()
            if n > 1:
                sep = "]" if i == n - 1 else ","
                rest = line[p:].lstrip()
                if not rest.startswith(sep):
                    return None
                p = len(line) - len(rest) + 1
        out[key] = tuple(values)
    if "attitude" not in out and "quaternion" not in out:
        return None
    return out


def trimmed_controls(setup: SimSetup) -> tuple[float, ...]:
    """The controls (PX4 order: roll, pitch, yaw, throttle) the aircraft of ``setup`` starts
    trimmed with: a tuned ArduPlane's servo trims for the peer's ``trim``."""
    with Flight(setup.flight.model_copy(update={"control": "external"}), setup.plan) as f:
        return f.vehicle_state().controls[:4]


@dataclass(frozen=True)
class PeerPlan:
    """What the peer's autopilot flies: ``headings`` = ((from_s, heading_deg), ...) on its
    clock (the first entry None-like: its start heading until the first time), holding the
    start altitude + ``climb_m`` and the start airspeed."""

    headings: tuple[tuple[float, float], ...] = ()
    climb_m: float = 0.0


@dataclass
class _Gps:
    """The peer's simulated GPS (SIM_GPS1_* parameters, as SIM_GPS.cpp)."""

    params: dict[str, float]
    history: deque[tuple[float, tuple[float, float, float], tuple[float, float, float]]] = \
        field(default_factory=lambda: deque(maxlen=200))
    last_fix_s: float = -math.inf

    def fix(self, t_s: float, lat_deg: float, lon_deg: float, alt_m: float,
            v_ned: tuple[float, float, float]) -> tuple[float, float, float,
                                                          tuple[float, float, float]] | None:
        """A fix when one is due at ``t_s`` and the GPS has lock, else None."""
        p = self.params
        self.history.append((t_s, (lat_deg, lon_deg, alt_m), v_ned))
        if t_s - self.last_fix_s < 1.0 / max(p["SIM_GPS1_HZ"], 1.0) - 1e-9:
            return None
        self.last_fix_s = t_s
        if p["SIM_GPS1_ENABLE"] < 0.5 or p["SIM_GPS1_JAM"] >= 0.5:
            return None
        lag_s = p["SIM_GPS1_LAG_MS"] * 1e-3
        sample = self.history[0]
        for entry in reversed(self.history):
            if t_s - entry[0] >= lag_s:
                sample = entry
                break
        (lat, lon, alt), vel = sample[1], sample[2]
        return (lat + p["SIM_GPS1_GLTCH_X"], lon + p["SIM_GPS1_GLTCH_Y"],
                alt + p["SIM_GPS1_GLTCH_Z"], vel)


class ArduPilotPeer:
    """ArduPilot SITL's side of the JSON interface (see the module docstring).

    Parameters
    ----------
    sim_url : str, optional
        The JSON backend: ``udp:HOST:PORT`` (or given to :meth:`start`).
    telemetry_url : str, optional
        Where the estimate goes (``udpout:HOST:PORT``).
    plan : PeerPlan
    home : (lat_deg, lon_deg, alt_msl_m)
        ArduPilot's home (the JSON origin).
    trim : sequence of float
        Its servo trims as controls in PX4 order (roll, pitch, yaw, throttle): the outputs of
        its first frame and the start of its integrators (a tuned ArduPlane's trims).
    channels : int
        16 or 32 outputs per packet (SERVO_32_ENABLE).
    mavlink : bool
        Serve a MAVLink port (``mavlink_listen``, default ``tcpin`` on a free port:
        :attr:`mavlink_url`).
    frame_rate_hz : int
        SIM_RATE_HZ sent in the packets.
    resend_s : float
        Resend the packet after this long without an answer (ArduPilot: 1 s).
    silent_after : int, optional
        Stop sending after this many answered frames (a hung autopilot), until :meth:`stop`.
    disarmed_s : float
        Booting disarmed for this long (its clock): neutral outputs, no armed flag.
    fix_after_s : float
        No GPS fix before this time (its clock); lat/lon 0/0 in its telemetry until one.
    """

    def __init__(
        self,
        sim_url: str | None = None,
        telemetry_url: str | None = None,
        *,
        plan: PeerPlan | None = None,
        home: tuple[float, float, float] = (47.0, 8.0, 0.0),
        trim: Sequence[float] = (0.0, 0.0, 0.0, 0.6),
        channels: int = 16,
        mavlink: bool = False,
        servo_map: ServoMap | None = None,
        frame_rate_hz: int = 400,
        resend_s: float = 1.0,
        telemetry_hz: float = 10.0,
        silent_after: int | None = None,
        disarmed_s: float = 0.0,
        fix_after_s: float = 0.0,
        commands: CommandSide | None = None,
        mavlink_listen: str = "tcpin:127.0.0.1:0",
    ) -> None:
        self.commands = commands
        self.custom_mode = _MANUAL
        self._gps2_fixed = False  # a GPS_INPUT for its second GPS with a 3-D fix came in
        if commands is not None:
            disarmed_s = float("inf")  # it arms when told to, never by itself
            if commands.prearm_check is None:
                commands.prearm_check = self._gps2_prearm
        self.disarmed_s = disarmed_s
        self.fix_after_s = fix_after_s
        self.armed_at_s: float | None = None
        """Its clock when it armed."""
        self._sim_address = _udp_address(sim_url) if sim_url is not None else None
        self.plan = plan or PeerPlan()
        self.home = home
        self.trim = [*trim, *([0.0] * (4 - len(trim)))][:4]
        self.channels = channels
        self.servo_map = servo_map or ServoMap.default()
        self.frame_rate_hz = frame_rate_hz
        self.resend_s = resend_s
        self.telemetry_period_s = 1.0 / telemetry_hz
        self.silent_after = silent_after
        self.params: dict[str, float] = dict(ARDUPILOT_DEFAULTS)
        self.param_log: list[tuple[float, str, float]] = []
        self.fix_times: list[float] = []
        """Its clock at each GPS fix it used."""
        self.counters = dict.fromkeys(
            ("frames", "resends", "lines", "bad_lines", "fixes", "params_set",
             "params_unknown", "telemetry", "gps_input_fixes",
             "gps_input_other_id"), 0)
        self._gps_input: Any = None
        self.estimate: dict[str, float] = {}
        self.track: list[tuple[float, float, float, float, float]] = []
        """(t_s, estimated north m, east m, alt m, heading rad) each second of its clock."""
        self.truth_track: list[tuple[float, float, float, float]] = []
        """(t_s, JSON north m, east m, alt m) each second (for the tests' error checks)."""
        self._gps = _Gps(self.params)
        self._sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self._sock.settimeout(0.05)
        self._mav = MavlinkLink(mavlink_listen, self._role()) if mavlink else None
        self._tel = MavlinkLink(telemetry_url, self._role()) if telemetry_url else None
        if disarmed_s <= 0.0:
            self.custom_mode = _CRUISE  # armed and flying from the first frame
        self._set_armed(disarmed_s <= 0.0)
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self.error: BaseException | None = None

    @staticmethod
    def _role() -> LinkRole:
        return LinkRole(system_id=1, component_id=1, mav_type=int(mavlink2.MAV_TYPE_FIXED_WING),
                        autopilot=int(mavlink2.MAV_AUTOPILOT_ARDUPILOTMEGA),
                        accept_msg_ids=_FROM_GCS)

    @property
    def mavlink_url(self) -> str:
        """Its MAVLink port as a client URL (``tcp:127.0.0.1:PORT``)."""
        if self._mav is None:
            raise RuntimeError("the peer serves no MAVLink port (mavlink=False)")
        return f"tcp:127.0.0.1:{self._mav.local_address[1]}"

    def start(self, sim_url: str | None = None) -> ArduPilotPeer:
        """Start flying; ``sim_url`` (``udp:HOST:PORT``) if not given to the constructor."""
        if sim_url is not None:
            self._sim_address = _udp_address(sim_url)
        if self._sim_address is None:
            raise ValueError("the peer needs the JSON backend's udp:HOST:PORT")
        self._thread = threading.Thread(target=self._run, name="ardupilot-peer", daemon=True)
        self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=10.0)
        self._sock.close()
        for link in (self._mav, self._tel):
            if link is not None:
                link.close()

    def __enter__(self) -> ArduPilotPeer:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def _links(self) -> list[MavlinkLink]:
        return [link for link in (self._mav, self._tel) if link is not None]

    def _set_armed(self, armed: bool) -> None:
        self.armed = armed
        for link in self._links():
            link.set_heartbeat_state(base_mode=_ARMED if armed else 0,
                                     custom_mode=self.custom_mode)

    def _heartbeat(self) -> None:
        """A HEARTBEAT on every link now (ArduPilot's 1 Hz of its clock, here each telemetry
        period), so that its armed state and mode are heard in simulated, not wall, time."""
        msg = mavlink2.MAVLink_heartbeat_message(
            int(mavlink2.MAV_TYPE_FIXED_WING), int(mavlink2.MAV_AUTOPILOT_ARDUPILOTMEGA),
            _ARMED if self.armed else 0, self.custom_mode, int(mavlink2.MAV_STATE_ACTIVE), 3)
        for link in self._links():
            link.send_message(msg)

    # -- the frame loop --
    def _run(self) -> None:
        try:
            self._loop()
        except BaseException as exc:  # surfaced to the test through .error
            self.error = exc

    def _loop(self) -> None:
        assert self._sim_address is not None
        frame = 0
        outputs = list(self.trim)
        state: dict[str, tuple[float, ...]] | None = None
        while not self._stop.is_set():
            if self.silent_after is not None and frame >= self.silent_after:
                self._stop.wait(0.01)
                continue
            packet = encode_servo_packet(frame, self.servo_map.pwm(outputs),
                                         frame_rate_hz=self.frame_rate_hz, channels=self.channels)
            self._sock.sendto(packet, self._sim_address)
            state = self._await_line(time.monotonic() + self.resend_s)
            if state is None:
                self.counters["resends"] += 1  # the same frame count again (ArduPilot)
                continue
            frame += 1
            self.counters["frames"] = frame
            outputs = self._autopilot(state)
            if self.commands is not None:
                self._serve_commands(state["timestamp"][0])
            if not self.armed and state["timestamp"][0] >= self.disarmed_s:
                # armed from a console and switched to CRUISE by its operator
                self.armed_at_s = state["timestamp"][0]
                self.custom_mode = _CRUISE
                self._set_armed(True)
                self._heartbeat()
            if not self.armed or self.custom_mode == _MANUAL:
                outputs = [0.0, 0.0, 0.0, 0.0]  # disarmed / MANUAL: neutral, throttle min
            if self._mav is not None and frame % 10 == 0:
                self._serve_params()
            if self._tel is not None:
                self._tel.tick()

    def _await_line(self, deadline: float) -> dict[str, tuple[float, ...]] | None:
        while not self._stop.is_set() and time.monotonic() < deadline:
            try:
                data = self._sock.recv(65000)
            except (TimeoutError, BlockingIOError):
                continue
            except OSError:
                return None
            lines = [x for x in data.decode("ascii", "replace").split("\n") if x.strip()]
            if not lines:
                continue
            self.counters["lines"] += 1
            parsed = parse_sim_json(lines[-1])
            if parsed is None:
                self.counters["bad_lines"] += 1
                continue
            return parsed
        return None

    def _serve_commands(self, clock_s: float) -> None:
        """The ground station's parameters, commands and mission on its telemetry link
        (:class:`tests.helpers.autopilot_commands.CommandSide`)."""
        side = self.commands
        assert side is not None
        if self._tel is None:
            return
        replies = side.tick(clock_s)
        for msg in self._tel.recv(0.0):
            if msg.get_type() == "GPS_INPUT":
                self._gps_input = msg  # its second GPS, of type MAVLink (GPS2_TYPE 14)
                self._gps2_fixed |= int(msg.gps_id) == 1 and int(msg.fix_type) >= 3
                continue
            replies += side.handle(msg, clock_s)
        for msg in replies:
            self._tel.send_message(msg)
        if (side.armed, side.custom_mode) != (self.armed, self.custom_mode):
            if side.armed and not self.armed:
                self.armed_at_s = clock_s
            self.custom_mode = side.custom_mode
            self._set_armed(side.armed)
            self._heartbeat()

    def _gps1_denied(self) -> bool:
        p = self.params
        return p["SIM_GPS1_ENABLE"] < 0.5 or p["SIM_GPS1_JAM"] >= 0.5

    def _gps2_prearm(self) -> str | None:
        """ArduPilot's pre-arm check of a second GPS of type MAVLink: it refuses to arm until
        that GPS has a 3-D fix (from a GPS_INPUT addressed to it)."""
        side = self.commands
        if side is not None and side.params.get("GPS2_TYPE") == 14.0 and not self._gps2_fixed:
            return "GPS 2: Bad fix"
        return None

    def _take_gps_input(self) -> tuple[float, float, float, tuple[float, float, float]] | None:
        """The newest GPS_INPUT not used yet, when its second GPS is of type MAVLink and EKF3
        may switch to it (GPS2_TYPE 14, GPS_AUTO_SWITCH 1): ArduPilot on GPS2 while GPS1 has
        no fix. As AP_GPS_MAV, the GPS reads only the frames whose ``gps_id`` is its instance
        (GPS2: 1); the others are counted in ``gps_input_other_id``."""
        msg, self._gps_input = self._gps_input, None
        side = self.commands
        if msg is not None and int(msg.gps_id) != 1:
            self.counters["gps_input_other_id"] += 1
            return None
        if msg is None or side is None or side.params.get("GPS2_TYPE") != 14.0 \
                or side.params.get("GPS_AUTO_SWITCH") != 1.0 or int(msg.fix_type) < 3:
            return None
        self.counters["gps_input_fixes"] += 1
        return (msg.lat * 1e-7, msg.lon * 1e-7, float(msg.alt),
                (float(msg.vn), float(msg.ve), float(msg.vd)))

    def _serve_params(self) -> None:
        assert self._mav is not None
        for msg in self._mav.recv(0.0):
            if msg.get_msgId() != mavlink2.MAVLINK_MSG_ID_PARAM_SET:
                continue
            name = msg.param_id.rstrip("\x00")
            if name not in self.params:
                self.counters["params_unknown"] += 1
                continue
            self.params[name] = float(msg.param_value)
            self.param_log.append((self._clock_s, name, float(msg.param_value)))
            self.counters["params_set"] += 1
            index = sorted(self.params).index(name)
            self._mav.send_message(mavlink2.MAVLink_param_value_message(
                name.encode("ascii"), float(msg.param_value),
                int(mavlink2.MAV_PARAM_TYPE_REAL32), len(self.params), index))

    # -- its estimator and controller --
    _clock_s = 0.0

    def _autopilot(self, s: dict[str, tuple[float, ...]]) -> list[float]:
        t = s["timestamp"][0]
        est = self.estimate
        gyro, accel = s["gyro"], s["accel_body"]
        airspeed = s.get("airspeed", (math.nan,))[0]
        pos, vel = s["position"], s["velocity"]
        lat_deg, lon_deg, alt_m = self._location(pos)
        compass_yaw = self._compass_heading(s)
        if not est:
            self._init_estimate(t, s, alt_m, compass_yaw, airspeed)
        dt = max(t - est["t"], 0.0)
        est["t"] = self._clock_s = t
        self._attitude(dt, gyro, accel, airspeed if math.isfinite(airspeed) else est["v_target"],
                       compass_yaw)
        baro_alt = alt_m + self.params["SIM_BARO_GLITCH"]
        if dt > 0:
            est["hdot"] += (dt / 0.5) * ((baro_alt - est["alt"]) / dt - est["hdot"])
        est["alt"] = baro_alt
        fix = self._gps.fix(t, lat_deg, lon_deg, alt_m, (vel[0], vel[1], vel[2]))
        if t < self.fix_after_s:
            fix = None
        if fix is None and self._gps1_denied():
            fix = self._take_gps_input()
        if fix is not None:
            self.counters["fixes"] += 1
            self.fix_times.append(t)
            f_lat, f_lon, _, f_vel = fix
            est["n"] = (f_lat - self.home[0]) * 1e7 * LATLON_TO_M
            est["e"] = (f_lon - self.home[1]) * 1e7 * LATLON_TO_M * math.cos(
                math.radians(0.5 * (f_lat + self.home[0])))
            est["vn"], est["ve"] = f_vel[0], f_vel[1]
            est["fix_yaw"] = est["yaw"]
            est["last_fix"] = t
        else:
            # dead reckoning: the last GPS velocity, turned by the heading change since
            turn = est["yaw"] - est["fix_yaw"]
            c, sn = math.cos(turn), math.sin(turn)
            vn, ve = est["vn"] * c - est["ve"] * sn, est["vn"] * sn + est["ve"] * c
            est["n"] += vn * dt
            est["e"] += ve * dt
        if t >= est["next_track"]:
            est["next_track"] += 1.0
            self.track.append((t, est["n"], est["e"], est["alt"], est["yaw"]))
            self.truth_track.append((t, pos[0], pos[1], -pos[2] + self.home[2]))
        if t >= est["next_tel"]:
            est["next_tel"] += self.telemetry_period_s
            if self._tel is not None:
                self._telemetry(t)
            self._heartbeat()
        return self._control(dt, gyro, airspeed)

    def _location(self, pos: tuple[float, ...]) -> tuple[float, float, float]:
        # ArduPilot: home.offset(north, east); altitude = home alt - down
        lat = self.home[0] + pos[0] / (LATLON_TO_M * 1e7)
        lon = self.home[1] + pos[1] / (LATLON_TO_M * 1e7) / math.cos(
            math.radians(0.5 * (lat + self.home[0])))
        return lat, lon, self.home[2] - pos[2]

    @staticmethod
    def _compass_heading(s: dict[str, tuple[float, ...]]) -> float:
        # SITL's compass is the earth field rotated by the JSON attitude: it knows the heading
        if "quaternion" in s:
            w, x, y, z = s["quaternion"]
            return math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
        return s["attitude"][2]

    def _init_estimate(self, t: float, s: dict[str, tuple[float, ...]], alt_m: float,
                       yaw: float, airspeed: float) -> None:
        f = s["accel_body"]
        roll = math.atan2(-f[1], -f[2])
        pitch = math.atan2(f[0], math.hypot(f[1], f[2]))
        self.estimate.update(
            t=t, roll=roll, pitch=pitch, yaw=yaw, alt=alt_m, hdot=0.0, n=0.0, e=0.0, vn=0.0,
            ve=0.0, fix_yaw=yaw, last_fix=-math.inf, next_track=t, next_tel=t,
            alt_target=alt_m + self.plan.climb_m, v_target=airspeed, pitch0=pitch,
            yaw0=yaw, i_roll=0.0, i_pitch=0.0, i_hdot=0.0, i_thr=0.0,
        )

    def _attitude(self, dt: float, gyro: tuple[float, ...], accel: tuple[float, ...],
                  speed: float, compass_yaw: float) -> None:
        e = self.estimate
        p, q, r = gyro
        phi, theta = e["roll"], e["pitch"]
        cth = max(math.cos(theta), 1e-3)
        e["roll"] = phi + dt * (p + math.tan(theta) * (q * math.sin(phi) + r * math.cos(phi)))
        e["pitch"] = theta + dt * (q * math.cos(phi) - r * math.sin(phi))
        e["yaw"] = e["yaw"] + dt * (q * math.sin(phi) + r * math.cos(phi)) / cth
        # gravity in body = (omega x v_b) - f, with v_b ~ (speed, 0, 0): no turn bias
        gx = -accel[0]
        gy = r * speed - accel[1]
        gz = -q * speed - accel[2]
        roll_g = math.atan2(gy, gz)
        pitch_g = math.atan2(-gx, math.hypot(gy, gz))
        k = min(1.0, dt / 2.0)
        e["roll"] += k * _wrap(roll_g - e["roll"])
        e["pitch"] += k * (pitch_g - e["pitch"])
        e["yaw"] = _wrap(e["yaw"] + min(1.0, dt / 5.0) * _wrap(compass_yaw - e["yaw"]))

    def _heading_target(self, t: float) -> float:
        target = self.estimate["yaw0"]
        for start_s, heading_deg in self.plan.headings:
            if t >= start_s:
                target = math.radians(heading_deg)
        return target

    def _control(self, dt: float, gyro: tuple[float, ...], airspeed: float) -> list[float]:
        e = self.estimate
        p, q, _ = gyro
        trim_roll, trim_pitch, trim_yaw, trim_thr = self.trim
        # heading -> bank -> aileron
        bank_c = _clip(1.0 * _wrap(self._heading_target(e["t"]) - e["yaw"]), math.radians(25))
        roll_err = bank_c - e["roll"]
        e["i_roll"] = _clip(e["i_roll"] + 0.3 * roll_err * dt, 0.3)
        aileron = trim_roll + 0.8 * roll_err - 0.3 * p + e["i_roll"]
        # altitude -> climb rate -> pitch -> elevator (PX4 sign: + = nose up)
        hdot_c = _clip(0.2 * (e["alt_target"] - e["alt"]), 4.0)
        hdot_err = hdot_c - e["hdot"]
        e["i_hdot"] = _clip(e["i_hdot"] + 0.004 * hdot_err * dt, math.radians(8))
        pitch_c = e["pitch0"] + _clip(0.02 * hdot_err + e["i_hdot"], math.radians(10))
        pitch_err = pitch_c - e["pitch"]
        e["i_pitch"] = _clip(e["i_pitch"] + 0.5 * pitch_err * dt, 0.4)
        elevator = trim_pitch + 2.0 * pitch_err - 0.5 * q + e["i_pitch"]
        # airspeed -> throttle
        v_err = e["v_target"] - airspeed if math.isfinite(airspeed) else 0.0
        e["i_thr"] = _clip(e["i_thr"] + 0.02 * v_err * dt, 0.3)
        throttle = min(max(trim_thr + 0.05 * v_err + e["i_thr"], 0.0), 1.0)
        return [_clip(aileron, 1.0), _clip(elevator, 1.0), trim_yaw, throttle]

    def _telemetry(self, t: float) -> None:
        assert self._tel is not None
        e = self.estimate
        boot_ms = round(t * 1000.0) & 0xFFFF_FFFF
        lat, lon, _ = self._location((e["n"], e["e"], 0.0))
        alt = e["alt"]
        if not math.isfinite(e["last_fix"]):
            lat, lon, alt = 0.0, 0.0, -1000.0  # no origin yet: ArduPilot says 0/0
        gps_ok = t - e["last_fix"] < 1.0
        flags = (mavlink2.EKF_ATTITUDE | mavlink2.EKF_VELOCITY_HORIZ | mavlink2.EKF_VELOCITY_VERT
                 | mavlink2.EKF_POS_VERT_ABS | mavlink2.EKF_PRED_POS_HORIZ_REL)
        if gps_ok:
            flags |= mavlink2.EKF_POS_HORIZ_REL | mavlink2.EKF_POS_HORIZ_ABS
        msgs = [
            mavlink2.MAVLink_global_position_int_message(
                boot_ms, round(lat * 1e7), round(lon * 1e7), round(alt * 1000),
                round((alt - self.home[2]) * 1000), round(e["vn"] * 100),
                round(e["ve"] * 100), round(-e["hdot"] * 100),
                round(math.degrees(e["yaw"]) % 360 * 100)),
            mavlink2.MAVLink_attitude_message(boot_ms, e["roll"], e["pitch"], e["yaw"],
                                              0.0, 0.0, 0.0),
            mavlink2.MAVLink_ekf_status_report_message(
                int(flags), 0.1, 0.1, 0.1 if gps_ok else 1.0, 0.1, 0.0),
        ]
        for msg in msgs:
            self._tel.send_message(msg)
        self.counters["telemetry"] += 1


def _udp_address(url: str) -> tuple[str, int]:
    scheme, _, rest = url.partition(":")
    host, _, port = rest.rpartition(":")
    if scheme not in ("udp", "udpout") or not port.isdigit():
        raise ValueError(f"sim_url {url!r}: expected udp:HOST:PORT")
    return host, int(port)


def _wrap(angle: float) -> float:
    return (angle + math.pi) % (2 * math.pi) - math.pi


def _clip(x: float, limit: float) -> float:
    return max(-limit, min(limit, x))
