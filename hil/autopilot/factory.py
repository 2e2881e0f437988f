"""The one place that builds an autopilot backend from its kind and settings.

The protocol backends live in their own modules (:mod:`hil.autopilot.px4`,
:mod:`hil.autopilot.ardupilot`) and are imported only when asked for, so a scenario flown by
hilnav's own guidance never loads them.
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Final

from hil.autopilot.backend import AutopilotBackend
from hil.pipeline import SimSetup

__all__ = ["AUTOPILOT_KINDS", "BackendSettings", "close_backend", "make_backend"]

AUTOPILOT_KINDS: Final = ("px4", "ardupilot")
"""The autopilots that can fly (``none``, hilnav's guidance, needs no backend)."""


@dataclass(frozen=True)
class BackendSettings:
    """What a backend is built from (None: the backend's default).

    ``link``: where the simulator meets the autopilot (PX4 ``tcpin:HOST:4560`` or
    ``serial:DEV:BAUD``; ArduPilot ``udpin:HOST:9002``). ``actuator_map`` (PX4) /
    ``servo_map`` (ArduPilot): the YAML file of the map. ``mavlink`` (ArduPilot): its MAVLink
    port for the simulated-GPS parameters of ``setup``'s GNSS events.
    """

    link: str | None = None
    actuator_map: Path | None = None
    servo_map: Path | None = None
    mavlink: str | None = None
    setup: SimSetup | None = None


def _load(module: str, what: str) -> Any:
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        if exc.name not in (module, None) and not str(exc).startswith("import of"):
            raise
        raise ValueError(f"this hilnav has no {what} backend (no module {module})") \
            from None


def make_backend(kind: str, settings: BackendSettings | None = None) -> AutopilotBackend:
    """The backend of autopilot ``kind`` (``"px4"`` or ``"ardupilot"``).

    Raises
    ------
    ValueError
        An unknown kind, a map file the backend refuses, a bad link URL, a setting of the
        other autopilot, or a backend this installation lacks.
    """
    s = settings or BackendSettings()
    if kind == "px4":
        if s.servo_map is not None or s.mavlink is not None:
            raise ValueError("servo_map and mavlink are ArduPilot settings, not PX4's")
        px4 = _load("hil.autopilot.px4", "PX4")
        kwargs: dict[str, Any] = {}
        if s.actuator_map is not None:
            kwargs["actuator_map"] = _load("hil.autopilot.actuators", "PX4").ActuatorMap.load(
                s.actuator_map)
        backend: AutopilotBackend = (px4.Px4Backend(s.link, **kwargs) if s.link is not None
                                     else px4.Px4Backend(**kwargs))
        return backend
    if kind == "ardupilot":
        if s.actuator_map is not None:
            raise ValueError("actuator_map is a PX4 setting; ArduPilot takes a servo_map")
        ardupilot = _load("hil.autopilot.ardupilot", "ArduPilot")
        kwargs = {"setup": s.setup, "mavlink_url": s.mavlink}
        if s.servo_map is not None:
            kwargs["servo_map"] = _load("hil.autopilot.servos", "ArduPilot").ServoMap.load(
                s.servo_map)
        backend = (ardupilot.ArduPilotBackend(s.link, **kwargs) if s.link is not None
                   else ardupilot.ArduPilotBackend(**kwargs))
        return backend
    raise ValueError(f"unknown autopilot {kind!r}; valid: {', '.join(AUTOPILOT_KINDS)}")


def close_backend(backend: AutopilotBackend) -> None:
    """Close a backend that holds sockets (the protocol does not require ``close``)."""
    close = getattr(backend, "close", None)
    if callable(close):
        close()
