"""The collector's compact storage: bytes per recorded sample are the row size (computed)."""

from __future__ import annotations

import numpy as np

from hil.tracks import EST_FLOAT_WIDTH, EST_INT_WIDTH, TRUTH_WIDTH, RowStore


def test_row_store_grows_by_one_row_size_per_sample_in_chunks() -> None:
    """GIVEN a row store of 103 float64 columns in chunks of 64 rows WHEN 1000 rows are added
    THEN it holds them in order and has allocated at most one chunk beyond the rows."""
    store = RowStore(EST_FLOAT_WIDTH, np.float64, chunk_rows=64)
    row_bytes = EST_FLOAT_WIDTH * 8
    for k in range(1000):
        store.next_row()[:] = k
    assert len(store) == 1000
    a = store.array()
    assert a.shape == (1000, EST_FLOAT_WIDTH)
    np.testing.assert_array_equal(a[:, 0], np.arange(1000.0))
    assert 1000 * row_bytes <= store.nbytes <= (1000 + 64) * row_bytes


def test_estimate_and_truth_rows_are_fixed_size() -> None:
    """The per-sample budget: an estimate row is 103 float64 + 13 int64 = 928 bytes, a truth
    row 10 float64 + 1 int64 = 88 bytes (versus several kB of objects per estimate)."""
    assert EST_FLOAT_WIDTH * 8 + EST_INT_WIDTH * 8 == 928
    assert TRUTH_WIDTH * 8 + 8 == 88
