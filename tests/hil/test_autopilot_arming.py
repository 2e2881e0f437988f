"""The trim hold (hil.autopilot.arming.TrimHold): the autopilot's controls are flown only once
it is armed and, when its mode can be seen, in a flying mode (hil.autopilot.modes)."""

from __future__ import annotations

from hil.autopilot.arming import TrimHold
from hil.autopilot.modes import ARDUPLANE_MODES, PX4_MODES, is_flying_mode

CONTROLS = [0.1, -0.2, 0.0, 0.7]


def test_armed_in_manual_still_holds_until_a_flying_mode() -> None:
    mode = {"custom": ARDUPLANE_MODES["MANUAL"]}
    hold = TrimHold()
    hold.flying = lambda: is_flying_mode("ardupilot", mode["custom"])
    assert hold.apply(CONTROLS, False, 1_000_000) == []
    assert hold.apply(CONTROLS, True, 2_000_000) == []  # armed, MANUAL: neutral surfaces
    mode["custom"] = ARDUPLANE_MODES["AUTO"]
    assert hold.apply(CONTROLS, True, 3_000_000) == CONTROLS
    assert (hold.armed_s, hold.released_s, hold.held) == (2.0, 3.0, 2)


def test_an_unseen_mode_or_armed_state_does_not_hold() -> None:
    hold = TrimHold()
    hold.flying = lambda: None  # no HEARTBEAT yet: armed is enough
    assert hold.apply(CONTROLS, True, 5_000) == CONTROLS and hold.released_us == 5_000
    assert TrimHold().apply(CONTROLS, None, 0) == CONTROLS
    assert TrimHold(enabled=False).apply(CONTROLS, False, 0) == CONTROLS


def test_flying_modes_of_both_autopilots() -> None:
    assert not is_flying_mode("ardupilot", ARDUPLANE_MODES["MANUAL"])
    assert all(is_flying_mode("ardupilot", ARDUPLANE_MODES[m])
               for m in ("FBWA", "CRUISE", "AUTO", "RTL", "LOITER", "TAKEOFF"))
    assert not any(is_flying_mode("px4", PX4_MODES[m]) for m in ("MANUAL", "ACRO"))
    assert not is_flying_mode("px4", 4 << 16 | 1 << 24)  # AUTO.READY
    assert not is_flying_mode("px4", 0)  # no main mode
    assert all(is_flying_mode("px4", PX4_MODES[m])
               for m in ("HOLD", "MISSION", "RTL", "TAKEOFF", "POSCTL", "ALTCTL", "STABILIZED"))
