"""Benchmark: MAVLink codec cost per HIL_SENSOR frame (IMU fields only), CPU time.

    python bench/codec_speed.py        # writes bench/results/codec_speed.json

pymavlink uses ``fastcrc`` for the X.25 CRC when it is installed (it is a hilnav dependency);
the JSON records whether it was importable.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import time
from pathlib import Path

import numpy as np

from hil.codec import Decoder, Encoder
from sim.samples import ImuSample


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--frames", type=int, default=20000)
    ap.add_argument("--out", type=Path, default=Path("bench/results/codec_speed.json"))
    args = ap.parse_args()
    enc, dec = Encoder(), Decoder()
    f_b = np.array([0.1, 0.2, -9.8])
    w_b = np.array([0.01, 0.02, 0.03])
    samples = [ImuSample(1000 + i * 5000, 0.005, f_b, w_b) for i in range(args.frames)]
    t0 = time.process_time()
    frames = [enc.sensors(s) for s in samples]
    encode_us = (time.process_time() - t0) / args.frames * 1e6
    t0 = time.process_time()
    n = sum(len(dec.feed(f)) for f in frames)
    decode_us = (time.process_time() - t0) / args.frames * 1e6
    assert n == args.frames
    result = {
        "benchmark": "codec_speed",
        "frames": args.frames,
        "fastcrc": importlib.util.find_spec("fastcrc") is not None,
        "load_average_1m": os.getloadavg()[0],
        "encode_us_per_hil_sensor": encode_us,
        "decode_us_per_hil_sensor": decode_us,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=2) + "\n")
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
