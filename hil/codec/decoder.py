"""The MAVLink decoder: parses a byte stream, counts what it drops, and dispatches each sensor
or truth message to its decoder.

Messages of our simulator go to :mod:`hil.codec.hil_messages`, those of a real flight
controller to :mod:`hil.codec.fc_messages`, and the vehicle's outputs (HIL_ACTUATOR_CONTROLS,
SERVO_OUTPUT_RAW, RAW_RPM) to :mod:`hil.codec.vehicle_messages`; IMU intervals, temperatures
and each system's latest time (which stamps RAW_RPM) are remembered per source
(:mod:`hil.codec.sources`). Everything dropped is counted in :class:`DecoderCounters`.

Framing is :class:`hil.codec.framing.FrameParser`, the live links' resynchronising parser:
after a damaged or cut frame the next good one is found at its start-of-frame marker, so the
damage costs only that frame (pymavlink's own byte parser could lose many good frames after
it). Each CRC-valid frame (MAVLink 2, or MAVLink 1 from a mixed link) is then decoded by
pymavlink, which also checks a configured signing key.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from itertools import chain
from operator import itemgetter
from typing import Any, NamedTuple

from hil.codec.counters import DecoderCounters
from hil.codec.fast_frames import FAST_LAYOUTS, FastLayout
from hil.codec.fc_messages import (
    SCALED_IMU_IDS,
    SCALED_PRESSURE_IDS,
    RawImuScale,
    decode_gps_raw_int,
    decode_raw_imu,
    decode_scaled_imu,
    decode_scaled_pressure,
)
from hil.codec.framing import FrameParser
from hil.codec.hil_messages import (
    HIL_GPS_VALUES,
    HIL_STATE_QUATERNION_WIRE,
    decode_hil_gps,
    decode_hil_gps_values,
    decode_hil_sensor,
    decode_hil_sensor_values,
    decode_hil_state_quaternion,
    decode_hil_state_quaternion_wire,
)
from hil.codec.sources import DEFAULT_FIRST_IMU_DT_S, SourceState
from hil.codec.vehicle_messages import (
    ServoChannelMap,
    decode_hil_actuator_controls,
    decode_raw_rpm,
    decode_servo_output_raw,
)
from hil.codec.wire import MAGIC_V2, mavlink2
from sim.samples import Sample, Truth

__all__ = ["Decoded", "Decoder"]

# Messages whose time does not tell the system's current time: GNSS fixes carry their (earlier)
# time of validity, RAW_RPM carries none.
_NOT_CLOCK_IDS = frozenset({
    mavlink2.MAVLINK_MSG_ID_HIL_GPS,
    mavlink2.MAVLINK_MSG_ID_GPS_RAW_INT,
    mavlink2.MAVLINK_MSG_ID_RAW_RPM,
})


# The fast HIL_SENSOR decode reads its unpacked fields by position.
if FAST_LAYOUTS[mavlink2.MAVLINK_MSG_ID_HIL_SENSOR].fields._fields[:7] + (
        FAST_LAYOUTS[mavlink2.MAVLINK_MSG_ID_HIL_SENSOR].fields._fields[14:]) != (
        "time_usec", "xacc", "yacc", "zacc", "xgyro", "ygyro", "zgyro", "fields_updated", "id"):
    raise ImportError("HIL_SENSOR's field order changed in the dialect")

# The fast HIL_STATE_QUATERNION decode takes the unpacked wire values as they are.
if FAST_LAYOUTS[mavlink2.MAVLINK_MSG_ID_HIL_STATE_QUATERNION].wire_fields != (
        HIL_STATE_QUATERNION_WIRE):
    raise ImportError("HIL_STATE_QUATERNION's wire order changed in the dialect")

_new_decoded = tuple.__new__  # Decoded(...) without the named tuple's Python-level __new__
_Samples = list[Sample | Truth]
_Handler = Callable[[Any, int, int, int], _Samples]


class Decoded(NamedTuple):
    """One SI sample decoded from a MAVLink message, with where it came from (a named tuple:
    one is made per sample, and a tuple is the cheapest immutable record to make)."""

    sample: Sample | Truth
    system_id: int
    component_id: int
    msg_id: int


class Decoder:
    """Parse a MAVLink byte stream and turn sensor and truth messages into SI samples.

    Stateful: it keeps partial frames between :meth:`feed` calls, the previous IMU timestamp
    of each source (to infer ``ImuSample.dt_s``) and the last temperature of each HIL_SENSOR /
    HIGHRES_IMU source.

    Parameters
    ----------
    imu_dt_s : float, optional
        ``dt_s`` given to the first IMU sample of each source (> 0). Default
        :data:`DEFAULT_FIRST_IMU_DT_S` (0.0: unknown interval).
    raw_imu_scale : RawImuScale, optional
        Enables RAW_IMU decoding; without it RAW_IMU is counted and dropped.
    servo_map : ServoChannelMap, optional
        Outputs of SERVO_OUTPUT_RAW and the controls they carry; default
        ``ServoChannelMap()`` (a typical fixed wing: 1 aileron, 2 elevator, 3 throttle,
        4 rudder, 1000/1500/2000 us).

    Attributes
    ----------
    counters : DecoderCounters
    mav : pymavlink MAVLink
        Decodes the framed messages. Configure signing on ``mav.signing`` to reject
        unsigned or badly signed frames.
    """

    def __init__(
        self,
        *,
        imu_dt_s: float | None = None,
        raw_imu_scale: RawImuScale | None = None,
        servo_map: ServoChannelMap | None = None,
    ) -> None:
        if imu_dt_s is not None and not (math.isfinite(imu_dt_s) and imu_dt_s > 0.0):
            raise ValueError(f"imu_dt_s must be a finite number > 0, got {imu_dt_s!r}")
        first_dt_s = DEFAULT_FIRST_IMU_DT_S if imu_dt_s is None else float(imu_dt_s)
        self._raw_imu_scale = raw_imu_scale
        self.servo_map = servo_map if servo_map is not None else ServoChannelMap()
        self.mav = mavlink2.MAVLink(None, srcSystem=0, srcComponent=0)
        self.counters = DecoderCounters()
        self._framer = FrameParser(self.counters)
        self._sources = SourceState(first_dt_s)
        self._handlers = self._handler_table()
        self._fast = self._fast_table()

    # -- bytes -> messages --
    def parse(self, data: bytes, *, final: bool = False) -> list[Any]:
        """Parse bytes into valid pymavlink messages of known ids; count and drop the rest.

        Parameters
        ----------
        data : bytes
            Any slice of a MAVLink byte stream; an incomplete trailing frame is kept for the
            next call.
        final : bool
            No more bytes follow: an incomplete trailing frame is counted as truncated.

        Returns
        -------
        list of pymavlink MAVLink_message
        """
        out = []
        for frame in self._framer.feed(data, final=final):
            msg = self._decode_frame(frame)
            if msg is not None:
                out.append(msg)
        return out

    def _decode_frame(self, frame: bytes) -> Any | None:
        """One framed message through pymavlink (signature checked), or None (counted)."""
        try:
            msg = self.mav.decode(bytearray(frame))
        except mavlink2.MAVError as err:  # signature (or a length pymavlink refuses)
            if "signature" in str(err):
                self.counters.bad_signature += 1
            else:
                self.counters.bad_frames += 1
            return None
        return msg if self._accept(msg) else None

    def _accept(self, msg: Any) -> bool:
        msg_id = msg.get_msgId()
        if msg_id == mavlink2.MAVLINK_MSG_ID_BAD_DATA:
            reason = str(getattr(msg, "reason", ""))
            if reason == "Bad prefix":
                self.counters.garbage_bytes += len(msg.data)
            elif "CRC" in reason:
                self.counters.bad_crc += 1
            elif "signature" in reason:
                self.counters.bad_signature += 1
            else:
                self.counters.bad_frames += 1
            return False
        if msg_id == mavlink2.MAVLINK_MSG_ID_UNKNOWN:
            self.counters.unknown_msg_id += 1
            return False
        self.counters.frames_ok += 1
        return True

    def feed(self, data: bytes) -> list[Decoded]:
        """Parse bytes and decode every sensor / truth message in them.

        Unsigned HIL_SENSOR and HIL_GPS frames, while no signing key is configured, take
        :mod:`hil.codec.fast_frames` (the same field values as pymavlink's decode, without its
        second CRC check and message object); every other frame goes through :meth:`parse`'s
        pymavlink path. Counters and samples are the same either way.

        Parameters
        ----------
        data : bytes
            Any slice of a MAVLink byte stream (partial frames are kept for the next call).

        Returns
        -------
        list of Decoded
            In stream order; one message may give several samples (HIL_SENSOR: IMU, mag, baro).
        """
        return self._decode_frames(self._framer.feed(data))

    def feed_all(self, chunks: Iterable[bytes]) -> list[Decoded]:
        """:meth:`feed` of each chunk in turn, in one call: the same samples, in the same order,
        and the same counters as one :meth:`feed` per chunk (a lockstep batch of frames is
        decoded without a Python call, a list and the signing check per frame)."""
        return self._decode_frames(chain.from_iterable(map(self._framer.feed, chunks)))

    def _decode_frames(self, frames: Iterable[bytes]) -> list[Decoded]:
        """The samples of framed messages (:class:`FrameParser` output), in order."""
        fast = self.mav.signing.secret_key is None
        fast_get, counters = self._fast.get, self.counters
        out: list[Decoded] = []
        extend = out.extend
        for frame in frames:
            if fast and frame[0] == MAGIC_V2 and frame[2] == 0:
                fast_decode = fast_get(frame[7] | (frame[8] << 8) | (frame[9] << 16))
                if fast_decode is not None:
                    counters.frames_ok += 1
                    extend(fast_decode(frame))
                    continue
            msg = self._decode_frame(frame)
            if msg is not None:
                extend(self._decode(msg))
        return out

    def decode_message(self, msg: Any) -> list[Decoded]:
        """Decode one pymavlink message object (e.g. from ``mavutil`` or a tlog reader).

        Bad-data and unknown-id placeholders are counted and give no sample.

        Parameters
        ----------
        msg : pymavlink MAVLink_message

        Returns
        -------
        list of Decoded
        """
        if not self._accept(msg):
            return []
        return self._decode(msg)

    # -- messages -> samples --
    def _decode(self, msg: Any) -> list[Decoded]:
        return self._decode_fields(
            msg.get_msgId(), msg.get_srcSystem(), msg.get_srcComponent(), msg
        )

    def _decode_fields(self, msg_id: int, sys_id: int, comp_id: int, msg: Any) -> list[Decoded]:
        """Samples of one message given as anything with its fields as attributes (a
        pymavlink message or a :mod:`hil.codec.fast_frames` named tuple)."""
        handler = self._handlers.get(msg_id)
        if handler is None:
            self.counters.ignored_msgs += 1
            return []
        return self._wrap(handler(msg, msg_id, sys_id, comp_id), msg_id, sys_id, comp_id)

    def _wrap(self, samples: _Samples, msg_id: int, sys_id: int, comp_id: int) -> list[Decoded]:
        """The samples of one message as :class:`Decoded`, counted; the system's clock."""
        if not samples:
            return []
        if msg_id not in _NOT_CLOCK_IDS:  # the system's clock, for RAW_RPM
            self._sources.last_time_us[sys_id] = samples[-1].time_us
        self.counters.samples += len(samples)
        if len(samples) == 1:  # most messages
            return [_new_decoded(Decoded, (samples[0], sys_id, comp_id, msg_id))]
        return [_new_decoded(Decoded, (s, sys_id, comp_id, msg_id)) for s in samples]

    def _fast_table(self) -> dict[int, Callable[[bytes], list[Decoded]]]:
        """Message id -> decoder of an unsigned MAVLink 2 frame (CRC checked) of the
        :mod:`hil.codec.fast_frames` messages, through their fast unpack: HIL_SENSOR straight
        to its samples, the others through their handler."""
        sources, counters, wrap = self._sources, self.counters, self._wrap
        sensor_id = mavlink2.MAVLINK_MSG_ID_HIL_SENSOR
        unpack_sensor = FAST_LAYOUTS[sensor_id].unpack

        def hil_sensor(frame: bytes) -> list[Decoded]:
            fields = unpack_sensor(frame)
            sys_id, comp_id = frame[5], frame[6]
            # wire order = field order: time, 3 accel, 3 gyro, ..., fields_updated, id
            samples = decode_hil_sensor_values(
                fields, fields[0], fields[14], fields[1:4], fields[4:7],
                (sys_id, comp_id, sensor_id, fields[15]), sources, counters)
            return wrap(samples, sensor_id, sys_id, comp_id)

        gps_id = mavlink2.MAVLINK_MSG_ID_HIL_GPS
        gps_layout = FAST_LAYOUTS[gps_id]
        unpack_gps = gps_layout.unpack_wire
        # HIL_GPS has no array field: its wire values are the named fields, picked by name
        pick_gps = itemgetter(*(gps_layout.wire_fields.index(n) for n in HIL_GPS_VALUES))

        def hil_gps(frame: bytes) -> list[Decoded]:
            fix = decode_hil_gps_values(*pick_gps(unpack_gps(frame)))
            return wrap([fix], gps_id, frame[5], frame[6])

        truth_id = mavlink2.MAVLINK_MSG_ID_HIL_STATE_QUATERNION
        unpack_truth = FAST_LAYOUTS[truth_id].unpack_wire

        def hil_state_quaternion(frame: bytes) -> list[Decoded]:
            truth = decode_hil_state_quaternion_wire(unpack_truth(frame))
            return wrap([truth], truth_id, frame[5], frame[6])

        def through_handler(msg_id: int, layout: FastLayout) -> Callable[[bytes], list[Decoded]]:
            unpack, handler = layout.unpack, self._handlers[msg_id]
            return lambda frame: wrap(handler(unpack(frame), msg_id, frame[5], frame[6]),
                                      msg_id, frame[5], frame[6])

        table = {i: through_handler(i, layout) for i, layout in FAST_LAYOUTS.items()}
        table[sensor_id] = hil_sensor
        table[gps_id] = hil_gps
        table[truth_id] = hil_state_quaternion
        return table

    def _handler_table(self) -> dict[int, _Handler]:
        """Message id -> its decoder, as ``(msg, msg_id, sys_id, comp_id) -> samples``."""
        sources, counters = self._sources, self.counters

        def hil_sensor(msg: Any, msg_id: int, sys_id: int, comp_id: int) -> _Samples:
            return decode_hil_sensor(msg, (sys_id, comp_id, msg_id, int(msg.id)), sources,
                                     counters)

        def scaled_imu(msg: Any, msg_id: int, sys_id: int, comp_id: int) -> _Samples:
            key = (sys_id, comp_id, msg_id, SCALED_IMU_IDS[msg_id])
            return decode_scaled_imu(msg, key, sources, counters)

        def raw_imu(msg: Any, msg_id: int, sys_id: int, comp_id: int) -> _Samples:
            key = (sys_id, comp_id, msg_id, int(msg.id))
            return decode_raw_imu(msg, key, sources, counters, self._raw_imu_scale)

        def scaled_pressure(msg: Any, msg_id: int, sys_id: int, comp_id: int) -> _Samples:
            return [decode_scaled_pressure(msg, SCALED_PRESSURE_IDS[msg_id])]

        def servo_output_raw(msg: Any, msg_id: int, sys_id: int, comp_id: int) -> _Samples:
            return [*decode_servo_output_raw(msg, (sys_id, comp_id), self.servo_map, sources,
                                             counters)]

        ids = mavlink2
        table: dict[int, _Handler] = {
            ids.MAVLINK_MSG_ID_HIL_SENSOR: hil_sensor,
            ids.MAVLINK_MSG_ID_HIGHRES_IMU: hil_sensor,
            ids.MAVLINK_MSG_ID_HIL_GPS: lambda msg, *_: [decode_hil_gps(msg)],
            ids.MAVLINK_MSG_ID_HIL_STATE_QUATERNION:
                lambda msg, *_: [decode_hil_state_quaternion(msg)],
            ids.MAVLINK_MSG_ID_RAW_IMU: raw_imu,
            ids.MAVLINK_MSG_ID_GPS_RAW_INT: lambda msg, *_: [decode_gps_raw_int(msg)],
            ids.MAVLINK_MSG_ID_HIL_ACTUATOR_CONTROLS:
                lambda msg, *_: [*decode_hil_actuator_controls(msg, counters)],
            ids.MAVLINK_MSG_ID_SERVO_OUTPUT_RAW: servo_output_raw,
            ids.MAVLINK_MSG_ID_RAW_RPM:
                lambda msg, _id, sys_id, _c: [*decode_raw_rpm(msg, sys_id, sources, counters)],
        }
        table.update(dict.fromkeys(SCALED_IMU_IDS, scaled_imu))
        table.update(dict.fromkeys(SCALED_PRESSURE_IDS, scaled_pressure))
        return table
