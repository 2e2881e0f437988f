"""Flight mode names of ArduPlane and PX4 and the HEARTBEAT ``custom_mode`` they are flown as.

ArduPlane's ``custom_mode`` is its mode number (``Plane::Mode::Number``: MANUAL 0, FBWA 5,
AUTO 10, ...). PX4 packs ``main_mode << 16 | sub_mode << 24`` (``px4_custom_mode.h``: main
modes MANUAL 1, ALTCTL 2, POSCTL 3, AUTO 4, ACRO 5, OFFBOARD 6, STABILIZED 7; AUTO's sub
modes READY 1, TAKEOFF 2, LOITER 3, MISSION 4, RTL 5, LAND 6). Commanding a mode with
MAV_CMD_DO_SET_MODE takes ``param1`` = MAV_MODE_FLAG_CUSTOM_MODE_ENABLED and then ArduPilot's
mode number in ``param2``; PX4's main mode in ``param2`` and sub mode in ``param3``
(:func:`set_mode_params`).

A *flying* mode is one in which the autopilot flies the aircraft by itself with no pilot
input: every ArduPlane mode but MANUAL (surfaces follow the sticks, which nobody moves) and
INITIALISING; every PX4 mode but MANUAL, ACRO (stick pass-through / body rates) and AUTO.READY
(armed, nothing to fly). The trim hold (:mod:`hil.autopilot.arming`) ends only in one.
"""

from __future__ import annotations

from typing import Final

__all__ = ["ARDUPLANE_MODES", "PX4_MODES", "is_flying_mode", "mode_name", "mode_names",
           "set_mode_params"]

ARDUPLANE_MODES: Final[dict[str, int]] = {
    "MANUAL": 0, "CIRCLE": 1, "STABILIZE": 2, "TRAINING": 3, "ACRO": 4, "FBWA": 5, "FBWB": 6,
    "CRUISE": 7, "AUTOTUNE": 8, "AUTO": 10, "RTL": 11, "LOITER": 12, "TAKEOFF": 13,
    "GUIDED": 15, "THERMAL": 24,
}
"""ArduPlane's fixed-wing modes -> custom_mode (its mode number)."""

_PX4_MAIN: Final = {"MANUAL": 1, "ALTCTL": 2, "POSCTL": 3, "AUTO": 4, "ACRO": 5, "OFFBOARD": 6,
                    "STABILIZED": 7}
_PX4_AUTO_SUB: Final = {"READY": 1, "TAKEOFF": 2, "LOITER": 3, "MISSION": 4, "RTL": 5,
                        "LAND": 6}


def _px4(main: str, sub: str | None = None) -> int:
    return _PX4_MAIN[main] << 16 | (0 if sub is None else _PX4_AUTO_SUB[sub]) << 24


PX4_MODES: Final[dict[str, int]] = {
    "MANUAL": _px4("MANUAL"), "STABILIZED": _px4("STABILIZED"), "ACRO": _px4("ACRO"),
    "ALTCTL": _px4("ALTCTL"), "POSCTL": _px4("POSCTL"), "OFFBOARD": _px4("OFFBOARD"),
    "HOLD": _px4("AUTO", "LOITER"), "LOITER": _px4("AUTO", "LOITER"),
    "MISSION": _px4("AUTO", "MISSION"), "TAKEOFF": _px4("AUTO", "TAKEOFF"),
    "RTL": _px4("AUTO", "RTL"), "LAND": _px4("AUTO", "LAND"),
}
"""PX4's modes -> custom_mode (``main << 16 | sub << 24``); HOLD is AUTO.LOITER (QGC's name)."""

_TABLES: Final = {"ardupilot": ARDUPLANE_MODES, "px4": PX4_MODES}
_NOT_FLYING: Final = {
    "ardupilot": frozenset({ARDUPLANE_MODES["MANUAL"], 16}),  # 16: INITIALISING
    "px4": frozenset({PX4_MODES["MANUAL"], PX4_MODES["ACRO"], _px4("AUTO", "READY")}),
}


def _table(autopilot: str) -> dict[str, int]:
    try:
        return _TABLES[autopilot]
    except KeyError:
        raise ValueError(f"no flight modes known for autopilot {autopilot!r}; valid: "
                         f"{', '.join(_TABLES)}") from None


def mode_names(autopilot: str) -> tuple[str, ...]:
    """The mode names of ``autopilot`` (``"ardupilot"`` or ``"px4"``)."""
    return tuple(_table(autopilot))


def custom_mode(autopilot: str, name: str) -> int:
    """The HEARTBEAT ``custom_mode`` of mode ``name`` (KeyError: not a mode of it)."""
    return _table(autopilot)[name.upper()]


def mode_name(autopilot: str, custom: int) -> str:
    """The name of ``custom`` (``custom_mode``) for reports; ``"MODE <n>"`` when unknown."""
    for name, value in _table(autopilot).items():
        if value == custom:
            return name
    return f"MODE {custom}"


def is_flying_mode(autopilot: str, custom: int) -> bool:
    """Whether ``custom`` is a flying mode (see the module docstring). A PX4 custom_mode with
    no main mode (0) is not one."""
    if autopilot == "px4" and (custom >> 16) & 0xFF == 0:
        return False
    return custom not in _NOT_FLYING[autopilot] if autopilot in _NOT_FLYING else False


def set_mode_params(autopilot: str, custom: int) -> tuple[float, float, float]:
    """``(param1, param2, param3)`` of MAV_CMD_DO_SET_MODE for ``custom`` (see the module
    docstring; param1 = MAV_MODE_FLAG_CUSTOM_MODE_ENABLED = 1)."""
    if autopilot == "px4":
        return 1.0, float((custom >> 16) & 0xFF), float((custom >> 24) & 0xFF)
    return 1.0, float(custom), 0.0
