"""The collector's compact storage (bounded memory): the tracks and the health
series built from compacted (or spilled) column chunks equal those built from the objects, and
a spilling collector holds at most one chunk of objects however long the run."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from fusion import rotations
from fusion.filter import NavFilter
from hil.codec import Decoder
from hil.pipeline import SimSetup, filter_config, fly
from hil.tracks import Collector, ColumnChunks
from sim.presets import gnss_preset
from sim.samples import Sample, Truth


@pytest.fixture(scope="module")
def samples() -> list[Sample | Truth]:
    """A 45 s racetrack with GNSS off 20-30 s, decoded from its MAVLink frames."""
    frames: list[bytes] = []
    fly(SimSetup.build(duration_s=45.0, seed=11, gnss_off=["20:10"]),
        lambda _t, f: frames.append(f))
    dec = Decoder()
    return [d.sample for f in frames for d in dec.feed(f)]


def _collect(samples: list[Sample | Truth], **kwargs: object) -> Collector:
    nav = NavFilter(filter_config("industrial-mems", gnss_preset("modern")))
    col = Collector(**kwargs)  # type: ignore[arg-type]
    for k in range(0, len(samples), 97):  # batches, as the live service and replay feed
        col.feed(nav, samples[k:k + 97])
    return col


def _assert_same_arrays(a: object, b: object) -> None:
    for name, x in vars(a).items():
        y = getattr(b, name)
        if x is None or y is None:
            assert x is y, name
        elif isinstance(x, np.ndarray):
            assert x.dtype == y.dtype, name
            np.testing.assert_array_equal(x, y, err_msg=name)
        else:
            _assert_same_arrays(x, y)


def test_compact_tracks_equal_the_arrays_built_from_the_objects(
    samples: list[Sample | Truth], tmp_path: Path,
) -> None:
    """GIVEN one flight collected with the objects kept, in chunks of 100 rows in memory, and
    in chunks of 100 rows spilled to a file WHEN the tracks, series, modes and fixes are built
    THEN they are bit for bit the arrays built directly from the estimate / truth / fix objects
    (the pre-compaction formulas), and equal across the three collectors."""
    ref = _collect(samples, keep_objects=True)
    est = [e for e in ref.estimates if e.mode != "initializing"]
    assert len(est) > 1500 and ref.n_estimates >= len(est)
    track = ref.estimate_track()
    np.testing.assert_array_equal(track.time_s, np.array([e.time_us for e in est]) * 1e-6)
    np.testing.assert_array_equal(track.lat_rad, np.array([e.lat_rad for e in est]))
    np.testing.assert_array_equal(track.v_ned_mps, np.array([e.v_ned_mps for e in est]))
    np.testing.assert_array_equal(track.euler_rad, np.array([e.euler_rad for e in est]))
    np.testing.assert_array_equal(
        track.sigma, np.array([np.sqrt(np.maximum(e.P_diag[:9], 0.0)) for e in est]))
    assert track.cov is not None
    np.testing.assert_array_equal(track.cov, np.array([e.P_nav for e in est]))
    tr = sorted(ref.truths, key=lambda s: s.time_us)
    truth = ref.truth_track()
    np.testing.assert_array_equal(truth.alt_m, np.array([s.alt_msl_m for s in tr]))
    np.testing.assert_array_equal(
        truth.euler_rad, rotations.quat_to_euler(np.array([s.q_nb for s in tr])))
    series = ref.series()
    assert series.mode is not None and series.gnss_fused is not None
    assert list(series.mode) == [str(e.mode) for e in est]
    np.testing.assert_array_equal(series.gnss_fused, [e.health.gnss_fused for e in est])
    assert ref.modes() == [str(e.mode) for e in ref.estimates]
    np.testing.assert_array_equal(ref.fix_times_us, [f.time_us for f in ref.fixes])
    assert ref.n_fixes == len(ref.fixes) > 30

    for other in (_collect(samples, chunk_rows=100),
                  _collect(samples, chunk_rows=100, spill_dir=tmp_path / "spill")):
        assert other.n_estimates == ref.n_estimates and other.n_truths == ref.n_truths
        _assert_same_arrays(other.estimate_track(), track)
        _assert_same_arrays(other.truth_track(), truth)
        _assert_same_arrays(other.series(), series)
        _assert_same_arrays(other.fix_track(), ref.fix_track())
        assert other.modes() == ref.modes()
        assert other.end_s() == ref.end_s()
        assert other.last_time_us == ref.last_time_us
        other.close()


def test_a_spilling_collector_holds_at_most_one_chunk_of_objects(
    samples: list[Sample | Truth], tmp_path: Path,
) -> None:
    """GIVEN a collector spilling to a folder in chunks of 64 rows WHEN a whole flight is fed
    THEN no stream ever holds 64 objects, nothing of the columns stays in memory, the folder
    shows no file (the spill file is anonymous), and the objects are not kept."""
    spill = tmp_path / "out"
    nav = NavFilter(filter_config("industrial-mems", gnss_preset("modern")))
    col = Collector(spill_dir=spill, chunk_rows=64)
    most = 0
    for k in range(0, len(samples), 50):
        col.feed(nav, samples[k:k + 50])
        most = max(most, *(len(s.pending) for s in (col._est, col._tru, col._fix)))
    assert most < 64
    assert col.n_estimates > 1500 and col.n_truths > 1500
    for stream in (col._est, col._tru, col._fix):
        assert stream.chunks._held == {}
    assert col.compact_nbytes > 1500 * (8 + 1 + 9 * 8 + 9 * 8 + 81 * 8 + 4 * 8 + 10 * 8)
    assert list(spill.iterdir()) == []
    with pytest.raises(ValueError, match="keep_objects"):
        _ = col.estimates
    assert col.estimate_track().time_s.size > 1500
    col.close()


def test_column_chunks_refuse_a_chunk_with_other_columns() -> None:
    chunks = ColumnChunks()
    assert chunks.columns() == {}
    chunks.append({"a": np.zeros(3), "b": np.ones(3)})
    with pytest.raises(ValueError, match="differ"):
        chunks.append({"b": np.ones(3), "a": np.zeros(3)})
    assert chunks.rows == 3
    chunks.append({"a": np.full(2, 2.0), "b": np.zeros(2)})
    np.testing.assert_array_equal(chunks.columns()["a"], [0.0, 0.0, 0.0, 2.0, 2.0])


def test_column_chunks_in_memory_are_held_once() -> None:
    """GIVEN three chunks kept in memory
    WHEN the columns are read, more chunks appended (the store grows) and the columns read
    again
    THEN both reads give every row in order, read-only views of the one array per column the
    store holds (no copy), and the first read is unchanged by what came after."""
    chunks = ColumnChunks()
    for k in range(3):
        chunks.append({"a": np.full(2, float(k)), "b": np.arange(4.0).reshape(2, 2) + k})
    first = chunks.columns()
    np.testing.assert_array_equal(first["a"], [0, 0, 1, 1, 2, 2])
    assert not first["a"].flags.writeable
    assert np.shares_memory(chunks._held["b"], first["b"])
    kept = first["b"].copy()
    for k in range(5):
        chunks.append({"a": np.full(1, 3.0 + k), "b": np.full((1, 2), 9.0 + k)})
    second = chunks.columns()
    np.testing.assert_array_equal(second["a"], [0, 0, 1, 1, 2, 2, 3, 4, 5, 6, 7])
    np.testing.assert_array_equal(second["b"][:6], kept)
    np.testing.assert_array_equal(second["b"][6:, 0], [9.0, 10.0, 11.0, 12.0, 13.0])
    np.testing.assert_array_equal(first["b"], kept)
    assert np.shares_memory(chunks._held["b"], second["b"])
    assert chunks.rows == 11
