"""hil.sample_clock: one stamp cannot move the trusted time (lockstep acks, run duration)."""

from __future__ import annotations

import pytest

from hil.sample_clock import MAX_TIME_US, SampleClock


def test_a_stamp_far_ahead_is_refused_unless_the_filter_took_it() -> None:
    clock = SampleClock(jump_us=1_000_000)
    assert clock.offer(5_000, filter_time_us=0)  # the first stamp starts the clock
    assert clock.offer(10_000, filter_time_us=10_000)
    assert not clock.offer(10_000 + 3_600_000_000, filter_time_us=10_000)  # an hour ahead
    assert not clock.offer(2**64 - 1, filter_time_us=10_000)
    assert not clock.offer(9_000, filter_time_us=10_000)  # older: not counted, not taken
    assert clock.latest_us == 10_000 and clock.refused == 2
    # a new time base the filter's clock moved to (a restarted simulator 30 s on) is taken
    assert clock.offer(40_000_000, filter_time_us=40_000_000)
    assert clock.offer(40_005_000, filter_time_us=40_005_000)
    assert clock.latest_us == 40_005_000


def test_nothing_beyond_timesyncs_nanoseconds_is_ever_taken() -> None:
    clock = SampleClock(jump_us=1_000_000)
    assert not clock.offer(MAX_TIME_US + 1, filter_time_us=MAX_TIME_US + 1)
    assert clock.latest_us == -1 and clock.refused == 1
    assert MAX_TIME_US * 1000 <= 2**63 - 1
    with pytest.raises(ValueError):
        SampleClock(jump_us=0)
