"""Decoder of an autopilot's own navigation estimate as its telemetry reports it:
GLOBAL_POSITION_INT, ATTITUDE, LOCAL_POSITION_NED -> SI reports on the autopilot's clock.

GLOBAL_POSITION_INT (33)
    ``lat`` / ``lon`` degE7, ``alt`` mm above MSL, ``vx`` / ``vy`` / ``vz`` cm/s North / East /
    Down, ``hdg`` cdeg (UINT16_MAX: unknown), ``time_boot_ms``.
ATTITUDE (30)
    ``roll`` / ``pitch`` / ``yaw`` rad (yaw in [-pi, pi]), body rates rad/s, ``time_boot_ms``.
LOCAL_POSITION_NED (32)
    ``x`` / ``y`` / ``z`` m and ``vx`` / ``vy`` / ``vz`` m/s NED from the autopilot's local
    origin, ``time_boot_ms``.

Each report carries ``time_us = time_boot_ms * 1000``: the autopilot's time since boot, on its
own clock. Whether that is the simulator's time is the caller's business (in lockstep SITL it
is: see :mod:`hil.autopilot.telemetry`). A report with a non-finite value is refused
(``None``): an estimator that has not converged yet sends NaN attitude in some versions.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hil.codec.wire import DEGE7_PER_RAD, UINT16_MAX

__all__ = [
    "AttitudeReport",
    "LocalPositionReport",
    "PositionReport",
    "decode_attitude",
    "decode_global_position_int",
    "decode_local_position_ned",
]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class PositionReport:
    """The autopilot's global position estimate (GLOBAL_POSITION_INT), SI.

    ``heading_rad`` None: the autopilot did not know it (``hdg`` = UINT16_MAX).
    """

    time_us: int
    lat_rad: float
    lon_rad: float
    alt_msl_m: float
    relative_alt_m: float
    v_ned_mps: FloatArray
    heading_rad: float | None


@dataclass(frozen=True)
class AttitudeReport:
    """The autopilot's attitude estimate (ATTITUDE): roll, pitch, yaw (rad) and body rates."""

    time_us: int
    euler_rad: FloatArray
    rates_rps: FloatArray


@dataclass(frozen=True)
class LocalPositionReport:
    """The autopilot's local position (LOCAL_POSITION_NED) from its own origin, m and m/s."""

    time_us: int
    pos_ned_m: FloatArray
    v_ned_mps: FloatArray


def _finite(*values: float) -> bool:
    return all(math.isfinite(v) for v in values)


def decode_global_position_int(msg: Any) -> PositionReport | None:
    """GLOBAL_POSITION_INT -> PositionReport (``None``: latitude out of range)."""
    lat = msg.lat / DEGE7_PER_RAD
    if not abs(lat) <= math.pi / 2:
        return None
    hdg = int(msg.hdg)
    return PositionReport(
        time_us=int(msg.time_boot_ms) * 1000,
        lat_rad=lat,
        lon_rad=msg.lon / DEGE7_PER_RAD,
        alt_msl_m=msg.alt * 1e-3,
        relative_alt_m=msg.relative_alt * 1e-3,
        v_ned_mps=np.array([msg.vx, msg.vy, msg.vz], dtype=np.float64) * 1e-2,
        heading_rad=None if hdg == UINT16_MAX else math.radians(hdg * 1e-2),
    )


def decode_attitude(msg: Any) -> AttitudeReport | None:
    """ATTITUDE -> AttitudeReport (``None``: a non-finite angle or rate)."""
    angles = (float(msg.roll), float(msg.pitch), float(msg.yaw))
    rates = (float(msg.rollspeed), float(msg.pitchspeed), float(msg.yawspeed))
    if not _finite(*angles, *rates):
        return None
    return AttitudeReport(int(msg.time_boot_ms) * 1000, np.array(angles, dtype=np.float64),
                          np.array(rates, dtype=np.float64))


def decode_local_position_ned(msg: Any) -> LocalPositionReport | None:
    """LOCAL_POSITION_NED -> LocalPositionReport (``None``: a non-finite value)."""
    pos = (float(msg.x), float(msg.y), float(msg.z))
    vel = (float(msg.vx), float(msg.vy), float(msg.vz))
    if not _finite(*pos, *vel):
        return None
    return LocalPositionReport(int(msg.time_boot_ms) * 1000, np.array(pos, dtype=np.float64),
                               np.array(vel, dtype=np.float64))
