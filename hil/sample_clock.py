"""The newest sample time a run can trust: what the live fusion acknowledges to a lockstep
simulator and how long the scorecard says the run was.

A sample's stamp is whatever its sender wrote: an hour ahead, 2^64 - 1 us, from a glitch or a
sender forging the simulator's address. The filter never lets one stamp move its clock
(:mod:`fusion.screening`); this is the same rule for the shell around it, so that one stamp
cannot end a simulator's lockstep pacing (it keeps the largest acknowledgement it saw) or
make a 40 s flight a 213-day one in ``summary.json``.
"""

from __future__ import annotations

from typing import Final

__all__ = ["MAX_TIME_US", "SampleClock"]

MAX_TIME_US: Final = (2**63 - 1) // 1000
"""The largest stamp a TIMESYNC (int64 nanoseconds) can carry, us."""


class SampleClock:
    """The newest trusted sample time, advanced sample by sample.

    A stamp is taken when it is newer than the newest one and either within ``jump_us`` of
    it, or the time the filter's clock now stands at (the filter took it, e.g. as a new time
    base after a simulator restart); never beyond :data:`MAX_TIME_US`. Everything else is
    counted in :attr:`refused`.

    Parameters
    ----------
    jump_us : int
        The filter's IMU time-jump threshold (``ImuTuning.time_jump_s``), us.
    """

    def __init__(self, jump_us: int) -> None:
        if jump_us <= 0:
            raise ValueError("jump_us must be > 0")
        self._jump_us = jump_us
        self.latest_us = -1
        """The newest trusted stamp, us (-1 before any)."""
        self.refused = 0

    def offer(self, time_us: int, filter_time_us: int) -> bool:
        """Advance to ``time_us`` if it is trusted (see the class); whether it advanced."""
        last = self.latest_us
        if time_us <= last:
            return False
        if time_us > MAX_TIME_US or (
                last >= 0 and time_us - last > self._jump_us and time_us != filter_time_us):
            self.refused += 1
            return False
        self.latest_us = time_us
        return True
