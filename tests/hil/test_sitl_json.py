"""ArduPilot SITL JSON interface bytes (hil.autopilot.sitl_json), read back the way ArduPilot's
SIM_JSON parser reads them (tests.helpers.ardupilot_peer.parse_sim_json)."""

from __future__ import annotations

import math
import struct

import numpy as np
import pytest

from hil.autopilot.sitl_json import (
    LATLON_TO_M,
    JsonOrigin,
    ServoPacket,
    encode_servo_packet,
    json_state_line,
    ned_from_origin,
    parse_servo_packet,
)
from sim.samples import ImuSample, Truth
from tests.helpers.ardupilot_peer import parse_sim_json


def _truth(**kw: object) -> Truth:
    half = math.radians(30.0) / 2  # yaw 30 deg, roll 10 deg
    qz = np.array([math.cos(half), 0.0, 0.0, math.sin(half)])
    r = math.radians(10.0) / 2
    qx = np.array([math.cos(r), math.sin(r), 0.0, 0.0])
    w1, x1, y1, z1 = qz
    w2, x2, y2, z2 = qx
    q = np.array([w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2, w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
                  w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2, w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2])
    base: dict[str, object] = dict(
        time_us=12_345_000, lat_rad=math.radians(47.01), lon_rad=math.radians(8.02),
        alt_msl_m=1234.5, v_ned_mps=np.array([40.0, 20.0, -1.5]), q_nb=q,
        omega_b_rps=np.array([0.01, -0.02, 0.05]),
        specific_force_b_mps2=np.array([0.3, 1.7, -9.6]), static_pressure_pa=87000.0,
        temperature_k=280.0, airspeed_mps=48.0, indicated_airspeed_mps=45.0)
    base.update(kw)
    return Truth(**base)  # type: ignore[arg-type]


def test_servo_packets_of_16_and_32_outputs_have_sim_json_layouts() -> None:
    p16 = encode_servo_packet(7, [1100, 1200, 1300], frame_rate_hz=400)
    p32 = encode_servo_packet(8, list(range(1000, 1032)), channels=32)
    assert len(p16) == 40 and len(p32) == 72
    assert struct.unpack_from("<HHI", p16) == (18458, 400, 7)
    assert struct.unpack_from("<HHI", p32)[0] == 29569
    assert parse_servo_packet(p16) == ServoPacket(400, 7, (1100, 1200, 1300, *([0] * 13)))
    assert parse_servo_packet(p32) == ServoPacket(400, 8, tuple(range(1000, 1032)))


@pytest.mark.parametrize(("data", "reason"), [
    (struct.pack("<HHI16H", 12345, 400, 1, *([1500] * 16)), "bad_magic"),
    (struct.pack("<HHI16H", 18458, 400, 1, *([1500] * 16))[:-2], "bad_size"),
    (struct.pack("<HHI32H", 18458, 400, 1, *([1500] * 32)), "bad_size"),
    (struct.pack("<HHI16H", 29569, 400, 1, *([1500] * 16)), "bad_size"),
    (b"\xfd\x09\x00\x00\x00\x01\x01\x00\x00\x00" + bytes(11), "wrong_protocol"),
    (b"\xfe\x09\x00\x01\x01\x00" + bytes(11), "wrong_protocol"),
    (b"\x1a", "bad_size"),
])
def test_bad_packets_say_why(data: bytes, reason: str) -> None:
    assert parse_servo_packet(data) == reason


def test_state_line_reads_back_through_sim_json_parser() -> None:
    truth = _truth()
    origin = JsonOrigin(math.radians(47.0), math.radians(8.0), 0.0)
    line = json_state_line(truth, origin)
    assert line.startswith(b"\n{") and line.endswith(b"}\n") and line.count(b"\n") == 2
    got = parse_sim_json(line.decode("ascii").strip())
    assert got is not None
    assert got["timestamp"] == (12.345,)
    assert got["gyro"] == pytest.approx(truth.omega_b_rps, abs=0)
    assert got["accel_body"] == pytest.approx(truth.specific_force_b_mps2, abs=0)
    assert got["velocity"] == pytest.approx(truth.v_ned_mps, abs=0)
    assert got["quaternion"] == pytest.approx(truth.q_nb, abs=0)
    roll, pitch, yaw = got["attitude"]
    assert (math.degrees(roll), math.degrees(pitch), math.degrees(yaw)) == pytest.approx(
        (10.0, 0.0, 30.0), abs=1e-9)
    assert got["airspeed"] == (45.0,)
    n, e, d = got["position"]
    assert d == pytest.approx(-1234.5)
    assert n == pytest.approx(0.01 * 1e7 * LATLON_TO_M, rel=1e-12)
    assert e == pytest.approx(0.02 * 1e7 * LATLON_TO_M * math.cos(math.radians(47.005)),
                              rel=1e-12)


def test_position_round_trips_through_ardupilots_location_offset() -> None:
    # ArduPilot: lat = home + north / LATLON_TO_M (1e-7 deg); lng = home + east /
    # (LATLON_TO_M * cos(mid latitude)). Our NED must land on our lat/lon again.
    origin = JsonOrigin(math.radians(-33.9), math.radians(151.2), 20.0)
    for dlat, dlon in ((0.1, -0.2), (-0.05, 0.3), (0.0, 0.0)):
        lat, lon = origin.lat_rad + math.radians(dlat), origin.lon_rad + math.radians(dlon)
        n, e, d = ned_from_origin(origin, lat, lon, 520.0)
        lat_e7 = math.degrees(origin.lat_rad) * 1e7 + n / LATLON_TO_M
        mid = math.radians(0.5 * (lat_e7 * 1e-7 + math.degrees(origin.lat_rad)))
        lon_e7 = math.degrees(origin.lon_rad) * 1e7 + e / (LATLON_TO_M * math.cos(mid))
        # 1e-7 deg ~ 1.1 cm: float round-off only
        assert lat_e7 == pytest.approx(math.degrees(lat) * 1e7, abs=1e-4)
        assert lon_e7 == pytest.approx(math.degrees(lon) * 1e7, abs=1e-4)
        assert d == -500.0


def test_a_line_without_a_mandatory_field_is_dropped_like_sim_json() -> None:
    line = json_state_line(_truth(), JsonOrigin(0.0, 0.0)).decode()
    assert parse_sim_json(line.replace('"velocity"', '"speed"')) is None
    no_attitude = line.replace('"quaternion"', '"q"').replace('"attitude"', '"att"')
    assert parse_sim_json(no_attitude) is None
    # a space before a vector breaks SIM_JSON's reader (it skips exactly '":', then
    # sscanf("[%f, %f, %f]") needs the bracket)
    assert parse_sim_json(line.replace('"position":', '"position": ')) is None


def test_the_imu_and_airspeed_can_be_the_sensors_hilnav_fuses() -> None:
    truth = _truth()
    imu = ImuSample(time_us=truth.time_us, dt_s=0.005,
                    specific_force_b_mps2=np.array([0.5, 1.5, -9.0]),
                    angular_rate_b_rps=np.array([0.2, 0.0, -0.1]))
    line = json_state_line(truth, JsonOrigin(0.0, 0.0), imu=imu, airspeed_mps=0.0)
    got = parse_sim_json(line.decode().strip())
    assert got is not None
    assert got["gyro"] == (0.2, 0.0, -0.1) and got["accel_body"] == (0.5, 1.5, -9.0)
    assert got["airspeed"] == (0.0,)  # a blocked pitot reads no airspeed
