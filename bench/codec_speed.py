"""Benchmark: MAVLink codec cost per HIL_SENSOR / HIL_GPS frame, CPU time, and where it goes.

    python bench/codec_speed.py                      # writes bench/results/codec_speed.json
    python bench/codec_speed.py --base REV --rounds 3 \
        --out /tmp/codec_speed_ab.json   # another revision against this tree, alternating

For each message (HIL_SENSOR with IMU fields only, HIL_SENSOR with IMU + mag + baro +
diff_pressure, HIL_GPS) it times, in one process run:

- ``encode_us``: ``Encoder.sensors`` / ``Encoder.gnss`` (SI sample -> frame bytes: validation,
  unit conversion, the fast-path pack of :mod:`hil.codec.fast_frames`);
- ``decode_us``: ``Decoder.feed`` (frame bytes -> SI samples: framing with its CRC check, the
  fast-path unpack, the samples);
- ``pymavlink_pack_us`` / ``pymavlink_decode_us``: the reference path on the same frames
  (pymavlink message object + ``pack``; ``Decoder.parse``, i.e. framing + ``MAVLink.decode``,
  + the same dispatch): pymavlink's own path, the reference;
- ``parts``: each part of the HIL_SENSOR (IMU fields) and HIL_GPS encode and decode timed
  alone on the same frames, µs per frame: encode ``pack`` (the ``struct`` call of the fields,
  ``FastLayout.payload``), ``crc`` (the X.25 CRC of header, payload and CRC_EXTRA, one
  ``fastcrc`` call over the joined bytes), ``framing`` (``pack_frame``: header, trailing-zero
  cut, CRC, join; includes ``crc``), ``checks_conversions`` (encode minus pack minus
  framing); decode ``framing`` (``FrameParser.feed``, with its CRC check), ``unpack``
  (``FastLayout.unpack``), ``conversions_samples`` (``decode_hil_sensor`` / ``decode_hil_gps``
  on the unpacked fields: unit conversions, IMU interval, the sample objects with their numpy
  vectors), ``sample_objects`` (of which: the sample object and its vectors alone, made as
  the decoder makes them), ``dispatch`` (decode minus framing, unpack and
  conversions_samples: the decoder's loop, message-id dispatch, ``Decoded`` records).

Each figure is the best of ``--repeats`` runs of ``--frames`` frames (CPU time, so other
processes cost less; the load average is recorded). pymavlink uses ``fastcrc`` for the X.25
CRC when it is installed (it is a hilnav dependency).

``--base REV`` measures the code of git revision ``REV`` (a ``git archive`` of it, first on
``PYTHONPATH``) and this checkout alternately, ``--rounds`` times each, one child process per
measurement, and keeps the best of each figure: before / after on a loaded machine.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parent.parent


def _best_us(fn: Callable[[], Any], n: int, repeats: int) -> float:
    best = math.inf
    for _ in range(repeats):
        t0 = time.process_time()
        fn()
        best = min(best, time.process_time() - t0)
    return best / n * 1e6


def _decode(frames: list[bytes]) -> int:
    from hil.codec import Decoder

    dec = Decoder()
    return sum(len(dec.feed(f)) for f in frames)


def _reference_decode(frames: list[bytes]) -> int:
    from hil.codec import Decoder

    dec = Decoder()
    return sum(len(dec._decode(m)) for f in frames for m in dec.parse(f))


def _reference_pack_s(frames: list[bytes]) -> float:
    """CPU seconds to build and pack pymavlink message objects of the frames' fields."""
    from hil.codec.wire import mavlink2

    plain = mavlink2.MAVLink(None)
    msgs = [plain.decode(bytearray(f)) for f in frames]
    mav = mavlink2.MAVLink(None, srcSystem=1, srcComponent=200)
    t0 = time.process_time()
    for m in msgs:  # a fresh object per frame, as the encoder made one
        type(m)(*(getattr(m, n) for n in m.fieldnames)).pack(mav)
    return time.process_time() - t0


def _case(make_frames: Callable[[Any], list[bytes]], n: int, repeats: int,
          samples_per_frame: int) -> dict[str, Any]:
    from hil.codec import Encoder

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


def _parts(frames: list[bytes], encode_us: float, decode_us: float, repeats: int
           ) -> dict[str, dict[str, float]]:
    """Each part of one message's encode and decode timed alone on ``frames`` (µs / frame)."""
    import sim.samples as samples_module
    from hil.codec.counters import DecoderCounters
    from hil.codec.fast_frames import FAST_LAYOUTS, pack_frame
    from hil.codec.framing import FrameParser
    from hil.codec.hil_messages import decode_hil_gps, decode_hil_sensor
    from hil.codec.sources import SourceState
    from hil.codec.wire import mcrf4xx

    n = len(frames)
    msg_id = frames[0][7]
    layout = FAST_LAYOUTS[msg_id]
    fields = [layout.unpack(f) for f in frames]
    payloads = [layout.payload(*x) for x in fields]
    extra = layout.crc_extra_byte
    heads = [f[1:-2] for f in frames]

    def pack() -> None:
        for x in fields:
            layout.payload(*x)

    def framing_out() -> None:
        for i, p in enumerate(payloads):
            pack_frame(layout, p, i & 0xFF, 1, 200)

    def crc() -> None:
        for h in heads:
            mcrf4xx(h + extra)

    def framing_in() -> None:
        parser = FrameParser(DecoderCounters())
        for f in frames:
            parser.feed(f)

    def unpack() -> None:
        for f in frames:
            layout.unpack(f)

    is_sensor = msg_id == 107

    def conversions_samples() -> None:
        if is_sensor:
            sources, counters = SourceState(0.0), DecoderCounters()
            for x in fields:
                decode_hil_sensor(x, (1, 200, 107, 0), sources, counters)
        else:
            for x in fields:
                decode_hil_gps(x)

    f64 = np.float64
    made_fast = hasattr(samples_module, "make_imu_sample")  # else: as the base decoder did

    def sample_objects() -> None:  # as each tree's decoder makes them
        if is_sensor and made_fast:
            make = samples_module.make_imu_sample
            for x in fields:
                make(x[0], 0.005, np.array(x[1:4], f64), np.array(x[4:7], f64), 288.15, 0)
        elif is_sensor:
            for x in fields:
                samples_module.ImuSample(x[0], 0.005, np.array([x[1], x[2], x[3]], f64),
                                         np.array([x[4], x[5], x[6]], f64), 288.15, 0)
        else:
            make_fix = getattr(samples_module, "make_gnss_fix", samples_module.GnssFix)
            for x in fields:
                make_fix(x[0], 0.8, 0.1, 500.0, np.array((0.5, 0.3, 0.1), f64), 1.5, 2.5,
                         math.nan, 3, 12, 0)

    enc_pack = _best_us(pack, n, repeats)
    enc_framing = _best_us(framing_out, n, repeats)
    dec_framing = _best_us(framing_in, n, repeats)
    dec_unpack = _best_us(unpack, n, repeats)
    dec_samples = _best_us(conversions_samples, n, repeats)
    return {
        "encode": {
            "checks_conversions_us": encode_us - enc_pack - enc_framing,
            "pack_us": enc_pack,
            "framing_us": enc_framing,
            "crc_us": _best_us(crc, n, repeats),
        },
        "decode": {
            "framing_us": dec_framing,
            "unpack_us": dec_unpack,
            "conversions_samples_us": dec_samples,
            "sample_objects_us": _best_us(sample_objects, n, repeats),
            "dispatch_us": decode_us - dec_framing - dec_unpack - dec_samples,
        },
    }


def measure(n: int, repeats: int) -> dict[str, Any]:
    """Every case and the parts, in this process, with the code on ``sys.path``."""
    from hil.codec import Encoder
    from sim.samples import BaroSample, GnssFix, ImuSample, MagSample

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
    cases: dict[str, dict[str, Any]] = {
        "hil_sensor_imu": _case(lambda e: [e.sensors(s) for s in imu], n, repeats, 1),
        "hil_sensor_all": _case(
            lambda e: [e.sensors(s, b, m, diff_pressure_pa=600.0)
                       for s, b, m in zip(imu, baro, mag, strict=True)], n, repeats, 4),
        "hil_gps": _case(lambda e: [e.gnss(f) for f in fixes], n, repeats, 1),
    }
    enc = Encoder()
    cases["hil_sensor_imu"]["parts"] = _parts(
        [enc.sensors(s) for s in imu], cases["hil_sensor_imu"]["encode_us"],
        cases["hil_sensor_imu"]["decode_us"], repeats)
    cases["hil_gps"]["parts"] = _parts(
        [enc.gnss(f) for f in fixes], cases["hil_gps"]["encode_us"],
        cases["hil_gps"]["decode_us"], repeats)
    return cases


def _best_of(runs: list[dict[str, Any]]) -> dict[str, Any]:
    """Figure by figure, the smallest of the runs (nested dicts of floats)."""
    first = runs[0]
    if isinstance(first, dict):
        return {k: _best_of([r[k] for r in runs]) for k in first}
    return min(runs)


def _child(tree: Path, n: int, repeats: int) -> dict[str, Any]:
    env = {**os.environ, "PYTHONPATH": str(tree), "OPENBLAS_NUM_THREADS": "1"}
    out = subprocess.run(
        [sys.executable, str(Path(__file__).resolve()), "--child", str(n), str(repeats)],
        cwd=tree, env=env, capture_output=True, text=True, check=True)
    cases: dict[str, Any] = json.loads(out.stdout)
    return cases


def _ab(base: str, n: int, repeats: int, rounds: int) -> dict[str, Any]:
    """Base revision and this checkout, alternately, ``rounds`` child runs each."""
    with tempfile.TemporaryDirectory() as tmp:
        archive = subprocess.run(["git", "archive", base], cwd=ROOT, check=True,
                                 capture_output=True).stdout
        subprocess.run(["tar", "-x", "-C", tmp], input=archive, check=True)
        runs: dict[str, list[dict[str, Any]]] = {"before": [], "after": []}
        for _ in range(rounds):
            runs["before"].append(_child(Path(tmp), n, repeats))
            runs["after"].append(_child(ROOT, n, repeats))
    return {k: _best_of(v) for k, v in runs.items()}


def main() -> None:
    if len(sys.argv) > 1 and sys.argv[1] == "--child":
        print(json.dumps(measure(int(sys.argv[2]), int(sys.argv[3]))))
        return
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--frames", type=int, default=20000)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--base", default=None, help="git revision to compare with (alternating)")
    ap.add_argument("--rounds", type=int, default=3, help="child runs of each tree (--base)")
    ap.add_argument("--out", type=Path, default=Path("bench/results/codec_speed.json"))
    args = ap.parse_args()
    result: dict[str, Any] = {
        "benchmark": "codec_speed",
        "frames": args.frames,
        "repeats": args.repeats,
        "fastcrc": importlib.util.find_spec("fastcrc") is not None,
        "load_average_1m": os.getloadavg()[0],
    }
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT,
                            capture_output=True, text=True, check=False).stdout.strip()
    if args.base is None:
        result["commit"] = commit
        result["cases"] = measure(args.frames, args.repeats)
    else:
        result.update(base=args.base, commit=commit, rounds=args.rounds,
                      method="best of each figure over alternating child runs")
        result.update(_ab(args.base, args.frames, args.repeats, args.rounds))
    result["load_average_1m_end"] = os.getloadavg()[0]
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=2) + "\n")
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
