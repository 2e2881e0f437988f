"""The trim hold: what the aircraft flies while its autopilot is not armed.

hilnav's aircraft starts trimmed in the air, but an autopilot that boots (or sits disarmed)
does not fly it: PX4 sends all-zero controls while disarmed, ArduPlane sits in MANUAL with
neutral surfaces and its throttle at the minimum. Flown as they are, those outputs spiral a
trimmed aircraft into the ground long before the autopilot arms. So every backend passes its
controls through one :class:`TrimHold`: while the autopilot is known to be disarmed (or has not
said yet whether it is armed, though it will), the flight holds its controls (the trimmed
state's surfaces and throttle, as ``Flight.command([])`` leaves them); from the first armed
report on the autopilot's controls are flown, and the simulated time of that release is kept
for the scorecard (:attr:`TrimHold.released_us`).
"""

from __future__ import annotations

from collections.abc import Sequence

__all__ = ["TrimHold"]


class TrimHold:
    """Hold the trim until the autopilot is armed (see the module docstring).

    Parameters
    ----------
    enabled : bool
        False: fly the autopilot's controls whatever its armed state.
    """

    def __init__(self, *, enabled: bool = True) -> None:
        self.enabled = enabled
        self.released_us: int | None = None
        """Simulated time (us) of the first armed report; None while never armed."""
        self.held = 0
        """Control vectors replaced by the trim hold."""

    def apply(self, controls: Sequence[float], armed: bool | None,
              time_us: int) -> Sequence[float]:
        """``controls`` when the autopilot is armed (or the hold is off), else ``[]`` (every
        control holds). ``armed`` None: the armed state cannot be seen, fly the controls.
        ``time_us``: the simulated time the controls are flown from."""
        if not self.enabled or armed is None:
            return controls
        if armed:
            if self.released_us is None:
                self.released_us = int(time_us)
            return controls
        self.held += 1
        return []

    @property
    def released_s(self) -> float | None:
        """:attr:`released_us` in seconds (None: never armed while held)."""
        return None if self.released_us is None else self.released_us / 1e6
