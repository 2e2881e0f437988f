"""Decoder of what a flight controller reports about its outputs: HIL_ACTUATOR_CONTROLS,
SERVO_OUTPUT_RAW -> ActuatorSample; RAW_RPM -> RpmSample.

HIL_ACTUATOR_CONTROLS (93)
    ``controls[16]`` in PX4's order (roll, pitch, yaw, throttle, flaps, ...; see
    :data:`sim.vehicle_state.CONTROL_INDEX`), ``time_usec``. A non-finite roll, pitch, yaw or
    throttle drops the sample (``controls_invalid``); a non-finite value in slots 4-15 (which
    an autopilot may leave unset) becomes 0, and a finite value outside its range
    (:func:`sim.vehicle_state.control_range`: throttle [0, 1], the rest [-1, 1]) is clipped to
    it; a message with either is counted once in ``controls_clipped``.
SERVO_OUTPUT_RAW (36)
    PWM (us) of outputs 1-16 of ``port`` -> normalised controls through a
    :class:`ServoChannelMap` (default: a typical ArduPlane / PX4 fixed wing, outputs 1 aileron,
    2 elevator, 3 throttle, 4 rudder, 1000-2000 us, trim 1500 us). A bidirectional control is
    ``(pwm - trim) / (max - trim)`` above trim and ``(pwm - trim) / (trim - min)`` below, so
    PWM above trim is positive (ArduPlane's scaled outputs use PX4's signs: aileron + = roll
    right, elevator + = nose up, rudder + = nose right; ``reversed`` undoes a reversed servo);
    the throttle is ``(pwm - min) / (max - min)``. Unmapped controls are 0. A mapped output
    at 0 or 65535 (not driven) drops the sample (``controls_invalid``); PWM outside
    [min, max] is clipped and counted (``controls_clipped``). Other ports are ignored
    (``ignored_msgs``). ``time_usec`` (uint32, wraps after 71.6 min) is unwrapped per source.
RAW_RPM (339)
    ``frequency`` (rev/min) and ``index`` -> RpmSample, stamped with the latest time of its
    system (:attr:`hil.codec.sources.SourceState.last_time_us`; the message has none). Negative
    or non-finite rpm is dropped (``rpm_invalid``), as is an rpm before any timed message of its
    system (``rpm_untimed``).
"""

from __future__ import annotations

import math
import operator
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

from hil.codec.counters import DecoderCounters
from hil.codec.sources import SourceState
from hil.codec.wire import UINT16_MAX
from sim.samples import ActuatorSample, RpmSample
from sim.vehicle_state import CONTROL_INDEX, N_CONTROLS, control_range

__all__ = [
    "ServoChannel",
    "ServoChannelMap",
    "decode_hil_actuator_controls",
    "decode_raw_rpm",
    "decode_servo_output_raw",
]

ControlName = Literal[
    "roll", "pitch", "yaw", "throttle", "flaps", "spoilers", "airbrakes", "landing_gear"
]
_N_REQUIRED = 4  # roll, pitch, yaw, throttle: a sample without them is not a control state
_LOW = tuple(control_range(i)[0] for i in range(N_CONTROLS))
_HIGH = tuple(control_range(i)[1] for i in range(N_CONTROLS))
_le = operator.le


class ServoChannel(BaseModel):
    """One flight-controller output and the control it drives.

    Attributes
    ----------
    output : int
        SERVO_OUTPUT_RAW output number, 1-16 (``servo{output}_raw``).
    control : str
        The control it carries (``roll`` = aileron, ``pitch`` = elevator, ``yaw`` = rudder,
        ``throttle``, ``flaps``, ...).
    pwm_min_us, pwm_trim_us, pwm_max_us : int
        PWM at the control's minimum, neutral and maximum, us (the trim is unused for the
        throttle, whose range is [0, 1]).
    reversed : bool
        The servo is reversed (ArduPilot ``SERVOn_REVERSED``): PWM above trim means a negative
        control (throttle: a higher PWM means less throttle).
    """

    model_config = ConfigDict(frozen=True, extra="forbid")

    output: int = Field(ge=1, le=16)
    control: ControlName
    pwm_min_us: int = Field(default=1000, ge=1, le=UINT16_MAX - 1)
    pwm_trim_us: int = Field(default=1500, ge=1, le=UINT16_MAX - 1)
    pwm_max_us: int = Field(default=2000, ge=1, le=UINT16_MAX - 1)
    reversed: bool = False

    @model_validator(mode="after")
    def _check_pwm(self) -> ServoChannel:
        if self.control == "throttle":
            ok = self.pwm_min_us < self.pwm_max_us
        else:
            ok = self.pwm_min_us < self.pwm_trim_us < self.pwm_max_us
        if not ok:
            raise ValueError(
                f"output {self.output} ({self.control}): need pwm_min_us < pwm_trim_us < "
                f"pwm_max_us (got {self.pwm_min_us}, {self.pwm_trim_us}, {self.pwm_max_us}; "
                "the trim is not used for the throttle)"
            )
        return self

    def normalised(self, pwm_us: int) -> tuple[float, bool]:
        """Control value of ``pwm_us`` and whether it had to be clipped to the range."""
        lo, hi = self.pwm_min_us, self.pwm_max_us
        clipped = not lo <= pwm_us <= hi
        pwm = min(max(pwm_us, lo), hi)
        if self.control == "throttle":
            x = (pwm - lo) / (hi - lo)
            return (1.0 - x if self.reversed else x), clipped
        trim = self.pwm_trim_us
        x = (pwm - trim) / (hi - trim) if pwm >= trim else (pwm - trim) / (trim - lo)
        return (-x if self.reversed else x), clipped


class ServoChannelMap(BaseModel):
    """Which SERVO_OUTPUT_RAW outputs carry which control (see the module docstring).

    Attributes
    ----------
    port : int
        SERVO_OUTPUT_RAW ``port`` decoded (0 = main outputs); other ports are ignored.
    channels : tuple of ServoChannel
        At most one channel per control and per output.
    """

    model_config = ConfigDict(frozen=True, extra="forbid")

    port: int = Field(default=0, ge=0, le=255)
    channels: tuple[ServoChannel, ...] = (
        ServoChannel(output=1, control="roll"),
        ServoChannel(output=2, control="pitch"),
        ServoChannel(output=3, control="throttle"),
        ServoChannel(output=4, control="yaw"),
    )

    @model_validator(mode="after")
    def _check_unique(self) -> ServoChannelMap:
        for attr in ("output", "control"):
            values = [getattr(c, attr) for c in self.channels]
            dupes = sorted({str(v) for v in values if values.count(v) > 1})
            if dupes:
                raise ValueError(f"servo map: {attr} {', '.join(dupes)} mapped more than once")
        return self


def decode_hil_actuator_controls(
    msg: Any, counters: DecoderCounters
) -> list[ActuatorSample]:
    """HIL_ACTUATOR_CONTROLS -> ActuatorSample (see the module docstring for bad values)."""
    raw = list(map(float, msg.controls))
    if all(map(_le, _LOW, raw)) and all(map(_le, raw, _HIGH)) and len(raw) == N_CONTROLS:
        # all finite and in range (NaN fails both comparisons): every value kept as it is
        return [ActuatorSample(int(msg.time_usec), tuple(raw))]
    if not all(math.isfinite(x) for x in raw[:_N_REQUIRED]):
        counters.controls_invalid += 1
        return []
    controls: list[float] = []
    clipped = False
    for i, x in enumerate(raw):
        if not math.isfinite(x):
            controls.append(0.0)
            clipped = True
            continue
        lo, hi = control_range(i)
        if x < lo or x > hi:
            x = lo if x < lo else hi
            clipped = True
        controls.append(x)
    if clipped:
        counters.controls_clipped += 1
    return [ActuatorSample(int(msg.time_usec), tuple(controls))]


def decode_servo_output_raw(
    msg: Any,
    source: tuple[int, int],
    servo_map: ServoChannelMap,
    sources: SourceState,
    counters: DecoderCounters,
) -> list[ActuatorSample]:
    """SERVO_OUTPUT_RAW of ``source`` (system, component) -> ActuatorSample through
    ``servo_map`` (see the module docstring)."""
    if int(msg.port) != servo_map.port:
        counters.ignored_msgs += 1
        return []
    controls = [0.0] * N_CONTROLS
    clipped = False
    for ch in servo_map.channels:
        pwm = int(getattr(msg, f"servo{ch.output}_raw"))
        if pwm in (0, UINT16_MAX):
            counters.controls_invalid += 1
            return []
        value, was_clipped = ch.normalised(pwm)
        controls[CONTROL_INDEX[ch.control]] = value
        clipped |= was_clipped
    if clipped:
        counters.controls_clipped += 1
    time_us = sources.unwrap_u32_us(source, int(msg.time_usec))
    return [ActuatorSample(time_us, tuple(controls))]


def decode_raw_rpm(
    msg: Any, system_id: int, sources: SourceState, counters: DecoderCounters
) -> list[RpmSample]:
    """RAW_RPM -> RpmSample stamped with the latest time of ``system_id``."""
    rpm = float(msg.frequency)
    if not (math.isfinite(rpm) and rpm >= 0.0):
        counters.rpm_invalid += 1
        return []
    time_us = sources.last_time_us.get(system_id)
    if time_us is None:
        counters.rpm_untimed += 1
        return []
    return [RpmSample(time_us, rpm, int(msg.index))]
