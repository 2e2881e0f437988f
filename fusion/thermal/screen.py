"""Screening of the IMU's die temperature: what the thermal corrections may believe.

A reading is rejected, and counted in :class:`fusion.estimate.Health`, when it is

- not finite (``temperature_nan``);
- outside the part's operating range (``temperature_out_of_range``);
- further from the last good reading than the die can move (``max_slew_k_per_s`` over the
  time between them, plus two sensor quanta: ``temperature_jump``);
- identical, to the bit, for more than ``stuck_updates`` of the sensor's update periods and
  ``stuck_min_s`` (``temperature_stuck``): a live sensor's last bit moves far more often.

A rejected reading leaves the last good temperature in force and makes
:attr:`TemperatureScreen.good` false: the thermal corrections hold (the blind filter's
behaviour) until a good reading comes back.
"""

from __future__ import annotations

import math

from fusion.estimate import HealthCounters
from fusion.thermal.tuning import ThermalTuning


class TemperatureScreen:
    """Screen one temperature stream (module docstring).

    Parameters
    ----------
    tuning : ThermalTuning
    counters : HealthCounters
        Where rejections are counted.

    Attributes
    ----------
    temperature_k : float
        The last good reading (NaN before the first), K.
    time_us : int or None
        Time of the last good reading.
    good : bool
        The latest reading was accepted.
    """

    def __init__(self, tuning: ThermalTuning, counters: HealthCounters) -> None:
        self._t = tuning
        self._c = counters
        self.temperature_k = math.nan
        self.time_us: int | None = None
        self.good = False
        self._raw_last = math.nan
        self._raw_since_us: int | None = None
        self._stuck_us = round(max(tuning.stuck_updates * tuning.update_period_s,
                                   tuning.stuck_min_s) * 1e6)
        # a reading that has not changed since the last call is not a new reading
        self._seen = math.nan

    def add(self, time_us: int, temperature_k: float) -> bool:
        """Screen a reading at ``time_us``; True when it is a new good temperature.

        Repeats of the last reading (the sensor updates slower than the IMU) are neither new
        nor counted, until the repetition outlasts ``stuck_updates`` periods.
        """
        t = self._t
        c = self._c
        if not math.isfinite(temperature_k):
            if self._seen == self._seen or self.good:  # count a NaN run once per onset
                c.temperature_nan += 1
            self._seen = math.nan
            self.good = False
            return False
        if temperature_k == self._raw_last:
            since = self._raw_since_us
            if since is not None and time_us - since > self._stuck_us:
                if self.good:
                    c.temperature_stuck += 1
                self.good = False
            return False
        self._raw_last = temperature_k
        self._raw_since_us = time_us
        self._seen = temperature_k
        if not t.min_k <= temperature_k <= t.max_k:
            c.temperature_out_of_range += 1
            self.good = False
            return False
        last_us = self.time_us
        if last_us is not None:
            dt = max(0.0, (time_us - last_us) * 1e-6)
            if abs(temperature_k - self.temperature_k) > t.max_slew_k_per_s * dt + 2 * t.quantum_k:
                c.temperature_jump += 1
                self.good = False
                return False
        self.temperature_k = temperature_k
        self.time_us = time_us
        self.good = True
        return True
