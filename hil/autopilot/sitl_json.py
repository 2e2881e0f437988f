"""ArduPilot SITL's JSON physics interface, the bytes: servo packets in, JSON state lines out.

Written from ArduPilot's ``libraries/SITL/SIM_JSON.cpp`` / ``SIM_JSON.h`` and
``libraries/SITL/examples/JSON/readme.md`` (read, not copied).

Servo packet (ArduPilot -> physics, one UDP datagram per ArduPilot physics frame, little-endian
as on every SITL host)::

    uint16 magic        18458 (16 outputs) | 29569 (32 outputs, SERVO_32_ENABLE = 1)
    uint16 frame_rate   Hz, SIM_RATE_HZ: the step ArduPilot would like (we fly our own rate)
    uint32 frame_count  +1 per new frame; the same count again = a resend (ArduPilot resends
                        after 1 s without a reply); smaller = ArduPilot restarted
    uint16 pwm[16|32]   us

    40 bytes (16 outputs) or 72 bytes (32 outputs).

State line (physics -> ArduPilot, to the address the packet came from): one JSON object
preceded and terminated by ``\\n``. SIM_JSON's parser is not a JSON parser: it finds each key
with ``strstr`` and reads the value right after ``"key":`` (so no space after the colon, and
vectors as ``[x,y,z]``), so no key may be a prefix of an earlier key (we send no
``velocity_wind``, whose name starts with ``velocity``). Fields (SI, ArduPilot's frames):

    ==============  ==========================================================================
    timestamp       simulated time since the flight start, s (``Truth.time_us`` / 1e6).
                    ArduPilot's clock is this time: SIM_JSON's ``recv_fdm`` adds
                    ``timestamp - last_timestamp`` (``last_timestamp`` starting at 0) to the
                    aircraft's ``time_now_us`` (0 at construction, ``SIM_Aircraft``), and
                    lockstep SITL's HAL clock is stopped at ``time_now_us``; so its
                    ``time_boot_ms`` x 1000 = our ``time_usec`` (to the ms). After a restart
                    ArduPilot's clock jumps straight to our current timestamp
    imu.gyro        body rates FRD, rad/s: the step's IMU sample (hilnav's IMU model and the
                    scenario's IMU faults, as our fusion gets them; the truth without one)
    imu.accel_body  specific force FRD, m/s^2 (about [0, 0, -9.8] level), the same way
    position        NED from the origin, m (down = -(alt MSL - origin alt)); ArduPilot turns
                    it into lat/lon with ``Location::offset`` from its home, so the origin
                    must be ArduPilot's home (``--home LAT,LON,ALT,HDG``)
    quaternion      [w, x, y, z] body -> NED (ArduPilot's q1..q4); used when present
    attitude        [roll, pitch, yaw] rad (for ArduPilot versions without ``quaternion``)
    velocity        NED, m/s (ground velocity)
    airspeed        calibrated airspeed of the latest pitot sample (pitot faults included),
                    else the truth's indicated airspeed, m/s: ArduPilot's simulated pitot
                    turns it into a differential pressure
    ==============  ==========================================================================

ArduPilot simulates its own barometer (from the position), compass (from the attitude), and
GPS (from the position, with its SIM_GPS* parameters: :mod:`sim.faults.ardupilot`).
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass
from typing import Final

from sim.faults.ardupilot import LATLON_TO_M
from sim.samples import ImuSample, Truth

__all__ = [
    "LATLON_TO_M",
    "SERVO_MAGIC_16",
    "SERVO_MAGIC_32",
    "JsonOrigin",
    "ServoPacket",
    "encode_servo_packet",
    "json_state_line",
    "ned_from_origin",
    "parse_servo_packet",
]

SERVO_MAGIC_16: Final = 18458
SERVO_MAGIC_32: Final = 29569
_PACKET_16 = struct.Struct("<HHI16H")
_PACKET_32 = struct.Struct("<HHI32H")
PACKET_SIZES: Final = {SERVO_MAGIC_16: _PACKET_16.size, SERVO_MAGIC_32: _PACKET_32.size}
"""Magic -> packet size, bytes (40, 72)."""
_MAVLINK_STX = (0xFD, 0xFE)


@dataclass(frozen=True, slots=True)
class ServoPacket:
    """One decoded servo packet."""

    frame_rate_hz: int
    frame_count: int
    pwm_us: tuple[int, ...]


def parse_servo_packet(data: bytes) -> ServoPacket | str:
    """A servo packet, or why not: ``"bad_magic"``, ``"bad_size"`` (a known magic with the
    wrong length) or ``"wrong_protocol"`` (MAVLink bytes: starts with 0xFD / 0xFE)."""
    if len(data) < 2:
        return "bad_size"
    magic = int.from_bytes(data[:2], "little")
    layout = {SERVO_MAGIC_16: _PACKET_16, SERVO_MAGIC_32: _PACKET_32}.get(magic)
    if layout is None:
        return "wrong_protocol" if data[0] in _MAVLINK_STX else "bad_magic"
    if len(data) != layout.size:
        return "bad_size"
    _, rate, count, *pwm = layout.unpack(data)
    return ServoPacket(rate, count, tuple(pwm))


def encode_servo_packet(frame_count: int, pwm_us: list[int], *, frame_rate_hz: int = 400,
                        channels: int = 16) -> bytes:
    """What ArduPilot sends (for protocol peers and tests): ``channels`` 16 or 32."""
    if channels not in (16, 32):
        raise ValueError(f"channels must be 16 or 32, got {channels}")
    pwm = [*pwm_us[:channels], *([0] * (channels - len(pwm_us)))]
    layout, magic = (_PACKET_16, SERVO_MAGIC_16) if channels == 16 else (_PACKET_32,
                                                                         SERVO_MAGIC_32)
    return layout.pack(magic, frame_rate_hz, frame_count & 0xFFFF_FFFF, *pwm)


@dataclass(frozen=True, slots=True)
class JsonOrigin:
    """ArduPilot's home: the origin of the JSON ``position`` (rad, rad, m MSL)."""

    lat_rad: float
    lon_rad: float
    alt_msl_m: float = 0.0


def ned_from_origin(origin: JsonOrigin, lat_rad: float, lon_rad: float,
                    alt_msl_m: float) -> tuple[float, float, float]:
    """North, east, down from ``origin``, m, the inverse of ArduPilot's flat-earth
    ``Location::offset`` (latitude scale ``LATLON_TO_M`` per 1e-7 deg, longitude scaled by
    the cosine of the mid latitude), so ArduPilot's lat/lon equal ours to well below 1 mm
    within tens of km."""
    dlat_e7 = math.degrees(lat_rad - origin.lat_rad) * 1e7
    dlon_e7 = math.degrees(lon_rad - origin.lon_rad) * 1e7
    mid_lat = 0.5 * (lat_rad + origin.lat_rad)
    north = dlat_e7 * LATLON_TO_M
    east = dlon_e7 * LATLON_TO_M * max(math.cos(mid_lat), 0.01)
    return north, east, origin.alt_msl_m - alt_msl_m


def json_state_line(truth: Truth, origin: JsonOrigin, *, imu: ImuSample | None = None,
                    airspeed_mps: float | None = None) -> bytes:
    """The state line ArduPilot reads for ``truth`` (see the module docstring): its IMU is
    ``imu`` (the IMU sample hilnav's own fusion gets, faults included) or else the truth's
    rates and specific force; its airspeed ``airspeed_mps`` (the pitot's calibrated
    airspeed) or else the truth's indicated airspeed."""
    n, e, d = ned_from_origin(origin, truth.lat_rad, truth.lon_rad, truth.alt_msl_m)
    w, x, y, z = (float(v) for v in truth.q_nb)
    roll = math.atan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
    pitch = math.asin(max(-1.0, min(1.0, 2.0 * (w * y - z * x))))
    yaw = math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    g = truth.omega_b_rps if imu is None else imu.angular_rate_b_rps
    f = truth.specific_force_b_mps2 if imu is None else imu.specific_force_b_mps2
    v = truth.v_ned_mps
    airspeed = truth.indicated_airspeed_mps if airspeed_mps is None else airspeed_mps
    return (
        f'\n{{"timestamp":{truth.time_us / 1e6!r},'
        f'"imu":{{"gyro":[{float(g[0])!r},{float(g[1])!r},{float(g[2])!r}],'
        f'"accel_body":[{float(f[0])!r},{float(f[1])!r},{float(f[2])!r}]}},'
        f'"position":[{n!r},{e!r},{d!r}],'
        f'"quaternion":[{w!r},{x!r},{y!r},{z!r}],'
        f'"attitude":[{roll!r},{pitch!r},{yaw!r}],'
        f'"velocity":[{float(v[0])!r},{float(v[1])!r},{float(v[2])!r}],'
        f'"airspeed":{float(airspeed)!r}}}\n'
    ).encode("ascii")
