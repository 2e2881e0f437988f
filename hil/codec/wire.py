"""MAVLink wire conventions of hilnav: the dialect, wire units, integer ranges, component ids.

This package (:mod:`hil.codec`) is the only part of hilnav that knows MAVLink's wire units
(degE7, mm, cm/s, cdeg, hPa, mG, gauss, cdegC); what it returns is SI (see ``sim.samples`` and
``fusion``'s package docstring for frames and quaternion order).

Dialect
    One explicit dialect module, ``pymavlink.dialects.v20.ardupilotmega`` (a superset of
    ``common``; ArduPilot-specific messages in a real flight controller's stream are then
    "known, ignored" instead of "unknown"), MAVLink 2 framing. The process-global dialect that
    ``pymavlink.mavutil`` picks from environment variables is never used. Import the dialect
    from here (:data:`mavlink2`, also ``hil.codec.mavlink2``) so every hilnav module agrees on
    it. Plus the three messages of MAVLink's standard-modes microservice (AVAILABLE_MODES 435,
    CURRENT_MODE 436, AVAILABLE_MODES_MONITOR 437), which pymavlink 2.4.50 has only in its
    ``development`` dialect (:data:`STANDARD_MODES_DIALECT`): they are added to the dialect's
    id map on import, so links can frame, sign and decode them (ids unused by ardupilotmega;
    the shadow vehicle packs them with the ``development`` classes).

Component ids
    Sensors (HIL_SENSOR, HIL_GPS) come from :data:`SENSOR_COMPONENT_ID` = 200
    (``MAV_COMP_ID_IMU``), truth from :data:`TRUTH_COMPONENT_ID` = 25 (``MAV_COMP_ID_USER1``,
    the private-use range: no autopilot or ground station gives it a meaning, and a consumer
    separates truth from sensors by component). The vehicle state a flight controller reports
    (HIL_ACTUATOR_CONTROLS, RAW_RPM) comes from :data:`AUTOPILOT_COMPONENT_ID` = 1
    (``MAV_COMP_ID_AUTOPILOT1``): in a real HIL setup it is the autopilot (PX4's
    ``simulator_mavlink``) that sends HIL_ACTUATOR_CONTROLS to the simulator, and ArduPilot and
    PX4 send RAW_RPM and SERVO_OUTPUT_RAW from their autopilot component, so a consumer sees the
    simulated vehicle's outputs where a real one would put them. Each component has its own
    sequence counter, as MAVLink requires.
"""

from __future__ import annotations

import math
from typing import Final

import numpy as np
from fastcrc import crc16
from pymavlink.dialects.v20 import ardupilotmega as mavlink2
from pymavlink.dialects.v20 import development as STANDARD_MODES_DIALECT

__all__ = [
    "AUTOPILOT_COMPONENT_ID",
    "CRC_LEN",
    "DEGE7_PER_RAD",
    "FLOAT32_MAX",
    "HEADER_LEN",
    "IFLAG_SIGNED",
    "INT16_MAX",
    "INT16_MIN",
    "INT32_MAX",
    "INT32_MIN",
    "KELVIN_AT_0_CELSIUS",
    "MAGIC_V2",
    "PA_PER_HPA",
    "SENSOR_COMPONENT_ID",
    "SIGNATURE_BLOCK_LEN",
    "STANDARD_MODES_DIALECT",
    "STANDARD_MODE_MSG_IDS",
    "TESLA_PER_GAUSS",
    "TRUTH_COMPONENT_ID",
    "UINT8_MAX",
    "UINT16_MAX",
    "UINT64_MAX",
    "HilSensorField",
    "check_frame",
    "crc_extra",
    "frame_crc",
    "frame_msg_id",
    "mavlink2",
    "mcrf4xx",
]

STANDARD_MODE_MSG_IDS: Final = (
    int(STANDARD_MODES_DIALECT.MAVLINK_MSG_ID_AVAILABLE_MODES),
    int(STANDARD_MODES_DIALECT.MAVLINK_MSG_ID_CURRENT_MODE),
    int(STANDARD_MODES_DIALECT.MAVLINK_MSG_ID_AVAILABLE_MODES_MONITOR),
)
for _msg_id in STANDARD_MODE_MSG_IDS:
    mavlink2.mavlink_map.setdefault(_msg_id, STANDARD_MODES_DIALECT.mavlink_map[_msg_id])

TESLA_PER_GAUSS: Final = 1e-4
PA_PER_HPA: Final = 100.0
KELVIN_AT_0_CELSIUS: Final = 273.15
DEGE7_PER_RAD: Final = 1e7 * 180.0 / math.pi
UINT8_MAX: Final = 0xFF
UINT16_MAX: Final = 0xFFFF
INT16_MIN: Final = -0x8000
INT16_MAX: Final = 0x7FFF
INT32_MIN: Final = -0x8000_0000
INT32_MAX: Final = 0x7FFF_FFFF
UINT64_MAX: Final = 0xFFFF_FFFF_FFFF_FFFF
FLOAT32_MAX: Final = float(np.finfo(np.float32).max)

SIM_SYSTEM_ID: Final = 1  # the simulated vehicle's system id (hilnav sim's frames)
SENSOR_COMPONENT_ID: Final = int(mavlink2.MAV_COMP_ID_IMU)  # 200
TRUTH_COMPONENT_ID: Final = int(mavlink2.MAV_COMP_ID_USER1)  # 25
AUTOPILOT_COMPONENT_ID: Final = int(mavlink2.MAV_COMP_ID_AUTOPILOT1)  # 1


class HilSensorField:
    """Bits of HIL_SENSOR / HIGHRES_IMU ``fields_updated`` (same layout in both messages)."""

    XACC: Final = 1 << 0
    YACC: Final = 1 << 1
    ZACC: Final = 1 << 2
    XGYRO: Final = 1 << 3
    YGYRO: Final = 1 << 4
    ZGYRO: Final = 1 << 5
    XMAG: Final = 1 << 6
    YMAG: Final = 1 << 7
    ZMAG: Final = 1 << 8
    ABS_PRESSURE: Final = 1 << 9
    DIFF_PRESSURE: Final = 1 << 10
    PRESSURE_ALT: Final = 1 << 11
    TEMPERATURE: Final = 1 << 12
    SIM_RESET: Final = 1 << 31
    ACCEL: Final = XACC | YACC | ZACC
    GYRO: Final = XGYRO | YGYRO | ZGYRO
    IMU: Final = ACCEL | GYRO
    MAG: Final = XMAG | YMAG | ZMAG
    BARO: Final = ABS_PRESSURE | PRESSURE_ALT | TEMPERATURE


# --- MAVLink 2 frame layout (framing, signing, links) ---------------------------------------
MAGIC_V2: Final = 0xFD
HEADER_LEN: Final = 10
"""magic, len, incompat_flags, compat_flags, seq, sysid, compid, msgid (3 bytes)."""
CRC_LEN: Final = 2
SIGNATURE_BLOCK_LEN: Final = 13
"""link_id (1) + timestamp (6) + signature (6)."""
IFLAG_SIGNED: Final = 0x01

mcrf4xx: Final = crc16.mcrf4xx
"""MAVLink's X.25 CRC (CRC-16/MCRF4XX) of bytes, optionally continuing from ``initial``
(what pymavlink uses when ``fastcrc`` is installed)."""


_CRC_EXTRA: Final = {
    int(msg_id): int(msg_type.crc_extra) for msg_id, msg_type in mavlink2.mavlink_map.items()
}


def crc_extra(msg_id: int) -> int | None:
    """CRC_EXTRA seed of a message id in hilnav's dialect; None for an unknown id."""
    return _CRC_EXTRA.get(msg_id)


def frame_crc(frame: bytes | bytearray | memoryview, payload_len: int, extra: int) -> int:
    """X.25 CRC of a MAVLink 2 frame: header (without magic) and payload, then CRC_EXTRA.

    Parameters
    ----------
    frame : bytes-like
        The frame from its magic byte on (at least ``HEADER_LEN + payload_len`` bytes).
    payload_len : int
        Payload length, bytes (the header's ``len``).
    extra : int
        The message's CRC_EXTRA (:func:`crc_extra`).

    Returns
    -------
    int
        The 16-bit CRC as it must appear (little endian) after the payload.
    """
    return mcrf4xx(bytes((extra,)), mcrf4xx(frame[1 : HEADER_LEN + payload_len]))


def check_frame(frame: bytes | bytearray) -> tuple[int, bool]:
    """Validate the layout of one whole MAVLink 2 frame (not its CRC).

    Returns
    -------
    tuple of (int, bool)
        Payload length in bytes, and whether the frame is signed.

    Raises
    ------
    ValueError
        Wrong magic, or a length that disagrees with the header.
    """
    if len(frame) < HEADER_LEN + CRC_LEN or frame[0] != MAGIC_V2:
        raise ValueError("not a MAVLink 2 frame (magic 0xFD, at least 12 bytes)")
    payload_len = frame[1]
    signed = bool(frame[2] & IFLAG_SIGNED)
    want = HEADER_LEN + payload_len + CRC_LEN + (SIGNATURE_BLOCK_LEN if signed else 0)
    if len(frame) != want:
        raise ValueError(f"MAVLink 2 frame of {len(frame)} bytes, its header says {want}")
    return payload_len, signed


def frame_msg_id(frame: bytes | bytearray) -> int:
    """Message id of a MAVLink 2 frame (24 bits, little endian in header bytes 7..9)."""
    return int(frame[7]) | (int(frame[8]) << 8) | (int(frame[9]) << 16)
