"""A PX4 protocol peer: the autopilot's side of PX4's simulator MAVLink interface, for tests.

Written from PX4's ``src/modules/simulation/simulator_mavlink/SimulatorMavlink.cpp`` (read,
not copied), without hilnav's link code, so the backend is tested against an independent
implementation:

* connects as the TCP client with ``TCP_NODELAY`` (retrying until the simulator accepts), sends
  one HEARTBEAT (``autopilot`` 12 = PX4, armed flag in ``base_mode``) and a COMMAND_LONG
  ``SET_MESSAGE_INTERVAL`` asking for HIL_STATE_QUATERNION every 5 ms;
* takes its clock from HIL_SENSOR ``time_usec`` of sensor ``id`` 0 (lockstep: time moves only
  when the simulator sends it), reads accel / gyro / mag / baro / diff_pressure per
  ``fields_updated`` group and HIL_GPS (degE7, mm, cm/s, cm);
* after ``boot_sensors`` sensor messages (its boot) answers every HIL_SENSOR with one
  HIL_ACTUATOR_CONTROLS (``time_usec`` = its clock, ``mode`` custom | armed, ``flags`` bit 0 =
  lockstep), all zero while disarmed (the first ``disarmed_controls`` answers), in the output
  layout of PX4's standard SITL plane (``PWM_MAIN_FUNCn``: rudder 3, left flap 4, motor 5,
  ailerons 6 / 7, elevator 8, right flap 9, reversed) or the legacy HIL order.

Its flight controller works from its OWN estimate, never the truth: a complementary-filter
attitude (gyro integration; tilt from the accelerometer with the centripetal term of the
airspeed removed; heading from the magnetometer, its declination learnt at the first GNSS fix
from the course), altitude from the barometer (offset to GNSS while fixes come), position from
GNSS, dead-reckoned with airspeed along the heading plus the last wind estimate during an
outage. It holds altitude and airspeed and flies the heading changes of its :class:`PeerPlan`
(bank-to-turn), through PI loops with PX4-like trims. It publishes that estimate as telemetry
(GLOBAL_POSITION_INT, ATTITUDE, ESTIMATOR_STATUS, HEARTBEAT; ``time_boot_ms`` = its clock =
the simulator's time) on a ``udpout`` link when given one.

Armed state and mode: without ``commands`` it arms by itself after ``disarmed_controls`` (an
operator arming it) and its telemetry HEARTBEAT says MANUAL before, Hold (AUTO.LOITER) after.
Given ``commands`` (:class:`tests.helpers.autopilot_commands.CommandSide`) it arms and changes
mode only when the ground station on its telemetry link tells it to (parameters, commands and
the mission answered there as PX4 does), and sends zero controls while disarmed or in MANUAL
(nobody at the sticks).

Faults for tests: ``silent_after_s`` (stops sending controls, stays connected),
``restart_at_s`` (closes the connection, reboots: a PX4 restart), ``nan_every`` /
``out_of_range_every`` (a NaN elevator / a throttle of 1.5 in every N-th message).
"""

from __future__ import annotations

import math
import socket
import threading
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from fusion.rotations import (
    euler_from_quat,
    euler_to_quat,
    quat_multiply,
    quat_to_dcm,
    rotvec_to_quat,
    wrap_pi,
)
from hil.codec import mavlink2
from tests.helpers.autopilot_commands import CommandSide

_G = 9.80665
_R_EARTH = 6_378_137.0
_EV_ESTIMATOR_TYPES = frozenset({
    int(mavlink2.MAV_ESTIMATOR_TYPE_UNKNOWN), int(mavlink2.MAV_ESTIMATOR_TYPE_NAIVE),
    int(mavlink2.MAV_ESTIMATOR_TYPE_VISION), int(mavlink2.MAV_ESTIMATOR_TYPE_VIO)})
"""The ODOMETRY ``estimator_type`` PX4 takes as external vision
(``MavlinkReceiver::handle_message_odometry``); GPS, GPS_INS, LIDAR and AUTOPILOT it refuses."""
_PX4 = 12  # MAV_AUTOPILOT_PX4
_ARMED = 128
_CUSTOM = 1
_MANUAL_MODE = 1 << 16  # PX4 custom_mode: main mode MANUAL
_HOLD_MODE = 4 << 16 | 3 << 24  # AUTO.LOITER ("Hold")
_ACCEL, _GYRO, _MAG = 0b111, 0b111000, 0b111000000
_BARO = (1 << 9) | (1 << 11) | (1 << 12)
_DIFF = 1 << 10


@dataclass(frozen=True)
class PeerPlan:
    """What the peer's controller flies: hold the start altitude and airspeed, turn by
    ``turns`` ((simulated s, heading change deg) from the start heading)."""

    turns: tuple[tuple[float, float], ...] = ((20.0, 90.0),)
    airspeed_mps: float = 50.0
    max_bank_deg: float = 25.0
    trim_throttle: float = 0.7  # PX4's FW_THR_TRIM
    trim_pitch: float = -0.2  # PX4's TRIM_PITCH


@dataclass
class _Estimate:
    q: np.ndarray = field(default_factory=lambda: np.array([1.0, 0.0, 0.0, 0.0]))
    lat_rad: float = math.nan
    lon_rad: float = math.nan
    alt_m: float = math.nan
    v_ned: np.ndarray = field(default_factory=lambda: np.zeros(3))
    wind_ne: np.ndarray = field(default_factory=lambda: np.zeros(2))
    airspeed_mps: float = 0.0
    baro_alt_m: float = math.nan
    baro_offset_m: float = math.nan
    decl_rad: float = math.nan
    last_fix_us: int = -1
    aligned: bool = False
    omega: np.ndarray = field(default_factory=lambda: np.zeros(3))


class Px4Peer:
    """PX4's side of the simulator interface with a simple flight controller (module doc).

    Parameters
    ----------
    sim_url : str
        ``tcp:HOST:PORT`` of the simulator (PX4 is the TCP client).
    telemetry_url : str, optional
        ``udpout:HOST:PORT`` for the estimate telemetry, or ``udpin:HOST:PORT``: to the first
        client that speaks there (PX4's ground-station link).
    plan : PeerPlan
    outputs : {"standard_plane", "legacy"}
        Output layout of HIL_ACTUATOR_CONTROLS.
    boot_sensors, disarmed_controls : int
        HIL_SENSOR messages before the first controls; controls sent disarmed (all zero).
    silent_after_s, restart_at_s : float, optional
        Faults (simulated s): stop sending controls; drop the connection and reboot.
    nan_every, out_of_range_every : int
        Every N-th controls message carries a NaN elevator / a throttle of 1.5 (0: never).
    """

    def __init__(self, sim_url: str, telemetry_url: str | None = None, plan: PeerPlan | None = None,
                 *, outputs: str = "standard_plane", boot_sensors: int = 30,
                 disarmed_controls: int = 20, silent_after_s: float | None = None,
                 restart_at_s: float | None = None, nan_every: int = 0,
                 out_of_range_every: int = 0, telemetry_rate_hz: float = 10.0,
                 commands: CommandSide | None = None) -> None:
        self.commands = commands
        scheme, host, port = sim_url.split(":")
        if scheme != "tcp":
            raise ValueError("the PX4 peer connects as a TCP client: tcp:HOST:PORT")
        self.address = (host, int(port))
        self.telemetry: tuple[str, int] | None = None
        self._telemetry_listens = False
        self._tel_client: tuple[str, int] | None = None
        if telemetry_url is not None:
            t_scheme, t_host, t_port = telemetry_url.split(":")
            if t_scheme not in ("udpout", "udpin"):
                raise ValueError("telemetry goes out on udpout:HOST:PORT (or udpin:HOST:PORT: "
                                 "to whoever spoke first there, as PX4's ground-station link)")
            self.telemetry = (t_host, int(t_port))
            self._telemetry_listens = t_scheme == "udpin"
        self.plan = plan or PeerPlan()
        self.outputs = outputs
        self.boot_sensors = boot_sensors
        self.disarmed_controls = disarmed_controls
        self.silent_after_s = silent_after_s
        self.restart_at_s = restart_at_s
        self.nan_every = nan_every
        self.out_of_range_every = out_of_range_every
        self._telemetry_period_us = round(1e6 / telemetry_rate_hz)
        self.counters = {"sensors": 0, "gps": 0, "truth": 0, "controls": 0, "heartbeats": 0,
                         "connections": 0, "telemetry": 0, "bad_frames": 0}
        self.controls_at: list[int] = []  # the clock (us) of every controls message sent
        self.sensor_times: list[int] = []  # time_usec of every HIL_SENSOR id 0 received
        self.gps_times: list[int] = []  # time_usec of every HIL_GPS received
        self.bad_at: list[tuple[int, str]] = []
        """(controls message number from 1, "nan" | "out_of_range") of every bad value sent."""
        self.estimates: list[tuple[int, float, float, float, float, float]] = []
        """(time_us, lat_deg, lon_deg, alt_m, roll_rad, yaw_rad) at the telemetry rate."""
        self.errors: list[str] = []
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._tel_sock: socket.socket | None = None
        self._restarted = False
        self._reset()

    # -- lifetime --
    def start(self) -> Px4Peer:
        self._thread = threading.Thread(target=self._run, name="px4-peer", daemon=True)
        self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=10)

    def __enter__(self) -> Px4Peer:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    # -- state --
    def _reset(self) -> None:
        self.clock_us = 0
        self._sensors_since_boot = 0
        self._sent_since_boot = 0
        self._est = _Estimate()
        self._last_imu_us: int | None = None
        self._integ = {"roll": 0.0, "pitch": 0.0, "speed": 0.0}
        self._alt_cmd_m = math.nan
        self._heading0 = math.nan
        self._next_telemetry_us = 0
        self._baro_prev: tuple[int, float] | None = None
        self._climb_mps = 0.0
        self._mav = mavlink2.MAVLink(None, srcSystem=1, srcComponent=1)
        self._mav.robust_parsing = True
        self._tel_mav = mavlink2.MAVLink(None, srcSystem=1, srcComponent=1)
        self._next_heartbeat_us = 0

    # -- the connection --
    def _connect(self) -> socket.socket | None:
        while not self._stop.is_set():
            sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            try:
                sock.connect(self.address)
            except OSError:
                sock.close()
                time.sleep(0.01)
                continue
            self.counters["connections"] += 1
            return sock
        return None

    def _run(self) -> None:
        try:
            if self.telemetry is not None:
                self._tel_sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
                if self._telemetry_listens:
                    self._tel_sock.bind(self.telemetry)
                if self._telemetry_listens or self.commands is not None:
                    # answers (to a ground station, or to hilnav's commands) are read
                    # between sensor messages
                    self._tel_sock.setblocking(False)
            while not self._stop.is_set():
                sock = self._connect()
                if sock is None:
                    return
                with sock:
                    self._session(sock)
        except Exception as exc:  # reported to the test through .errors
            self.errors.append(repr(exc))
        finally:
            if self._tel_sock is not None:
                self._tel_sock.close()

    def _session(self, sock: socket.socket) -> None:
        self._reset()
        hb = mavlink2.MAVLink_heartbeat_message(0, _PX4, 0, 0, 0, 3)
        sock.sendall(hb.pack(self._mav))
        ask = mavlink2.MAVLink_command_long_message(
            0, 0, mavlink2.MAV_CMD_SET_MESSAGE_INTERVAL, 0,
            mavlink2.MAVLINK_MSG_ID_HIL_STATE_QUATERNION, 5000, 0, 0, 0, 0, 0)
        sock.sendall(ask.pack(self._mav))
        sock.settimeout(0.05)
        while not self._stop.is_set():
            try:
                data = sock.recv(65536)
            except TimeoutError:
                continue
            except OSError:
                return
            if not data:
                return  # the simulator closed
            try:
                msgs = self._mav.parse_buffer(data) or []
            except Exception:  # a bad frame: PX4 skips it too
                self.counters["bad_frames"] += 1
                continue
            for msg in msgs:
                if msg.get_type() == "BAD_DATA":
                    self.counters["bad_frames"] += 1
                    continue
                if self._handle(msg, sock) == "restart":
                    self._restarted = True
                    return

    # -- messages --
    def _handle(self, msg: Any, sock: socket.socket) -> str | None:
        kind = msg.get_type()
        if kind == "HEARTBEAT":
            self.counters["heartbeats"] += 1
        elif kind == "HIL_GPS":
            self.counters["gps"] += 1
            self.gps_times.append(int(msg.time_usec))
            self._gps(msg)
        elif kind == "HIL_STATE_QUATERNION":
            self.counters["truth"] += 1  # ground truth: PX4 only logs it
        elif kind == "HIL_SENSOR":
            self._sensor(msg)
            if msg.id != 0:
                return None
            self.clock_us = int(msg.time_usec)  # lockstep: the simulator sets PX4's clock
            self.sensor_times.append(self.clock_us)
            self.counters["sensors"] += 1
            self._sensors_since_boot += 1
            if (self.restart_at_s is not None and not self._restarted
                    and self.clock_us >= self.restart_at_s * 1e6):
                return "restart"
            self._publish_telemetry()
            if self.commands is not None:
                self._serve_commands()
            if self._sensors_since_boot <= self.boot_sensors:
                return None
            if self.silent_after_s is not None and self.clock_us >= self.silent_after_s * 1e6:
                return None
            sock.sendall(self._controls_frame())
            self.controls_at.append(self.clock_us)
            self.counters["controls"] += 1
        return None

    def _sensor(self, m: Any) -> None:
        e = self._est
        bits = int(m.fields_updated)
        t = int(m.time_usec)
        if bits & _BARO == _BARO:
            p_pa = float(m.abs_pressure) * 100.0
            # the six-figure textbook ISA formula (T0/L = 44330.77 m, exponent 0.190263), written
            # out on purpose: the peer stays independent of hilnav's physconst.isa
            e.baro_alt_m = 44330.77 * (1.0 - (p_pa / 101325.0) ** 0.190263)
            self._temp_k = float(m.temperature) + 273.15
            self._pressure_pa = p_pa
            if self._baro_prev is not None and t > self._baro_prev[0]:
                dt = (t - self._baro_prev[0]) * 1e-6
                rate = (e.baro_alt_m - self._baro_prev[1]) / dt
                self._climb_mps += min(1.0, dt / 1.0) * (rate - self._climb_mps)
            self._baro_prev = (t, e.baro_alt_m)
            if not math.isnan(e.baro_offset_m):
                e.alt_m = e.baro_alt_m + e.baro_offset_m
        if bits & _DIFF and hasattr(self, "_pressure_pa"):
            rho = self._pressure_pa / (287.05 * self._temp_k)
            e.airspeed_mps = math.sqrt(max(0.0, 2.0 * float(m.diff_pressure) * 100.0 / rho))
        if bits & _ACCEL == _ACCEL and bits & _GYRO == _GYRO:
            f = np.array([m.xacc, m.yacc, m.zacc], dtype=float)
            w = np.array([m.xgyro, m.ygyro, m.zgyro], dtype=float)
            mag = (np.array([m.xmag, m.ymag, m.zmag], dtype=float)
                   if bits & _MAG == _MAG else None)
            self._attitude(t, f, w, mag)
            self._dead_reckon(t)

    def _attitude(self, t: int, f: np.ndarray, w: np.ndarray, mag: np.ndarray | None) -> None:
        e = self._est
        e.omega = w
        if self._last_imu_us is None:
            # level the first time from the accelerometer (straight flight: f = -g)
            roll = math.atan2(-f[1], -f[2])
            pitch = math.atan2(f[0], math.hypot(f[1], f[2]))
            e.q = euler_to_quat([roll, pitch, 0.0])
            self._last_imu_us = t
            return
        dt = (t - self._last_imu_us) * 1e-6
        self._last_imu_us = t
        if dt <= 0:
            return
        c_nb = quat_to_dcm(e.q)
        v = max(e.airspeed_mps, 10.0)
        g_meas = np.array([0.0, w[2] * v, -w[1] * v]) - f  # gravity in body: w x v_b - f
        corr = np.zeros(3)
        norm = np.linalg.norm(g_meas)
        if 0.5 * _G < norm < 1.5 * _G:
            corr += 0.5 * np.cross(g_meas / norm, c_nb.T @ np.array([0.0, 0.0, 1.0]))
        if mag is not None and e.aligned:
            m_n = c_nb @ mag
            err = wrap_pi(math.atan2(m_n[1], m_n[0]) - e.decl_rad)
            corr += c_nb.T @ np.array([0.0, 0.0, -0.3 * err])
        e.q = quat_multiply(e.q, rotvec_to_quat((w + corr) * dt))
        e.q /= np.linalg.norm(e.q)
        if mag is not None:
            self._last_mag = mag

    def _gps(self, m: Any) -> None:
        e = self._est
        if int(m.fix_type) < 3:
            return
        e.lat_rad = math.radians(m.lat * 1e-7)
        e.lon_rad = math.radians(m.lon * 1e-7)
        gnss_alt = m.alt * 1e-3
        v = np.array([m.vn, m.ve, m.vd], dtype=float) * 1e-2
        e.v_ned = v
        e.last_fix_us = int(m.time_usec)
        self._ev_learn()
        if not math.isnan(e.baro_alt_m):
            off = gnss_alt - e.baro_alt_m
            e.baro_offset_m = off if math.isnan(e.baro_offset_m) else (
                e.baro_offset_m + 0.02 * (off - e.baro_offset_m))
            e.alt_m = e.baro_alt_m + e.baro_offset_m
        last_mag = getattr(self, "_last_mag", None)
        if not e.aligned and math.hypot(v[0], v[1]) > 10.0 and last_mag is not None:
            roll, pitch, _ = euler_from_quat(e.q)
            e.q = euler_to_quat([roll, pitch, math.atan2(v[1], v[0])])
            m_n = quat_to_dcm(e.q) @ last_mag
            e.decl_rad = math.atan2(m_n[1], m_n[0])
            e.aligned = True
        if e.aligned:
            _, pitch, yaw = euler_from_quat(e.q)
            air = e.airspeed_mps * math.cos(pitch) * np.array([math.cos(yaw), math.sin(yaw)])
            e.wind_ne += 0.05 * ((v[:2] - air) - e.wind_ne)

    def _gnss_lost(self) -> bool:
        return self._est.last_fix_us < 0 or self.clock_us - self._est.last_fix_us > 500_000

    def _dead_reckon(self, t: int) -> None:
        e = self._est
        prev = getattr(self, "_dr_prev_us", t)
        self._dr_prev_us = t
        if not e.aligned or not self._gnss_lost() or math.isnan(e.lat_rad):
            return
        dt = (t - prev) * 1e-6
        _, pitch, yaw = euler_from_quat(e.q)
        air = e.airspeed_mps * math.cos(pitch) * np.array([math.cos(yaw), math.sin(yaw)])
        vne = air + e.wind_ne
        e.v_ned = np.array([vne[0], vne[1], -self._climb_mps])
        e.lat_rad += vne[0] * dt / _R_EARTH
        e.lon_rad += vne[1] * dt / (_R_EARTH * math.cos(e.lat_rad))

    # -- the controller --
    def _commands(self) -> tuple[float, float, float, float]:
        """(roll, pitch, yaw, throttle) in the legacy HIL order and signs."""
        e, p = self._est, self.plan
        dt = 1e-6 * (self.clock_us - getattr(self, "_ctl_prev_us", self.clock_us))
        self._ctl_prev_us = self.clock_us
        roll, pitch, yaw = euler_from_quat(e.q)
        if math.isnan(self._alt_cmd_m) and not math.isnan(e.alt_m):
            self._alt_cmd_m = e.alt_m
        bank_cmd = 0.0
        if e.aligned:
            if math.isnan(self._heading0):
                self._heading0 = yaw
            heading_cmd = self._heading0 + math.radians(
                sum(d for t_s, d in p.turns if self.clock_us >= t_s * 1e6))
            limit = math.radians(p.max_bank_deg)
            bank_cmd = max(-limit, min(limit, 1.2 * wrap_pi(heading_cmd - yaw)))
        pitch_cmd = math.radians(2.0)
        if not math.isnan(self._alt_cmd_m) and not math.isnan(e.alt_m):
            climb_cmd = max(-3.0, min(3.0, 0.2 * (self._alt_cmd_m - e.alt_m)))
            pitch_cmd += max(-0.15, min(0.15, 0.06 * (climb_cmd - self._climb_mps)))
            pitch_cmd += 0.5 * (1.0 / max(math.cos(roll), 0.5) - 1.0)  # turn: more lift
        i = self._integ
        roll_err = bank_cmd - roll
        i["roll"] = max(-0.3, min(0.3, i["roll"] + 0.2 * roll_err * dt))
        aileron = 0.8 * roll_err - 0.15 * e.omega[0] + i["roll"]
        pitch_err = pitch_cmd - pitch
        i["pitch"] = max(-0.5, min(0.5, i["pitch"] + 0.3 * pitch_err * dt))
        elevator = p.trim_pitch + 1.5 * pitch_err - 0.3 * e.omega[1] + i["pitch"]
        speed_err = p.airspeed_mps - e.airspeed_mps
        i["speed"] = max(-0.3, min(0.3, i["speed"] + 0.01 * speed_err * dt))
        throttle = p.trim_throttle + 0.05 * speed_err + i["speed"]
        clip = lambda x, lo=-1.0, hi=1.0: max(lo, min(hi, x))  # noqa: E731
        return clip(aileron), clip(elevator), 0.0, clip(throttle, 0.0, 1.0)

    def _controls_frame(self) -> bytes:
        roll, pitch, yaw, throttle = self._commands()
        self._sent_since_boot += 1
        n = self.counters["controls"] + 1
        armed = self._armed()
        if armed and self.nan_every and n % self.nan_every == 0:
            pitch = math.nan
            self.bad_at.append((n, "nan"))
        if armed and self.out_of_range_every and n % self.out_of_range_every == 0:
            throttle = 1.5
            self.bad_at.append((n, "out_of_range"))
        out = [0.0] * 16
        if armed and self._mode() != _MANUAL_MODE:  # MANUAL, nobody at the sticks: zero
            if self.outputs == "legacy":
                out[:4] = [roll, pitch, yaw, throttle]
            else:  # PX4 standard SITL plane: PWM_MAIN_FUNC3..9
                out[2], out[3], out[4] = yaw, 0.0, throttle
                out[5], out[6], out[7], out[8] = -roll, roll, pitch, -0.0
        msg = mavlink2.MAVLink_hil_actuator_controls_message(
            self.clock_us, out, _CUSTOM | (_ARMED if armed else 0), 1)
        return bytes(msg.pack(self._mav))

    # -- armed state, mode and the ground station's commands --
    def _armed(self) -> bool:
        if self.commands is not None:
            return self.commands.armed
        return self._sent_since_boot > self.disarmed_controls

    def _mode(self) -> int:
        """Its custom_mode: the commanded one; without commands MANUAL while disarmed and
        Hold once armed (an operator arming it and selecting Hold)."""
        if self.commands is not None:
            return self.commands.custom_mode
        return _HOLD_MODE if self._armed() else _MANUAL_MODE

    def _serve_commands(self) -> None:
        """Answer the ground station on the telemetry socket
        (:class:`tests.helpers.autopilot_commands.CommandSide`), on PX4's clock."""
        side, sock = self.commands, self._tel_sock
        if side is None or sock is None or self.telemetry is None:
            return
        clock_s = self.clock_us * 1e-6
        replies = side.tick(clock_s)
        while True:
            try:
                data = sock.recv(65536)
            except (BlockingIOError, InterruptedError):
                break
            except OSError:
                break
            parser = self.__dict__.setdefault("_gcs_parser", mavlink2.MAVLink(None))
            parser.robust_parsing = True
            for msg in parser.parse_buffer(data) or []:
                if msg.get_type() == "ODOMETRY":
                    self._on_odometry(msg)
                elif msg.get_type() != "BAD_DATA":
                    replies += side.handle(msg, clock_s)
        for msg in replies:
            sock.sendto(bytes(msg.pack(self._tel_mav)), self.telemetry)

    def _ev_enabled(self) -> bool:
        side = self.commands
        return side is not None and bool(int(side.params.get("EKF2_EV_CTRL", 0.0)) & 1)

    def _ev_position(self) -> np.ndarray | None:
        """The latest ODOMETRY position (its own local frame, m N/E) carried to this clock by
        its velocity (body axes, turned by its q); None before one."""
        msg = getattr(self, "_ev_last", None)
        if msg is None:
            return None
        v = np.array([float(msg.vx), float(msg.vy), float(msg.vz)])
        if int(msg.child_frame_id) == int(mavlink2.MAV_FRAME_LOCAL_NED):
            v_ned = v  # as PX4: a NED velocity is taken as it is
        else:  # body axes (MAV_FRAME_BODY_FRD), turned by the message's q here
            v_ned = quat_to_dcm(np.array([float(c) for c in msg.q])) @ v
        age_s = (self.clock_us - int(msg.time_usec)) * 1e-6
        return np.array([float(msg.x), float(msg.y)]) + v_ned[:2] * age_s

    def _ev_local(self) -> np.ndarray:
        e = self._est
        lat0, lon0 = self._ev_ref
        return np.array([(e.lat_rad - lat0) * _R_EARTH,
                         (e.lon_rad - lon0) * _R_EARTH * math.cos(lat0)])

    def _ev_learn(self) -> None:
        """At a GNSS fix: the offset between the ODOMETRY's frame and the estimate's."""
        if not self._ev_enabled() or math.isnan(self._est.lat_rad):
            return
        self.__dict__.setdefault("_ev_ref", (self._est.lat_rad, self._est.lon_rad))
        odom = self._ev_position()
        if odom is not None:
            self._ev_offset = self._ev_local() - odom

    def _on_odometry(self, msg: Any) -> None:
        """External vision (EKF2_EV_CTRL bit 0: horizontal position): the ODOMETRY position is
        in a local frame of its own, so at each GNSS fix the offset between that frame and the
        estimate's is learnt (:meth:`_ev_learn`); while GNSS is lost the position is the
        ODOMETRY's plus that offset (EKF2 fuses the same, with its own weights)."""
        if not self._ev_enabled():
            return
        if int(msg.estimator_type) not in _EV_ESTIMATOR_TYPES:
            # PX4 drops it ("ODOMETRY: estimator_type N unsupported"; MOCAP goes elsewhere)
            self.counters["odometry_unsupported"] = (
                self.counters.get("odometry_unsupported", 0) + 1)
            return
        self._ev_last = msg
        offset = getattr(self, "_ev_offset", None)
        if not self._gnss_lost() or offset is None:
            return
        e = self._est
        lat0, lon0 = self._ev_ref
        odom = self._ev_position()
        assert odom is not None
        n, east = odom + offset
        e.lat_rad = lat0 + n / _R_EARTH
        e.lon_rad = lon0 + east / (_R_EARTH * math.cos(lat0))
        self.counters["ev_fixes"] = self.counters.get("ev_fixes", 0) + 1

    # -- telemetry --
    def _publish_telemetry(self) -> None:
        e = self._est
        self.__dict__.setdefault("_home_alt", e.alt_m)
        if self.clock_us < self._next_telemetry_us or math.isnan(e.lat_rad) or math.isnan(e.alt_m):
            return
        self._next_telemetry_us = self.clock_us + self._telemetry_period_us
        roll, pitch, yaw = euler_from_quat(e.q)
        self.estimates.append((self.clock_us, math.degrees(e.lat_rad), math.degrees(e.lon_rad),
                               e.alt_m, roll, yaw))
        if self._tel_sock is None or self.telemetry is None:
            return
        ms = self.clock_us // 1000
        frames = []
        if self.clock_us >= self._next_heartbeat_us:
            self._next_heartbeat_us = self.clock_us + 1_000_000
            frames.append(mavlink2.MAVLink_heartbeat_message(
                mavlink2.MAV_TYPE_FIXED_WING, _PX4, _CUSTOM | (_ARMED if self._armed() else 0),
                self._mode(), 4, 3))
        home = self._home_alt if not math.isnan(self._home_alt) else e.alt_m
        frames.append(mavlink2.MAVLink_global_position_int_message(
            ms, round(math.degrees(e.lat_rad) * 1e7), round(math.degrees(e.lon_rad) * 1e7),
            round(e.alt_m * 1e3), round((e.alt_m - home) * 1e3),
            *(round(x * 100) for x in e.v_ned), round(math.degrees(yaw) % 360 * 100)))
        frames.append(mavlink2.MAVLink_attitude_message(
            ms, roll, pitch, yaw, *(float(x) for x in e.omega)))
        lost = self._gnss_lost()
        flags = 1 | 2 | 4 | 8 | 32 | (0 if lost else 16)
        age_s = 0.0 if not lost else (self.clock_us - e.last_fix_us) * 1e-6
        frames.append(mavlink2.MAVLink_estimator_status_message(
            self.clock_us, flags, 0.1, 0.1 if not lost else 1.0, 0.1, 0.1, 0.0, 0.1,
            1.0 + 2.0 * age_s, 2.0))
        to = self.telemetry
        if self._telemetry_listens:
            while self._tel_client is None:
                try:
                    self._tel_client = self._tel_sock.recvfrom(4096)[1]
                except BlockingIOError:
                    return
            to = self._tel_client
        for frame in frames:
            self._tel_sock.sendto(bytes(frame.pack(self._tel_mav)), to)
            self.counters["telemetry"] += 1
