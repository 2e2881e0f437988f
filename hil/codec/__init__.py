"""MAVLink 2 codec: SI sample dataclasses <-> MAVLink frames; the public names of the package.

The only part of hilnav that knows MAVLink's wire units (degE7, mm, cm/s, cdeg, hPa, mG, gauss,
cdegC). Everything it returns is SI.

=============================  ===================================================================
:mod:`hil.codec.wire`          dialect (:data:`mavlink2`), wire units, integer ranges, component ids
:mod:`hil.codec.encoder`       :class:`Encoder`: HIL_SENSOR, HIL_GPS, HIL_STATE_QUATERNION,
                               HIL_ACTUATOR_CONTROLS, RAW_RPM frames
:mod:`hil.codec.decoder`       :class:`Decoder`: stream parsing and dispatch, :class:`Decoded`
:mod:`hil.codec.hil_messages`  decoding of HIL_SENSOR (and HIGHRES_IMU), HIL_GPS,
                               HIL_STATE_QUATERNION
:mod:`hil.codec.fc_messages`   decoding of SCALED_IMU*, RAW_IMU (:class:`RawImuScale`), GPS_RAW_INT,
                               SCALED_PRESSURE*
:mod:`hil.codec.vehicle_messages`  decoding of HIL_ACTUATOR_CONTROLS, SERVO_OUTPUT_RAW
                               (:class:`ServoChannelMap`), RAW_RPM
:mod:`hil.codec.sources`       per-source memory: IMU intervals, temperatures, system times
:mod:`hil.codec.counters`      :class:`DecoderCounters`
=============================  ===================================================================
"""

from __future__ import annotations

from hil.codec.counters import DecoderCounters
from hil.codec.decoder import Decoded, Decoder
from hil.codec.encoder import Encoder
from hil.codec.fc_messages import RawImuScale
from hil.codec.sources import DEFAULT_FIRST_IMU_DT_S
from hil.codec.vehicle_messages import ServoChannel, ServoChannelMap
from hil.codec.wire import (
    AUTOPILOT_COMPONENT_ID,
    DEGE7_PER_RAD,
    FLOAT32_MAX,
    INT16_MAX,
    INT16_MIN,
    INT32_MAX,
    INT32_MIN,
    KELVIN_AT_0_CELSIUS,
    PA_PER_HPA,
    SENSOR_COMPONENT_ID,
    SIM_SYSTEM_ID,
    TESLA_PER_GAUSS,
    TRUTH_COMPONENT_ID,
    UINT8_MAX,
    UINT16_MAX,
    UINT64_MAX,
    HilSensorField,
    mavlink2,
)

__all__ = [
    "AUTOPILOT_COMPONENT_ID",
    "DEFAULT_FIRST_IMU_DT_S",
    "DEGE7_PER_RAD",
    "FLOAT32_MAX",
    "INT16_MAX",
    "INT16_MIN",
    "INT32_MAX",
    "INT32_MIN",
    "KELVIN_AT_0_CELSIUS",
    "PA_PER_HPA",
    "SENSOR_COMPONENT_ID",
    "SIM_SYSTEM_ID",
    "TESLA_PER_GAUSS",
    "TRUTH_COMPONENT_ID",
    "UINT8_MAX",
    "UINT16_MAX",
    "UINT64_MAX",
    "Decoded",
    "Decoder",
    "DecoderCounters",
    "Encoder",
    "HilSensorField",
    "RawImuScale",
    "ServoChannel",
    "ServoChannelMap",
    "mavlink2",
]
