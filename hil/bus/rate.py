"""Per-topic rate limit of a bus: decimates each topic to its maximum rate on simulated time."""

from __future__ import annotations

import time

from hil.bus.config import BusConfig
from hil.bus.keys import Topic

__all__ = ["RateLimiter"]


class RateLimiter:
    """The decimation schedule of every topic of one bus.

    A message passes when its time is at or after the topic's next due time; a time more than
    two periods before it (a new run or a replay) starts the schedule over.

    Parameters
    ----------
    config : BusConfig
        Gives each topic's maximum rate (:meth:`BusConfig.rate_hz`).

    Notes
    -----
    Not thread-safe: the bus calls :meth:`take` under its lock.
    """

    def __init__(self, config: BusConfig) -> None:
        self._config = config
        self._next_due_us: dict[Topic, int] = {}

    def due(self, topic: Topic, time_us: int | None = None) -> bool:
        """Whether a message of ``topic`` at ``time_us`` would pass (no side effect).

        Parameters
        ----------
        topic : Topic
        time_us : int, optional
            Simulated time of the message, us; None: the wall clock (monotonic) instead.
        """
        rate = self._config.rate_hz(topic)
        if rate is None:
            return True
        return self._is_due(topic, _rate_time_us(time_us), round(1e6 / rate))

    def take(self, topic: Topic, time_us: int | None) -> bool:
        """Whether a message of ``topic`` at ``time_us`` passes; if so, book its slot."""
        rate = self._config.rate_hz(topic)
        if rate is None:
            return True
        period = round(1e6 / rate)
        t = _rate_time_us(time_us)
        if not self._is_due(topic, t, period):
            return False
        nxt = self._next_due_us.get(topic)
        # on schedule: keep the phase, so a 200 Hz stream decimates to an even 25 Hz
        on_schedule = nxt is not None and nxt <= t < nxt + period
        self._next_due_us[topic] = (nxt + period) if on_schedule and nxt is not None else t + period
        return True

    def _is_due(self, topic: Topic, t: int, period: int) -> bool:
        nxt = self._next_due_us.get(topic)
        # more than a period before the last message: a new run or a replay; start over
        return nxt is None or t >= nxt or t < nxt - 2 * period


def _rate_time_us(time_us: int | None) -> int:
    return time.monotonic_ns() // 1000 if time_us is None else int(time_us)
