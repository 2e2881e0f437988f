"""Barometer health: range check, frozen-sensor detection and the height innovation gate."""

from __future__ import annotations

from dataclasses import dataclass

from pydantic import Field, PositiveFloat

from fusion.altitude.atmosphere import pressure_altitude_m
from fusion.altitude.common import Frozen


class BaroMonitorConfig(Frozen):
    """When a baro sample is used."""

    freeze_time_s: PositiveFloat = 2.0
    """Bit-identical (within ``freeze_tolerance_pa``) readings for this long: sensor frozen.
    Sensors with a coarse output step hovering in still air repeat legitimately; raise it."""
    freeze_tolerance_pa: float = Field(default=0.0, ge=0.0)
    gate_m: PositiveFloat = 10.0
    """Samples whose height differs from the loop's prediction by more are rejected, m."""
    realign_after_rejected_s: PositiveFloat = 10.0
    """After this long of continuous gate rejections the baro datum is re-aligned (see
    :class:`fusion.altitude.channel.AltitudeChannel`), s."""


@dataclass(slots=True)
class BaroHealth:
    """Counters and flags of the barometer path (monotonic counters, current flags)."""

    samples: int = 0
    accepted: int = 0
    range_errors: int = 0
    frozen_samples: int = 0
    freeze_events: int = 0
    gate_rejections: int = 0
    realignments: int = 0
    frozen: bool = False
    rejecting: bool = False


class BaroMonitor:
    """Range check, freeze detector and innovation gate for one barometer.

    Usage per sample: :meth:`check` (range + freeze; returns the pressure altitude or ``None``),
    then :meth:`gate` with the calibrated height and the loop's predicted height.

    Parameters
    ----------
    config : BaroMonitorConfig
    health : BaroHealth or None
        Counters to update (a fresh one if ``None``).
    """

    def __init__(self, config: BaroMonitorConfig | None = None, health: BaroHealth | None = None):
        self.config = config or BaroMonitorConfig()
        self.health = health if health is not None else BaroHealth()
        self._last_p: float | None = None
        self._same_since_s = 0.0
        self._rejecting_since_s: float | None = None

    def check(self, pressure_pa: float, time_s: float) -> float | None:
        """Range and freeze check of one sample.

        Parameters
        ----------
        pressure_pa : float
            Static pressure, Pa (any value: bad ones are counted, never raised).
        time_s : float
            Sample time, s.

        Returns
        -------
        float or None
            The pressure altitude ``Hp`` (m), or ``None`` if the sample must not be used.
        """
        h = self.health
        h.samples += 1
        try:
            hp = pressure_altitude_m(pressure_pa)
        except ValueError:
            h.range_errors += 1
            return None
        cfg = self.config
        if self._last_p is not None and abs(pressure_pa - self._last_p) <= cfg.freeze_tolerance_pa:
            if time_s - self._same_since_s >= cfg.freeze_time_s:
                if not h.frozen:
                    h.freeze_events += 1
                h.frozen = True
        else:
            self._last_p = pressure_pa
            self._same_since_s = time_s
            h.frozen = False
        if h.frozen:
            h.frozen_samples += 1
            return None
        return hp

    def gate(self, baro_height_m: float, predicted_height_m: float, time_s: float) -> bool:
        """Innovation gate: accept if ``|baro − predicted| ≤ gate_m``.

        Returns
        -------
        bool
            ``True`` when accepted. Rejections are counted; :attr:`rejecting_for_s` tells how
            long they have lasted without a break.
        """
        h = self.health
        if abs(baro_height_m - predicted_height_m) <= self.config.gate_m:
            h.accepted += 1
            h.rejecting = False
            self._rejecting_since_s = None
            return True
        h.gate_rejections += 1
        h.rejecting = True
        if self._rejecting_since_s is None:
            self._rejecting_since_s = time_s
        return False

    def rejecting_for_s(self, time_s: float) -> float:
        """How long the gate has rejected every sample, s (0 if the last one was accepted)."""
        return 0.0 if self._rejecting_since_s is None else time_s - self._rejecting_since_s

    def clear_rejection(self) -> None:
        """Forget the current run of rejections (after a datum re-alignment)."""
        self._rejecting_since_s = None
        self.health.rejecting = False
