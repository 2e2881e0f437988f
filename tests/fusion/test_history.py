"""fusion.history: the delayed-measurement buffer (ring wrap, interpolation, corrections)."""

from __future__ import annotations

import pytest

from fusion import earth
from fusion.history import InsHistory, span_capacity
from fusion.strapdown import InsState


def state(k: int) -> InsState:
    """A state whose every field moves linearly with the epoch k."""
    return InsState(0.7 + 1e-7 * k, 0.1 + 2e-7 * k, 100.0 + k, (1.0 * k, 2.0, -0.5 * k),
                    (1.0, 0.0, 0.0, 0.0))  # fmt: skip


def test_exact_interpolated_and_out_of_span_lookups_across_the_ring_wrap() -> None:
    # GIVEN a 5-slot buffer filled with 12 epochs (wrapped twice), 10 ms apart
    hist = InsHistory(5)
    for k in range(12):
        hist.push(10_000 * k, state(k))
    # THEN only the last five are kept, exact epochs come back unchanged
    assert hist.oldest_us == 70_000
    assert hist.at(110_000) == state(11)
    assert hist.at(70_000) == state(7)
    # AND a time between epochs is interpolated linearly (attitude: the nearer epoch)
    mid = hist.at(95_000)
    assert mid is not None
    assert mid.alt_msl_m == pytest.approx(109.5)
    assert mid.v_ned_mps[0] == pytest.approx(9.5)
    assert mid.lat_rad == pytest.approx(0.7 + 9.5e-7, abs=1e-15)
    # AND times outside the span are refused
    assert hist.at(69_999) is None
    assert hist.at(110_001) is None


def test_feedback_after_an_epoch_is_applied_to_it_on_readback() -> None:
    # GIVEN two stored epochs, then a feedback of 1 m north, 2 m down, 0.1 m/s east
    hist = InsHistory(span_capacity(0.3))
    hist.push(0, state(0))
    hist.add_correction([1.0, 0.0, 2.0, 0.0, 0.1, 0.0, 0.0, 0.0, 0.0])
    hist.push(10_000, state(1))
    # WHEN the epochs are read back
    old, new = hist.at(0), hist.at(10_000)
    assert old is not None and new is not None
    # THEN the epoch stored before the feedback carries it, the later one is untouched
    rho_n = earth.local_terms(state(0).lat_rad, state(0).alt_msl_m).rho_n_m
    assert old.lat_rad == pytest.approx(state(0).lat_rad - 1.0 / rho_n, abs=1e-15)
    assert old.alt_msl_m == pytest.approx(state(0).alt_msl_m + 2.0)
    assert old.v_ned_mps[1] == pytest.approx(2.0 - 0.1)
    assert new == state(1)
    # AND clear() empties the buffer
    hist.clear()
    assert hist.oldest_us is None and hist.at(0) is None


def test_capacity_is_validated() -> None:
    with pytest.raises(ValueError, match="capacity"):
        InsHistory(1)
