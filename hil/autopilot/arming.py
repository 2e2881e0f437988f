"""The trim hold: what the aircraft flies until its autopilot is armed and in a flying mode.

hilnav's aircraft starts trimmed in the air, but an autopilot that boots (or sits disarmed)
does not fly it: PX4 sends all-zero controls while disarmed, ArduPlane sits in MANUAL with
neutral surfaces and its throttle at the minimum. Flown as they are, those outputs spiral a
trimmed aircraft into the ground long before the autopilot arms. So every backend passes its
controls through one :class:`TrimHold`: while the autopilot is known to be disarmed (or has not
said yet whether it is armed, though it will), the flight holds its controls (the trimmed
state's surfaces and throttle, as ``Flight.command([])`` leaves them). Armed is not enough:
an armed autopilot in a mode that follows the pilot's sticks (ArduPlane's MANUAL, PX4's MANUAL
or ACRO) with nobody at them flies the same neutral surfaces, so when the autopilot's mode can
be seen (:attr:`TrimHold.flying`, from its HEARTBEAT; :func:`hil.autopilot.modes.is_flying_mode`)
the hold lasts until it is armed *and* in a flying mode. From then on the autopilot's controls
are flown, and the simulated times are kept for the scorecard: the first armed report
(:attr:`TrimHold.armed_us`) and the release (:attr:`TrimHold.released_us`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

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
        """Simulated time (us) the hold first ended; None while it never did."""
        self.armed_us: int | None = None
        """Simulated time (us) of the first armed report; None while never armed."""
        self.flying: Callable[[], bool | None] | None = None
        """Whether the autopilot is in a flying mode (None from it, or no source: its mode
        cannot be seen, and armed is enough)."""
        self.held = 0
        """Control vectors replaced by the trim hold."""

    def apply(self, controls: Sequence[float], armed: bool | None,
              time_us: int) -> Sequence[float]:
        """``controls`` when the autopilot is armed and in a flying mode (or the hold is off),
        else ``[]`` (every control holds). ``armed`` None: the armed state cannot be seen, fly
        the controls. ``time_us``: the simulated time the controls are flown from."""
        if not self.enabled or armed is None:
            return controls
        if armed and self.armed_us is None:
            self.armed_us = int(time_us)
        flying = None if self.flying is None else self.flying()
        if armed and flying is not False:
            if self.released_us is None:
                self.released_us = int(time_us)
            return controls
        self.held += 1
        return []

    @property
    def released_s(self) -> float | None:
        """:attr:`released_us` in seconds (None: never released while held)."""
        return None if self.released_us is None else self.released_us / 1e6

    @property
    def armed_s(self) -> float | None:
        """:attr:`armed_us` in seconds (None: never armed while held)."""
        return None if self.armed_us is None else self.armed_us / 1e6
