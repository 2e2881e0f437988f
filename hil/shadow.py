"""Wire encoders for what the fusion service *sends*: the shadow vehicle and the companion.

This module sits next to :mod:`hil.codec` and follows its rule: wire units (degE7, mm, cm/s,
cdeg) are known only here and in the codec; callers hand over SI
:class:`fusion.filter.NavEstimate` objects and get whole MAVLink 2 frames back. The unit
constants are the codec's own (:mod:`hil.codec.wire`).

Shadow vehicle (towards ground stations; own system id, component 1)
    HEARTBEAT comes from the link (its fields from :func:`heartbeat_state`); this module
    builds GLOBAL_POSITION_INT, ATTITUDE_QUATERNION, ATTITUDE, VFR_HUD, SYS_STATUS,
    ESTIMATOR_STATUS, SYSTEM_TIME, GPS_RAW_INT, HOME_POSITION, EXTENDED_SYS_STATE, STATUSTEXT,
    the standard-modes messages (AVAILABLE_MODES, CURRENT_MODE, AVAILABLE_MODES_MONITOR) and
    the minimal answers ground stations wait for: PARAM_VALUE, AUTOPILOT_VERSION, COMMAND_ACK,
    MISSION_COUNT (0 items), FILE_TRANSFER_PROTOCOL (an empty, read-only file system).

    One time base: every ``time_boot_ms`` / ``time_usec`` is the estimate's time (simulated
    time in a simulation, the IMU's clock on a real flight controller), never the wall clock;
    SYSTEM_TIME's ``time_unix_usec`` alone is UTC.

Flight modes (HEARTBEAT ``base_mode = MAV_MODE_FLAG_CUSTOM_MODE_ENABLED``, ``custom_mode``)
    :data:`CUSTOM_MODES`: what the navigation rests on, numbered from 101 so that pymavlink /
    MAVProxy, which look ``custom_mode`` up in ArduPlane's table for any fixed-wing vehicle,
    do not show an ArduPlane name (ArduPlane uses 0-25). The names reach clients through
    MAVLink's standard-modes microservice (AVAILABLE_MODES, ``standard_mode`` NON_STANDARD,
    not user-selectable); the three messages exist only in pymavlink's ``development``
    dialect, whose definitions (:data:`STANDARD_MODES_DIALECT`) pack them.

Companion (towards a flight controller)
    GPS_INPUT (ArduPilot ``GPS_TYPE=14``) and ODOMETRY (PX4 external vision / odometry,
    ``frame_id = MAV_FRAME_LOCAL_NED`` about the first estimate's position,
    ``child_frame_id = MAV_FRAME_LOCAL_NED``: velocity NED; the estimate's variances as
    covariances).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any, Final

from fusion.earth import ned_offset_m
from fusion.estimate import Mode, NavEstimate
from hil.codec.wire import (
    DEGE7_PER_RAD,
    INT16_MAX,
    INT16_MIN,
    INT32_MAX,
    INT32_MIN,
    STANDARD_MODES_DIALECT,
    UINT16_MAX,
    mavlink2,
)
from sim.samples import GnssFix

__all__ = [
    "CUSTOM_MODES", "CompanionEncoder", "SensorBits", "ShadowEncoder", "gps_time",
    "heartbeat_state",
]

CUSTOM_MODES: Final = {
    Mode.INITIALIZING: (101, "ALIGNING"),
    Mode.GNSS: (102, "GNSS"),
    Mode.BRIDGING: (103, "BRIDGING"),
    Mode.DEAD_RECKONING: (104, "DEAD-RECKONING"),
    Mode.FREE_INERTIAL: (105, "FREE-INERTIAL"),
}
"""Navigation mode -> (HEARTBEAT ``custom_mode``, name in AVAILABLE_MODES)."""

_GPS_EPOCH_UNIX_S: Final = 315_964_800  # 1980-01-06
_GPS_LEAP_S: Final = 18  # GPS - UTC since 2017
_WEEK_S: Final = 7 * 86_400

_GEOFENCE: Final = int(mavlink2.MAV_SYS_STATUS_GEOFENCE)
# MAVLink FTP (https://mavlink.io/en/services/ftp.html): opcodes and error codes used here
_FTP_ACK: Final = 128
_FTP_NAK_OP: Final = 129
_FTP_ACK_OPS: Final = frozenset({1, 2})  # TerminateSession, ResetSessions
_FTP_ERR_INVALID_SESSION: Final = 4
_FTP_ERR_FILE_PROTECTED: Final = 9
_FTP_ERR_FILE_NOT_FOUND: Final = 10
_FTP_NAK: Final = {
    3: _FTP_ERR_FILE_NOT_FOUND,  # ListDirectory
    4: _FTP_ERR_FILE_NOT_FOUND,  # OpenFileRO
    14: _FTP_ERR_FILE_NOT_FOUND,  # CalcFileCRC32
    16: _FTP_ERR_FILE_NOT_FOUND,  # ListDirectoryWithTime
    5: _FTP_ERR_INVALID_SESSION,  # ReadFile
    7: _FTP_ERR_INVALID_SESSION,  # WriteFile
    15: _FTP_ERR_INVALID_SESSION,  # BurstReadFile
}
"""Error byte of the NAK per request opcode; any other (writing) opcode: FileProtected."""
_STD = STANDARD_MODES_DIALECT


@dataclass(frozen=True, slots=True)
class SensorBits:
    """SYS_STATUS ``onboard_control_sensors_{present,enabled,health}`` (``MAV_SYS_STATUS_*``
    bits). A health bit of a sensor that is not present is 0, except the geofence's (see
    :meth:`ShadowEncoder.sys_status`)."""

    present: int = 0
    enabled: int = 0
    health: int = 0


def heartbeat_state(mode: Mode | None) -> tuple[int, int, int]:
    """HEARTBEAT ``(base_mode, custom_mode, system_status)`` of the navigation mode: custom
    mode enabled (never armed: the shadow vehicle does not know), :data:`CUSTOM_MODES`,
    ``MAV_STATE_STANDBY`` while aligning else ``MAV_STATE_ACTIVE``."""
    m = Mode.INITIALIZING if mode is None else mode
    status = mavlink2.MAV_STATE_STANDBY if m == Mode.INITIALIZING else mavlink2.MAV_STATE_ACTIVE
    return int(mavlink2.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED), CUSTOM_MODES[m][0], int(status)


def _clip(value: float, lo: int, hi: int) -> int:
    if not math.isfinite(value):
        return 0
    return int(min(max(round(value), lo), hi))


def _f(value: float) -> float:
    """float32 wire field: NaN stays NaN (MAVLink's "unknown" for float fields)."""
    return float(value)


def _heading_deg(est: NavEstimate) -> float:
    return math.degrees(float(est.euler_rad[2])) % 360.0


def _rates(est: NavEstimate) -> tuple[float, float, float]:
    w = est.omega_b_rps
    if w is None:
        return 0.0, 0.0, 0.0
    return float(w[0]), float(w[1]), float(w[2])


def _mm(value_m: float) -> int:
    """An accuracy in mm (uint32; NaN -> 0 = unknown)."""
    return _clip(value_m * 1000.0, 0, 0xFFFF_FFFF)


def _sigma(est: NavEstimate, i: int) -> float:
    p = float(est.P_diag[i])
    return math.sqrt(p) if p > 0.0 else 0.0


def gps_time(unix_s: float) -> tuple[int, int]:
    """(GPS week, milliseconds of week) of a UTC Unix time."""
    gps_s = unix_s - _GPS_EPOCH_UNIX_S + _GPS_LEAP_S
    week = int(gps_s // _WEEK_S)
    return week, round((gps_s - week * _WEEK_S) * 1000.0) % (_WEEK_S * 1000)


class _Packer:
    def __init__(self, system_id: int, component_id: int, dialect: Any = mavlink2) -> None:
        self.mav = dialect.MAVLink(None, srcSystem=system_id, srcComponent=component_id)

    def pack(self, msg: Any) -> bytes:
        # the link re-sequences frames per component; the packer's own seq is irrelevant
        return bytes(msg.pack(self.mav))


class ShadowEncoder:
    """Frames of the shadow vehicle (the estimate shown to ground stations as an aircraft).

    Parameters
    ----------
    system_id : int
        The shadow vehicle's MAVLink system id (component 1, the autopilot).

    Every time field is the estimate time of the newest estimate encoded (:meth:`boot_ms`,
    see the module docstring).
    """

    def __init__(self, system_id: int) -> None:
        comp = int(mavlink2.MAV_COMP_ID_AUTOPILOT1)
        self._p = _Packer(system_id, comp)
        self._std = _Packer(system_id, comp, _STD)
        self.system_id = system_id
        self.time_us = 0
        """Estimate time of the newest estimate encoded, us (0 before the first)."""
        self.home: tuple[float, float, float] | None = None
        """Home (lat rad, lon rad, alt MSL m): the first estimate after alignment."""

    def _at(self, est: NavEstimate) -> None:
        self.time_us = max(self.time_us, int(est.time_us))
        if self.home is None and est.mode != Mode.INITIALIZING:
            self.home = (float(est.lat_rad), float(est.lon_rad), float(est.alt_msl_m))

    def heartbeat(self, mode: Mode | None) -> bytes:
        """HEARTBEAT as the link sends it (:func:`heartbeat_state`), for a recorded log."""
        base_mode, custom_mode, status = heartbeat_state(mode)
        return self._p.pack(mavlink2.MAVLink_heartbeat_message(
            int(mavlink2.MAV_TYPE_FIXED_WING), int(mavlink2.MAV_AUTOPILOT_GENERIC), base_mode,
            custom_mode, status, 3))

    def boot_ms(self) -> int:
        """``time_boot_ms``: the newest estimate time, ms (uint32 wrap)."""
        return (self.time_us // 1000) & 0xFFFF_FFFF

    def telemetry(self, est: NavEstimate) -> list[bytes]:
        """The fast group: GLOBAL_POSITION_INT, ATTITUDE, ATTITUDE_QUATERNION, VFR_HUD."""
        return [self.global_position_int(est), self.attitude(est),
                self.attitude_quaternion(est), self.vfr_hud(est)]

    def global_position_int(self, est: NavEstimate) -> bytes:
        """GLOBAL_POSITION_INT: degE7, mm (MSL and above home), cm/s, cdeg."""
        self._at(est)
        home_alt_m = est.alt_msl_m if self.home is None else self.home[2]
        vn, ve, vd = (float(v) for v in est.v_ned_mps)
        return self._p.pack(mavlink2.MAVLink_global_position_int_message(
            self.boot_ms(),
            _clip(est.lat_rad * DEGE7_PER_RAD, INT32_MIN, INT32_MAX),
            _clip(est.lon_rad * DEGE7_PER_RAD, INT32_MIN, INT32_MAX),
            _clip(est.alt_msl_m * 1000.0, INT32_MIN, INT32_MAX),
            _clip((est.alt_msl_m - home_alt_m) * 1000.0, INT32_MIN, INT32_MAX),
            _clip(vn * 100.0, INT16_MIN, INT16_MAX),
            _clip(ve * 100.0, INT16_MIN, INT16_MAX),
            _clip(vd * 100.0, INT16_MIN, INT16_MAX),
            _clip(_heading_deg(est) * 100.0, 0, 35999),
        ))

    def attitude(self, est: NavEstimate) -> bytes:
        """ATTITUDE: Euler angles (rad, yaw in [-pi, pi]) and the estimate's bias-corrected
        body rates (rad/s; 0 when the estimate carries none)."""
        self._at(est)
        r, p, y = (float(a) for a in est.euler_rad)
        y = math.atan2(math.sin(y), math.cos(y))
        return self._p.pack(mavlink2.MAVLink_attitude_message(
            self.boot_ms(), r, p, y, *_rates(est)))

    def attitude_quaternion(self, est: NavEstimate) -> bytes:
        """ATTITUDE_QUATERNION: q body->NED (w, x, y, z), body rates rad/s."""
        self._at(est)
        w, x, y, z = (float(q) for q in est.q_nb)
        return self._p.pack(mavlink2.MAVLink_attitude_quaternion_message(
            self.boot_ms(), w, x, y, z, *_rates(est), [0.0, 0.0, 0.0, 0.0]))

    def vfr_hud(self, est: NavEstimate) -> bytes:
        """VFR_HUD: airspeed = the estimated true airspeed ``|v - w|`` when the wind states
        run (air data), else the ground speed (m/s)."""
        vn, ve, vd = (float(v) for v in est.v_ned_mps)
        gs = math.hypot(vn, ve)
        air = getattr(est, "air_data", None)
        aspd = gs
        if air is not None and air.wind_active:
            wn, we = air.wind_ne_mps
            aspd = math.sqrt((vn - wn) ** 2 + (ve - we) ** 2 + vd * vd)
        return self._p.pack(mavlink2.MAVLink_vfr_hud_message(
            aspd, gs, _clip(_heading_deg(est), 0, 359), 0, est.alt_msl_m, -vd))

    def sys_status(self, bits: SensorBits) -> bytes:
        """SYS_STATUS with ``bits``; battery unknown as the message's text says (voltage
        UINT16_MAX, current -1, remaining -1), load and errors 0.

        The GEOFENCE *health* bit is always set (present and enabled never are): MAVProxy's
        fence module starts from "healthy" and says "fence breach" when a SYS_STATUS lacks
        that health bit, whether or not a fence is present (MAVProxy 1.8.75
        ``modules/mavproxy_fence.py``, ``handle_sys_status``); ArduPilot likewise reports a
        healthy, absent fence."""
        return self._p.pack(mavlink2.MAVLink_sys_status_message(
            bits.present & ~_GEOFENCE, bits.enabled & ~_GEOFENCE, bits.health | _GEOFENCE,
            0, UINT16_MAX, -1, -1, 0, 0, 0, 0, 0, 0))

    def gps_raw_int(self, fix: GnssFix | None, fix_lost: bool) -> bytes:
        """GPS_RAW_INT of the receiver's last fix: ``fix_type`` as received, or
        ``GPS_FIX_TYPE_NO_FIX`` with 0 satellites when ``fix_lost`` (no fix for a while: an
        outage or jamming); ``GPS_FIX_TYPE_NO_GPS`` before any fix. ``eph`` / ``epv`` are
        dilutions of precision in this message, which hilnav's receiver does not know:
        UINT16_MAX (unknown); its accuracies go to ``h_acc`` / ``v_acc`` / ``vel_acc`` (mm,
        mm/s). ``cog`` is unknown (UINT16_MAX) below 0.5 m/s."""
        if fix is None:
            return self._p.pack(mavlink2.MAVLink_gps_raw_int_message(
                self.time_us, int(mavlink2.GPS_FIX_TYPE_NO_GPS), 0, 0, 0, UINT16_MAX,
                UINT16_MAX, UINT16_MAX, UINT16_MAX, 0))
        vn, ve = float(fix.v_ned_mps[0]), float(fix.v_ned_mps[1])
        gs = math.hypot(vn, ve)
        cog = _clip(math.degrees(math.atan2(ve, vn)) % 360.0 * 100.0, 0, 35999) if (
            gs >= 0.5) else UINT16_MAX
        fix_type = int(mavlink2.GPS_FIX_TYPE_NO_FIX) if fix_lost else int(fix.fix_type)
        sats = 0 if fix_lost else int(fix.satellites_visible)
        return self._p.pack(mavlink2.MAVLink_gps_raw_int_message(
            int(fix.time_us), fix_type,
            _clip(fix.lat_rad * DEGE7_PER_RAD, INT32_MIN, INT32_MAX),
            _clip(fix.lon_rad * DEGE7_PER_RAD, INT32_MIN, INT32_MAX),
            _clip(fix.alt_msl_m * 1000.0, INT32_MIN, INT32_MAX),
            UINT16_MAX, UINT16_MAX, _clip(gs * 100.0, 0, UINT16_MAX - 1), cog,
            min(max(sats, 0), 254), 0,
            _mm(fix.eph_m), _mm(fix.epv_m), _mm(fix.speed_accuracy_mps), 0, 0))

    def home_position(self) -> bytes | None:
        """HOME_POSITION at :attr:`home` (None before alignment): degE7, mm MSL, local
        position 0 (the home is the local origin), q identity, approach vector 0."""
        if self.home is None:
            return None
        lat, lon, alt = self.home
        return self._p.pack(mavlink2.MAVLink_home_position_message(
            _clip(lat * DEGE7_PER_RAD, INT32_MIN, INT32_MAX),
            _clip(lon * DEGE7_PER_RAD, INT32_MIN, INT32_MAX),
            _clip(alt * 1000.0, INT32_MIN, INT32_MAX),
            0.0, 0.0, 0.0, [1.0, 0.0, 0.0, 0.0], 0.0, 0.0, 0.0, self.time_us))

    def extended_sys_state(self, in_air: bool | None) -> bytes:
        """EXTENDED_SYS_STATE: not a VTOL; landed state in air / on ground (None: undefined)."""
        landed = (mavlink2.MAV_LANDED_STATE_UNDEFINED if in_air is None
                  else mavlink2.MAV_LANDED_STATE_IN_AIR if in_air
                  else mavlink2.MAV_LANDED_STATE_ON_GROUND)
        return self._p.pack(mavlink2.MAVLink_extended_sys_state_message(
            int(mavlink2.MAV_VTOL_STATE_UNDEFINED), int(landed)))

    def statustext(self, severity: int, text: str) -> bytes:
        """STATUSTEXT of ``severity`` (``MAV_SEVERITY``), ``text`` cut to 50 ASCII chars."""
        raw = text.encode("ascii", "replace")[:50]
        return self._p.pack(mavlink2.MAVLink_statustext_message(int(severity), raw, 0, 0))

    def available_modes(self, index: int) -> bytes:
        """AVAILABLE_MODES of mode ``index`` (1-based, :data:`CUSTOM_MODES` order)."""
        modes = list(CUSTOM_MODES.values())
        number, name = modes[index - 1]
        return self._std.pack(_STD.MAVLink_available_modes_message(
            len(modes), index, int(_STD.MAV_STANDARD_MODE_NON_STANDARD), number,
            int(_STD.MAV_MODE_PROPERTY_NOT_USER_SELECTABLE), name.encode()))

    def current_mode(self, mode: Mode) -> bytes:
        """CURRENT_MODE: non-standard, the :data:`CUSTOM_MODES` number (also the intended one)."""
        number = CUSTOM_MODES[mode][0]
        return self._std.pack(_STD.MAVLink_current_mode_message(
            int(_STD.MAV_STANDARD_MODE_NON_STANDARD), number, number))

    def available_modes_monitor(self) -> bytes:
        """AVAILABLE_MODES_MONITOR: sequence 0 (the set of modes never changes)."""
        return self._std.pack(_STD.MAVLink_available_modes_monitor_message(0))

    def estimator_status(self, est: NavEstimate) -> bytes:
        """ESTIMATOR_STATUS: solution flags (``dead-reckoning``, ``free-inertial`` and
        ``bridging`` report a predicted horizontal position), test ratios (NaN -> 0; the
        airspeed's as ``tas_ratio``), 1-sigma accuracies (m)."""
        flags = int(mavlink2.ESTIMATOR_ATTITUDE | mavlink2.ESTIMATOR_VELOCITY_HORIZ
                    | mavlink2.ESTIMATOR_VELOCITY_VERT | mavlink2.ESTIMATOR_POS_VERT_ABS)
        if est.mode == "gnss":
            flags |= int(mavlink2.ESTIMATOR_POS_HORIZ_ABS | mavlink2.ESTIMATOR_POS_HORIZ_REL)
        elif est.mode in ("free-inertial", "bridging", "dead-reckoning"):
            flags |= int(mavlink2.ESTIMATOR_PRED_POS_HORIZ_ABS | mavlink2.ESTIMATOR_GPS_GLITCH)
        else:
            flags = int(mavlink2.ESTIMATOR_CONST_POS_MODE)
        tr = est.test_ratios

        def ratio(v: float) -> float:
            return float(v) if math.isfinite(v) else 0.0

        return self._p.pack(mavlink2.MAVLink_estimator_status_message(
            int(est.time_us), flags, ratio(tr.gnss_vel), ratio(tr.gnss_pos),
            ratio(tr.baro_hgt), ratio(tr.mag_hdg), 0.0, ratio(getattr(tr, "airspeed", math.nan)),
            math.hypot(_sigma(est, 0), _sigma(est, 1)), _sigma(est, 2)))

    def system_time(self, unix_s: float | None = None) -> bytes:
        """SYSTEM_TIME: wall-clock UTC (us) and the estimate time (ms)."""
        now = time.time() if unix_s is None else unix_s
        return self._p.pack(mavlink2.MAVLink_system_time_message(int(now * 1e6), self.boot_ms()))

    # -- minimal answers so ground stations connect without retry storms --
    def param_value(self, name: str, value: float, index: int, count: int) -> bytes:
        """PARAM_VALUE of a REAL32 parameter."""
        return self._p.pack(mavlink2.MAVLink_param_value_message(
            name.encode()[:16], float(value), int(mavlink2.MAV_PARAM_TYPE_REAL32), count, index))

    def autopilot_version(self) -> bytes:
        """AUTOPILOT_VERSION: MAVLink 2 capable, nothing else claimed."""
        caps = int(mavlink2.MAV_PROTOCOL_CAPABILITY_MAVLINK2)
        return self._p.pack(mavlink2.MAVLink_autopilot_version_message(
            caps, 0, 0, 0, 0, [0] * 8, [0] * 8, [0] * 8, 0, 0, self.system_id))

    def command_ack(self, command: int, result: int, target_system: int,
                    target_component: int) -> bytes:
        """COMMAND_ACK of ``command`` with ``MAV_RESULT`` ``result``."""
        return self._p.pack(mavlink2.MAVLink_command_ack_message(
            command, result, 0, 0, target_system, target_component))

    def ftp_reply(self, target_system: int, target_component: int, request: bytes) -> bytes:
        """FILE_TRANSFER_PROTOCOL answer of a vehicle with an empty, read-only file system.

        ``request`` is the request's 251-byte payload (MAVLink FTP header: seq uint16, session,
        opcode, size, req_opcode, burst_complete, padding, offset uint32, data). The reply has
        seq + 1 and the request's session and opcode (as ``req_opcode``): ACK to
        TerminateSession / ResetSessions, NAK otherwise with one error byte (:data:`_FTP_NAK`):
        FileNotFound for what reads a path, InvalidSession for what uses a session (none is
        ever opened), FileProtected for what would write. So a client that tries FTP first
        (MAVProxy fetches parameters as ``@PARAM/param.pck``) falls back at once instead of
        timing out."""
        seq, session, opcode = int.from_bytes(request[0:2], "little"), request[2], request[3]
        head = bytearray(12)
        head[0:2] = ((seq + 1) % 0x10000).to_bytes(2, "little")
        head[2], head[5] = session, opcode
        if opcode in _FTP_ACK_OPS:
            head[3] = _FTP_ACK
            body = b""
        else:
            head[3], head[4] = _FTP_NAK_OP, 1
            body = bytes([_FTP_NAK.get(opcode, _FTP_ERR_FILE_PROTECTED)])
        payload = list(bytes(head) + body) + [0] * (251 - len(head) - len(body))
        return self._p.pack(mavlink2.MAVLink_file_transfer_protocol_message(
            0, target_system, target_component, payload))

    def mission_count(self, target_system: int, target_component: int, mission_type: int
                      ) -> bytes:
        """MISSION_COUNT of zero items (the shadow vehicle has no mission)."""
        return self._p.pack(mavlink2.MAVLink_mission_count_message(
            target_system, target_component, 0, mission_type))


class CompanionEncoder:
    """Frames a companion computer sends a flight controller: GPS_INPUT or ODOMETRY.

    Parameters
    ----------
    system_id, component_id : int
        Our ids on the flight controller's link (system = the vehicle's).
    """

    def __init__(self, system_id: int, component_id: int) -> None:
        self._p = _Packer(system_id, component_id)
        self._origin: tuple[float, float, float] | None = None

    def gps_input(self, est: NavEstimate, unix_s: float | None = None,
                  gps_id: int = 0) -> bytes:
        """GPS_INPUT (ArduPilot): 3-D fix at the estimate; GPS week/ms from the wall clock.

        Accuracies are the estimate's 1-sigma position (m) and velocity (m/s); the yaw field
        is 0 (= not provided). ``gps_id`` is the GPS instance of type MAVLink that reads it
        (ArduPilot's GPS_TYPE: 0, GPS2_TYPE: 1); the others ignore the frame.
        """
        now = time.time() if unix_s is None else unix_s
        week, week_ms = gps_time(now)
        vn, ve, vd = (float(v) for v in est.v_ned_mps)
        h_acc = math.hypot(_sigma(est, 0), _sigma(est, 1))
        v_acc = _sigma(est, 2)
        s_acc = math.sqrt(sum(_sigma(est, i) ** 2 for i in (3, 4, 5)))
        fix = 3 if est.mode != "initializing" else 0
        return self._p.pack(mavlink2.MAVLink_gps_input_message(
            int(est.time_us), gps_id, 0, week_ms, week, fix,
            _clip(est.lat_rad * DEGE7_PER_RAD, INT32_MIN, INT32_MAX),
            _clip(est.lon_rad * DEGE7_PER_RAD, INT32_MIN, INT32_MAX),
            _f(est.alt_msl_m), 1.0, 1.0, vn, ve, vd, s_acc, h_acc, v_acc, 12, 0))

    def odometry(self, est: NavEstimate) -> bytes:
        """ODOMETRY (PX4): position NED about the first estimate (m), q body->NED, velocity NED
        (m/s), the estimate's variances as covariances.

        Velocity in ``MAV_FRAME_LOCAL_NED``, as estimated: in body axes PX4 would turn it back
        with its own attitude, so its own yaw error (e.g. a magnetometer realignment at
        lift-off) would turn hilnav's velocity with it. Covariances: the upper-right triangles
        (row-major) with the estimate's variances on their diagonals, where PX4 reads them
        (pose: position N/E/D, roll/pitch/yaw; velocity: N/E/D); PX4 takes them as its
        external-vision noise, its ``EKF2_EVP_NOISE`` / ``EKF2_EVV_NOISE`` as lower bounds.
        Unknown variances (not positive, not finite) are sent as a NaN first element.

        ``estimator_type`` VISION: PX4 routes ODOMETRY to its external-vision input only for
        UNKNOWN, NAIVE, VISION and VIO (``MavlinkReceiver::handle_message_odometry``) and drops
        GPS_INS with "ODOMETRY: estimator_type 5 unsupported"; hilnav's estimate is what PX4
        then fuses as external vision (``EKF2_EV_CTRL``)."""
        if self._origin is None:
            self._origin = (est.lat_rad, est.lon_rad, est.alt_msl_m)
        lat0, lon0, alt0 = self._origin
        # ned_offset_m(a, b) = a relative to b
        n, e, d = ned_offset_m(est.lat_rad, est.lon_rad, est.alt_msl_m, lat0, lon0, alt0)
        w, x, y, z = (float(q) for q in est.q_nb)
        vn, ve, vd = (float(v) for v in est.v_ned_mps)
        p_diag = [float(v) for v in est.P_diag[:9]]
        pose = _triangle(p_diag[0:3] + p_diag[6:9])
        vel = _triangle(p_diag[3:6] + [math.nan] * 3)
        return self._p.pack(mavlink2.MAVLink_odometry_message(
            int(est.time_us), int(mavlink2.MAV_FRAME_LOCAL_NED), int(mavlink2.MAV_FRAME_LOCAL_NED),
            float(n), float(e), float(d), [w, x, y, z], vn, ve, vd,
            math.nan, math.nan, math.nan, pose, vel, 0,
            int(mavlink2.MAV_ESTIMATOR_TYPE_VISION), 100))


_DIAGONAL_OF_TRIANGLE = (0, 6, 11, 15, 18, 20)
"""Where a 6x6 covariance's diagonal lies in MAVLink's 21-element upper-right triangle."""


def _triangle(variances: list[float]) -> list[float]:
    """A 21-element upper-right triangle (row-major) with ``variances`` (6; NaN = not given,
    sent as 0) on its diagonal; a NaN first element when one of the given ones is unknown."""
    out = [0.0] * 21
    for i, var in zip(_DIAGONAL_OF_TRIANGLE, variances, strict=True):
        if math.isnan(var):
            continue
        if not (math.isfinite(var) and var > 0.0):
            return [math.nan] + [0.0] * 20
        out[i] = var
    return out
