"""Hostile MAVLink input for the fuzz test and ``bench/fuzz.py``: the simulator's frames of a
synthetic flight, byte mutations, and CRC-valid frames carrying hostile values."""

from __future__ import annotations

import math

import numpy as np

from fusion import earth
from fusion.config import FilterConfig
from fusion.estimate import NavEstimate
from fusion.filter import NavFilter
from hil.codec import SENSOR_COMPONENT_ID, Decoder, Encoder, mavlink2
from sim.samples import BaroSample, GnssFix, ImuSample, MagSample
from tests.helpers.nav_synth import Scenario

NAN, INF = math.nan, math.inf


def encode(samples: list[object]) -> list[tuple[int, bytes]]:
    """``(time_us, frame)`` of every sample, as the simulator sends them."""
    enc = Encoder()
    out = []
    for s in samples:
        if isinstance(s, ImuSample):
            out.append((s.time_us, enc.sensors(s, time_us=s.time_us)))
        elif isinstance(s, BaroSample):
            out.append((s.time_us, enc.sensors(None, s, time_us=s.time_us)))
        elif isinstance(s, MagSample):
            out.append((s.time_us, enc.sensors(None, mag=s, time_us=s.time_us)))
        elif isinstance(s, GnssFix):
            out.append((s.time_us, enc.gnss(s)))
    return out


def sender() -> mavlink2.MAVLink:
    """A MAVLink 2 packer with the simulator's sensor source address (the worst case: source
    binding cannot tell the hostile frames from the real ones)."""
    return mavlink2.MAVLink(None, srcSystem=1, srcComponent=SENSOR_COMPONENT_ID)


def hostile_frame(rng: np.random.Generator, t_us: int, mav: mavlink2.MAVLink) -> bytes:
    """One CRC-valid HIL_SENSOR (60 %) or HIL_GPS with hostile values: NaN, inf, +-1e30,
    timestamps an hour ahead or behind, 2^64 - 1 or 0, latitude / longitude / altitude at the
    int32 limits (214.7 deg, 2,147 km), 327 m/s, unknown or 1 cm accuracies."""

    def pick(options: list[int] | list[float]) -> int | float:
        return options[int(rng.integers(len(options)))]  # plain Python numbers, no numpy

    bad = [NAN, INF, -INF, 1e30, -1e30]
    times = [t_us + 3_600_000_000, max(0, t_us - 3_600_000_000), 2**64 - 1, 0, t_us]
    if rng.random() < 0.6:
        v = [pick(bad) if rng.random() < 0.5 else 0.0 for _ in range(13)]
        return mavlink2.MAVLink_hil_sensor_message(pick(times), *v, 0x1FFF, 0).pack(mav)
    i32 = [2**31 - 1, -(2**31) + 1, 0]
    return mavlink2.MAVLink_hil_gps_message(
        pick(times), 3, pick(i32), pick(i32), pick(i32), pick([1, 65535, 0]), 1,
        pick([65535, 32767]), pick([32767, -32767, 0]), 0, 0, 0, 12, 0, 0).pack(mav)


def mutate(rng: np.random.Generator, frame: bytes) -> bytes:
    """``frame`` with 1-3 random bytes replaced."""
    b = bytearray(frame)
    for _ in range(int(rng.integers(1, 4))):
        b[int(rng.integers(len(b)))] = int(rng.integers(256))
    return bytes(b)


def decode_and_fuse(
    stream: list[bytes], config: FilterConfig
) -> tuple[NavFilter, list[NavEstimate]]:
    """Every frame through a fresh :class:`~hil.codec.Decoder` into a fresh filter."""
    nav, dec = NavFilter(config), Decoder()
    est: list[NavEstimate] = []
    for frame in stream:
        for d in dec.feed(frame):
            est.extend(nav.step(d.sample))
    return nav, est


def horizontal_error_m(sc: Scenario, est: NavEstimate) -> float:
    """Horizontal distance of an estimate from the scenario's truth at its time, m."""
    kin = sc.traj(np.array([est.time_us * 1e-6]))
    d = earth.ned_offset_m(est.lat_rad, est.lon_rad, est.alt_msl_m, *kin.lla[0])
    return float(math.hypot(d[0], d[1]))
