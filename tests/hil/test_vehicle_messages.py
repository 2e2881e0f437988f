"""Tests of the vehicle-state messages: HIL_ACTUATOR_CONTROLS, RAW_RPM and SERVO_OUTPUT_RAW.

Real pymavlink bytes both ways (hil.codec.Encoder -> hil.codec.Decoder), bad values clipped or
dropped and counted, the SERVO_OUTPUT_RAW channel map (asymmetric trim, reversed outputs, other
ports), RAW_RPM stamping with its system's latest time, and the link roles' source filtering.
"""

from __future__ import annotations

import math
import struct

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pydantic import ValidationError

from hil.codec import (
    AUTOPILOT_COMPONENT_ID,
    SENSOR_COMPONENT_ID,
    Decoder,
    Encoder,
    ServoChannel,
    ServoChannelMap,
    mavlink2,
)
from hil.link import FC_SENSOR_MSG_IDS, HIL_MSG_IDS, LinkRole
from hil.service import input_role
from sim.samples import ActuatorSample, GnssFix, ImuSample, RpmSample

_HAC = int(mavlink2.MAVLINK_MSG_ID_HIL_ACTUATOR_CONTROLS)
_RPM = int(mavlink2.MAVLINK_MSG_ID_RAW_RPM)
_SERVO = int(mavlink2.MAVLINK_MSG_ID_SERVO_OUTPUT_RAW)


def _f32(xs: tuple[float, ...]) -> tuple[float, ...]:
    return tuple(float(np.float32(x)) for x in xs)


def _imu(time_us: int) -> ImuSample:
    return ImuSample(time_us, 0.005, np.array([0.1, -0.2, -9.8]), np.array([0.01, 0.0, -0.02]))


def _frame(msg: mavlink2.MAVLink_message, sys_id: int = 1,
           comp_id: int = AUTOPILOT_COMPONENT_ID) -> bytes:
    mav = mavlink2.MAVLink(None, srcSystem=sys_id, srcComponent=comp_id)
    frame: bytes = msg.pack(mav)
    return frame


def _hac(controls: list[float], time_us: int = 1_000_000) -> bytes:
    return _frame(mavlink2.MAVLink_hil_actuator_controls_message(time_us, controls, 160, 0))


def _servo(pwm: dict[int, int], time_us: int = 2_000_000, port: int = 0,
           comp_id: int = AUTOPILOT_COMPONENT_ID) -> bytes:
    values = [pwm.get(i, 1500) for i in range(1, 17)]
    msg = mavlink2.MAVLink_servo_output_raw_message(time_us, port, *values)
    return _frame(msg, comp_id=comp_id)


def _rpm(rpm: float, index: int = 0, sys_id: int = 1) -> bytes:
    return _frame(mavlink2.MAVLink_raw_rpm_message(index, rpm), sys_id=sys_id)


# --------------------------------------------------------------- encode -> decode round trip
def test_actuators_and_rpm_round_trip_through_real_bytes() -> None:
    enc, dec = Encoder(system_id=3), Decoder()
    controls = (0.25, -0.5, 0.125, 0.7, 0.3)  # roll, pitch, yaw, throttle, flaps
    frames = [
        enc.sensors(_imu(5_000_000)),
        enc.actuators(ActuatorSample(5_000_000, controls)),
        enc.rpm(RpmSample(5_000_000, 2218.7, 0)),
        enc.rpm(RpmSample(5_000_000, 2201.3, 1)),
    ]
    out = dec.feed(b"".join(frames))
    assert [d.msg_id for d in out] == [mavlink2.MAVLINK_MSG_ID_HIL_SENSOR, _HAC, _RPM, _RPM]
    act, rpm0, rpm1 = (d.sample for d in out[1:])
    assert {(d.system_id, d.component_id) for d in out[1:]} == {(3, AUTOPILOT_COMPONENT_ID)}
    assert isinstance(act, ActuatorSample) and act.time_us == 5_000_000
    assert act.controls == _f32(controls) + (0.0,) * 11  # float32 on the wire, padded to 16
    assert isinstance(rpm0, RpmSample) and isinstance(rpm1, RpmSample)
    assert (rpm0.time_us, rpm0.index, rpm0.rpm) == (5_000_000, 0, float(np.float32(2218.7)))
    assert (rpm1.time_us, rpm1.index, rpm1.rpm) == (5_000_000, 1, float(np.float32(2201.3)))
    msg = dec.mav.decode(bytearray(frames[1]))
    assert msg.mode == mavlink2.MAV_MODE_FLAG_SAFETY_ARMED | mavlink2.MAV_MODE_FLAG_HIL_ENABLED
    assert msg.flags == 0
    c = dec.counters
    assert (c.controls_clipped, c.controls_invalid, c.rpm_invalid, c.rpm_untimed) == (0, 0, 0, 0)
    assert c.samples == 4


def test_encoder_rejects_what_it_cannot_send() -> None:
    enc = Encoder()
    with pytest.raises(ValueError, match="finite"):
        enc.actuators(ActuatorSample(0, (math.nan, 0.0, 0.0, 0.5)))
    with pytest.raises(ValueError, match="at most 16"):
        enc.actuators(ActuatorSample(0, (0.0,) * 17))
    with pytest.raises(ValueError, match=">= 0"):
        enc.rpm(RpmSample(0, -1.0))
    with pytest.raises(ValueError, match="finite"):
        enc.rpm(RpmSample(0, math.inf))
    with pytest.raises(ValueError, match="autopilot_component_id"):
        Encoder(autopilot_component_id=SENSOR_COMPONENT_ID)


def test_each_component_keeps_its_own_sequence() -> None:
    enc, dec = Encoder(), Decoder()
    frames = [enc.sensors(_imu(10_000)), enc.actuators(ActuatorSample(10_000, (0.0,) * 4)),
              enc.sensors(_imu(20_000)), enc.rpm(RpmSample(20_000, 1000.0))]
    seqs = [(m.get_srcComponent(), m.get_seq()) for m in dec.parse(b"".join(frames))]
    assert seqs == [(SENSOR_COMPONENT_ID, 0), (AUTOPILOT_COMPONENT_ID, 0),
                    (SENSOR_COMPONENT_ID, 1), (AUTOPILOT_COMPONENT_ID, 1)]


# ---------------------------------------------------------------- HIL_ACTUATOR_CONTROLS bad values
def test_out_of_range_controls_are_clipped_and_counted() -> None:
    dec = Decoder()
    raw = [1.5, -1.25, 0.5, -0.2, 2.0] + [0.0] * 11
    (d,) = dec.feed(_hac(raw))
    assert isinstance(d.sample, ActuatorSample)
    assert d.sample.controls[:5] == (1.0, -1.0, 0.5, 0.0, 1.0)  # throttle's range is [0, 1]
    assert dec.counters.controls_clipped == 1  # one message, however many values
    (d,) = dec.feed(_hac([0.0, 0.0, 0.0, 1.2] + [0.0] * 12))
    assert isinstance(d.sample, ActuatorSample) and d.sample.controls[3] == 1.0
    assert dec.counters.controls_clipped == 2


@pytest.mark.parametrize("slot", [0, 1, 2, 3])
@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_non_finite_primary_control_drops_the_sample(slot: int, bad: float) -> None:
    dec = Decoder()
    raw = [0.1, 0.2, 0.3, 0.4] + [0.0] * 12
    raw[slot] = bad
    assert dec.feed(_hac(raw)) == []
    assert (dec.counters.controls_invalid, dec.counters.samples) == (1, 0)


def test_non_finite_unused_slot_becomes_zero_and_is_counted() -> None:
    dec = Decoder()
    raw = [0.1, 0.2, 0.3, 0.4] + [math.nan] * 12
    (d,) = dec.feed(_hac(raw))
    assert isinstance(d.sample, ActuatorSample)
    assert d.sample.controls == _f32((0.1, 0.2, 0.3, 0.4)) + (0.0,) * 12
    assert (dec.counters.controls_clipped, dec.counters.controls_invalid) == (1, 0)


_control = st.one_of(st.floats(-1.0, 1.0, width=32), st.floats(width=32),
                     st.sampled_from([0.0, -0.0, 1.0, -1.0, 1.0000001, math.nan, math.inf]))


@settings(max_examples=300, deadline=None)
@given(raw=st.lists(_control, min_size=16, max_size=16))
def test_controls_follow_the_documented_rules(raw: list[float]) -> None:
    """Any 16 values (in range, out of range, NaN, infinite): the sample and the counters are
    the module docstring's rules, applied one value at a time."""
    dec = Decoder()
    got = dec.feed(_hac(raw))
    wire = [float(np.float32(x)) for x in raw]
    if not all(math.isfinite(x) for x in wire[:4]):
        assert got == [] and dec.counters.controls_invalid == 1
        return
    want, clipped = [], False
    for i, x in enumerate(wire):
        lo, hi = (0.0, 1.0) if i == 3 else (-1.0, 1.0)  # throttle [0, 1]
        y = 0.0 if not math.isfinite(x) else min(max(x, lo), hi)
        clipped |= not math.isfinite(x) or y != x
        want.append(y)
    (d,) = got
    assert isinstance(d.sample, ActuatorSample)
    assert [struct.pack("<d", v) for v in d.sample.controls] == [
        struct.pack("<d", v) for v in want]  # bit for bit (the sign of a zero too)
    assert (dec.counters.controls_clipped, dec.counters.controls_invalid) == (int(clipped), 0)


# ------------------------------------------------------------------------------ RAW_RPM
def test_rpm_is_stamped_with_the_latest_time_of_its_system() -> None:
    enc, dec = Encoder(), Decoder()
    assert dec.feed(_rpm(1500.0)) == []  # nothing timed from system 1 yet
    assert dec.counters.rpm_untimed == 1
    dec.feed(enc.sensors(_imu(7_000_000)))  # sensor component, same system
    (d,) = dec.feed(_rpm(1500.0))
    assert isinstance(d.sample, RpmSample) and d.sample.time_us == 7_000_000
    # a GNSS fix is stamped with its (earlier) time of validity: it does not move the clock
    fix = GnssFix(6_900_000, 0.8, 0.14, 1000.0, np.zeros(3), 1.0, 2.0, 0.1)
    dec.feed(enc.gnss(fix))
    (d,) = dec.feed(_rpm(1600.0))
    assert isinstance(d.sample, RpmSample) and d.sample.time_us == 7_000_000
    dec.feed(_hac([0.0] * 16, time_us=7_020_000))
    (d,) = dec.feed(_rpm(1700.0))
    assert isinstance(d.sample, RpmSample) and d.sample.time_us == 7_020_000
    # another system's clock is its own
    assert dec.feed(_rpm(1700.0, sys_id=2)) == []
    assert dec.counters.rpm_untimed == 2


@pytest.mark.parametrize("bad", [-1.0, math.nan, math.inf, -math.inf])
def test_negative_or_non_finite_rpm_is_dropped_and_counted(bad: float) -> None:
    enc, dec = Encoder(), Decoder()
    dec.feed(enc.sensors(_imu(1_000)))
    assert dec.feed(_rpm(bad)) == []
    assert (dec.counters.rpm_invalid, dec.counters.rpm_untimed) == (1, 0)


# ----------------------------------------------------------------------- SERVO_OUTPUT_RAW
def test_servo_output_default_map_of_a_fixed_wing() -> None:
    dec = Decoder()  # ch1 aileron, ch2 elevator, ch3 throttle, ch4 rudder, 1000/1500/2000 us
    (d,) = dec.feed(_servo({1: 2000, 2: 1000, 3: 1250, 4: 1625}, time_us=3_000_000))
    assert d.msg_id == _SERVO and d.component_id == AUTOPILOT_COMPONENT_ID
    assert isinstance(d.sample, ActuatorSample) and d.sample.time_us == 3_000_000
    assert d.sample.controls[:4] == (1.0, -1.0, 0.25, 0.25)
    assert d.sample.controls[4:] == (0.0,) * 12  # unmapped outputs 5-16 carry nothing
    assert dec.counters.controls_clipped == 0


def test_servo_output_asymmetric_trim_and_reversed_channels() -> None:
    servo_map = ServoChannelMap(channels=(
        ServoChannel(output=1, control="roll", pwm_min_us=1100, pwm_trim_us=1400,
                     pwm_max_us=1900),
        ServoChannel(output=2, control="pitch", reversed=True),
        ServoChannel(output=3, control="throttle", pwm_min_us=1100, pwm_max_us=1900,
                     reversed=True),
        ServoChannel(output=7, control="flaps"),
    ))
    dec = Decoder(servo_map=servo_map)
    (d,) = dec.feed(_servo({1: 1250, 2: 1750, 3: 1300, 7: 1600}))
    assert isinstance(d.sample, ActuatorSample)
    roll, pitch, yaw, throttle, flaps = d.sample.controls[:5]
    assert roll == pytest.approx(-0.5, abs=1e-12)  # (1250 - 1400) / (1400 - 1100)
    assert pitch == pytest.approx(-0.5, abs=1e-12)  # above trim, reversed
    assert yaw == 0.0  # not mapped
    assert throttle == pytest.approx(0.75, abs=1e-12)  # 1 - (1300 - 1100) / 800
    assert flaps == pytest.approx(0.2, abs=1e-12)
    (d,) = dec.feed(_servo({1: 1650, 2: 1500, 3: 1900, 7: 1500}))
    assert isinstance(d.sample, ActuatorSample)
    assert d.sample.controls[0] == pytest.approx(0.5, abs=1e-12)  # (1650 - 1400) / 500
    assert d.sample.controls[1] == 0.0 and d.sample.controls[3] == 0.0


def test_servo_output_bad_pwm_clipped_or_dropped_and_counted() -> None:
    dec = Decoder()
    (d,) = dec.feed(_servo({1: 2200, 3: 900}))
    assert isinstance(d.sample, ActuatorSample)
    assert d.sample.controls[0] == 1.0 and d.sample.controls[3] == 0.0
    assert dec.counters.controls_clipped == 1
    assert dec.feed(_servo({2: 0})) == []  # a mapped output not driven
    assert dec.feed(_servo({4: 65535})) == []
    assert dec.counters.controls_invalid == 2
    assert dec.feed(_servo({1: 2000}, port=1)) == []  # an auxiliary port: not mapped
    assert dec.counters.ignored_msgs == 1 and dec.counters.samples == 1


def test_servo_output_time_unwraps_its_uint32_per_source() -> None:
    dec = Decoder()
    times = []
    for t in (2**32 - 20_000, 2**32 - 10_000, 5_000, 15_000):
        (d,) = dec.feed(_servo({}, time_us=t))
        times.append(d.sample.time_us)
    assert times == [2**32 - 20_000, 2**32 - 10_000, 2**32 + 5_000, 2**32 + 15_000]
    (d,) = dec.feed(_servo({}, time_us=1_000, comp_id=2))  # another source: its own clock
    assert d.sample.time_us == 1_000
    (d,) = dec.feed(_servo({}, time_us=10_000))  # a small step back: a restart, not a wrap
    assert d.sample.time_us == 10_000


def test_servo_map_validation() -> None:
    with pytest.raises(ValidationError, match="mapped more than once"):
        ServoChannelMap(channels=(ServoChannel(output=1, control="roll"),
                                  ServoChannel(output=5, control="roll")))
    with pytest.raises(ValidationError, match="mapped more than once"):
        ServoChannelMap(channels=(ServoChannel(output=1, control="roll"),
                                  ServoChannel(output=1, control="yaw")))
    with pytest.raises(ValidationError, match="pwm_min_us < pwm_trim_us"):
        ServoChannel(output=1, control="pitch", pwm_trim_us=2000)
    ServoChannel(output=3, control="throttle", pwm_trim_us=1000)  # the trim is unused
    with pytest.raises(ValidationError):
        ServoChannel(output=17, control="roll")
    with pytest.raises(ValidationError):
        ServoChannel(output=1, control="elevator")  # type: ignore[arg-type]


# ------------------------------------------------------------------------ link filtering
def test_link_roles_accept_the_vehicle_state_like_the_other_messages() -> None:
    fusion = LinkRole.fusion()
    assert {_HAC, _RPM} <= HIL_MSG_IDS and {_SERVO, _RPM} <= FC_SENSOR_MSG_IDS
    assert fusion.accepts_source(1, AUTOPILOT_COMPONENT_ID)
    assert fusion.accepts_msg_id(_HAC) and fusion.accepts_msg_id(_RPM)
    assert not fusion.accepts_source(2, AUTOPILOT_COMPONENT_ID)  # another system
    only_sensors = input_role((1, SENSOR_COMPONENT_ID))  # --source 1:200
    assert not only_sensors.accepts_source(1, AUTOPILOT_COMPONENT_ID)
    whole_vehicle = input_role((1, None))  # --source 1
    assert whole_vehicle.accepts_source(1, AUTOPILOT_COMPONENT_ID)
    assert all(whole_vehicle.accepts_msg_id(i) for i in (_HAC, _RPM, _SERVO))
    companion = LinkRole.companion()
    assert companion.accepts_msg_id(_SERVO) and companion.accepts_msg_id(_RPM)
