"""Benchmark: MAVLink codec cost per HIL_SENSOR / HIL_GPS frame, CPU time.

    python bench/codec_speed.py        # writes bench/results/codec_speed.json

For each message (HIL_SENSOR with IMU fields only, HIL_SENSOR with IMU + mag + baro +
diff_pressure, HIL_GPS) it times, in one process run:

- ``encode_us``: ``Encoder.sensors`` / ``Encoder.gnss`` (SI sample -> frame bytes: validation,
  unit conversion, the fast-path pack of :mod:`hil.codec.fast_frames`);
- ``decode_us``: ``Decoder.feed`` (frame bytes -> SI samples: framing with its CRC check, the
  fast-path unpack, the samples);
- ``pymavlink_pack_us`` / ``pymavlink_decode_us``: the reference path on the same frames
  (pymavlink message object + ``pack``; ``Decoder.parse``, i.e. framing + ``MAVLink.decode``,
  + the same dispatch), i.e. what the codec cost before the fast path.

Each figure is the best of ``--repeats`` runs of ``--frames`` frames (CPU time, so other
processes cost less; the load average is recorded). pymavlink uses ``fastcrc`` for the X.25
CRC when it is installed (it is a hilnav dependency).
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import math
import os
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from hil.codec import Decoder, Encoder
from hil.codec.wire import mavlink2
from sim.samples import BaroSample, GnssFix, ImuSample, MagSample


def _best_us(fn: Callable[[], Any], n: int, repeats: int) -> float:
    best = math.inf
    for _ in range(repeats):
        t0 = time.process_time()
        fn()
        best = min(best, time.process_time() - t0)
    return best / n * 1e6


def _decode(frames: list[bytes]) -> int:
    dec = Decoder()
    return sum(len(dec.feed(f)) for f in frames)


def _reference_decode(frames: list[bytes]) -> int:
    dec = Decoder()
    return sum(len(dec._decode(m)) for f in frames for m in dec.parse(f))


def _reference_pack_s(frames: list[bytes]) -> float:
    """CPU seconds to build and pack pymavlink message objects of the frames' fields."""
    plain = mavlink2.MAVLink(None)
    msgs = [plain.decode(bytearray(f)) for f in frames]
    mav = mavlink2.MAVLink(None, srcSystem=1, srcComponent=200)
    t0 = time.process_time()
    for m in msgs:  # a fresh object per frame, as the encoder made one
        type(m)(*(getattr(m, n) for n in m.fieldnames)).pack(mav)
    return time.process_time() - t0


def _case(make_frames: Callable[[Encoder], list[bytes]], n: int, repeats: int,
          samples_per_frame: int) -> dict[str, float]:
    frames = make_frames(Encoder())
    encode_us = _best_us(lambda: make_frames(Encoder()), n, repeats)
    decode_us = _best_us(lambda: _decode(frames), n, repeats)
    assert _decode(frames) == n * samples_per_frame
    assert _reference_decode(frames) == n * samples_per_frame
    ref_decode_us = _best_us(lambda: _reference_decode(frames), n, repeats)
    pack_s = min(_reference_pack_s(frames) for _ in range(repeats))
    return {
        "encode_us": encode_us,
        "decode_us": decode_us,
        "pymavlink_pack_us": pack_s / n * 1e6,
        "pymavlink_decode_us": ref_decode_us,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--frames", type=int, default=20000)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--out", type=Path, default=Path("bench/results/codec_speed.json"))
    args = ap.parse_args()
    n = args.frames
    rng = np.random.default_rng(1)
    f_b = rng.normal(0.0, 1.0, (n, 3)) + np.array([0.0, 0.0, -9.8])
    w_b = rng.normal(0.0, 0.1, (n, 3))
    imu = [ImuSample(1000 + i * 5000, 0.005, f_b[i], w_b[i]) for i in range(n)]
    baro = [BaroSample(s.time_us, 95_000.0 + 10.0 * rng.normal(), 280.0) for s in imu]
    mag = [MagSample(s.time_us, np.array([2e-5, 1e-6, 4e-5]) + 1e-7 * rng.normal(size=3))
           for s in imu]
    fixes = [GnssFix(s.time_us, math.radians(47.0) + 1e-9 * i, math.radians(8.0), 500.0 + i,
                     np.array([50.0, -3.0, 0.5]) + rng.normal(size=3), 1.5, 2.5, math.nan, 3, 12)
             for i, s in enumerate(imu)]
    cases = {
        "hil_sensor_imu": _case(lambda e: [e.sensors(s) for s in imu], n, args.repeats, 1),
        "hil_sensor_all": _case(
            lambda e: [e.sensors(s, b, m, diff_pressure_pa=600.0)
                       for s, b, m in zip(imu, baro, mag, strict=True)], n, args.repeats, 4),
        "hil_gps": _case(lambda e: [e.gnss(f) for f in fixes], n, args.repeats, 1),
    }
    result = {
        "benchmark": "codec_speed",
        "frames": n,
        "repeats": args.repeats,
        "fastcrc": importlib.util.find_spec("fastcrc") is not None,
        "load_average_1m": os.getloadavg()[0],
        "cases": cases,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=2) + "\n")
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
