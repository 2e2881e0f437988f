"""Decoder counters: what the decoder saw, every dropped frame or message counted once."""

from __future__ import annotations

from dataclasses import dataclass, fields

__all__ = ["DecoderCounters"]


@dataclass(slots=True)
class DecoderCounters:
    """What the decoder saw. Every frame or message dropped is counted in exactly one place.

    Attributes
    ----------
    frames_ok : CRC-checked frames of known message ids.
    bad_crc : frames with a CRC mismatch (dropped).
    bad_signature : signed frames rejected by a configured signing key (dropped).
    bad_frames : other framing errors: bad length, unknown incompat flags (dropped).
    garbage_bytes : bytes skipped between frames (no start-of-frame marker).
    unknown_msg_id : frames whose id the dialect does not know; their CRC cannot be checked
        (no CRC_EXTRA), so they are dropped.
    truncated : a frame cut by the end of the input (``parse(..., final=True)``).
    ignored_msgs : valid messages that carry no sensor or truth data hilnav decodes.
    samples : SI samples produced.
    incomplete_fields : HIL_SENSOR / HIGHRES_IMU with only part of the accel+gyro or mag bits.
    unscaled_raw_imu : RAW_IMU messages dropped because no :class:`RawImuScale` was given.
    imu_duplicates : IMU messages with the same timestamp as the previous one (dropped).
    imu_time_resets : IMU timestamps that went backwards (source restarted).
    sim_resets : HIL_SENSOR frames with bit 31 ("simulation reset") set.
    controls_clipped : HIL_ACTUATOR_CONTROLS / SERVO_OUTPUT_RAW with a control clipped to its
        range (or an unset slot 4-15 set to 0); the sample is kept.
    controls_invalid : HIL_ACTUATOR_CONTROLS with a non-finite roll/pitch/yaw/throttle, or
        SERVO_OUTPUT_RAW with a mapped output not driven (0 or 65535) (dropped).
    rpm_invalid : RAW_RPM with a negative or non-finite rpm (dropped).
    rpm_untimed : RAW_RPM before any timed message of its system (no time to stamp; dropped).
    bad_diff_pressure : HIL_SENSOR differential pressures (bit 10) that are not finite
        (no AirspeedSample emitted). Finite values pass, negative ones included: a slightly
        negative reading is sensor noise at zero flow, and judging the physics (an absurd
        value, a blocked pitot) is the filter's job, not the codec's.
    """

    frames_ok: int = 0
    bad_crc: int = 0
    bad_signature: int = 0
    bad_frames: int = 0
    garbage_bytes: int = 0
    unknown_msg_id: int = 0
    truncated: int = 0
    ignored_msgs: int = 0
    samples: int = 0
    incomplete_fields: int = 0
    unscaled_raw_imu: int = 0
    imu_duplicates: int = 0
    imu_time_resets: int = 0
    sim_resets: int = 0
    controls_clipped: int = 0
    controls_invalid: int = 0
    rpm_invalid: int = 0
    rpm_untimed: int = 0
    bad_diff_pressure: int = 0

    def as_dict(self) -> dict[str, int]:
        """Counters as a plain dict (for JSON status output)."""
        return {f.name: getattr(self, f.name) for f in fields(self)}
