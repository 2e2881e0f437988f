"""hilnav's estimate as the autopilot's navigation source during a run (``aiding: hilnav``).

The companion use case inside a scripted run: every estimate of hilnav's filter (the one the
run scores, fused from the same sensor stream the autopilot gets) goes to the autopilot over
its telemetry link as a companion computer would send it (:class:`hil.shadow.CompanionEncoder`):

* ArduPilot: GPS_INPUT at 5 Hz of simulated time, read by a second GPS instance of type
  MAVLink (``GPS2_TYPE 14``; the frames carry its ``gps_id`` 1, as ArduPilot's MAVLink GPS
  reads only the frames of its own instance) that EKF3 switches to when its own GPS loses
  its fix (``GPS_AUTO_SWITCH 1``: use the best);
* PX4: ODOMETRY at 30 Hz (position NED about the first estimate, body-axis velocity), fused by
  EKF2 as external vision (``EKF2_EV_CTRL 5``: horizontal position and velocity).

Those parameters (:func:`aiding_params`) are set by the script's parameter step, after the
parameter file's (a name the file sets is left to the file). The unaided autopilot
(``aiding: disabled``) has them set off (:func:`aiding_off_params`: ``GPS2_TYPE 0``,
``EKF2_EV_CTRL 0``) whatever the file says, so that an autopilot whose parameters persist from
an aided flight (ArduPilot SITL's ``eeprom.bin``, PX4's parameter file) flies unaided.

The frames are sent from hilnav's system id of the vehicle, component
MAV_COMP_ID_ONBOARD_COMPUTER (191), only once the filter navigates (no frame while it
initialises). :class:`CompanionAiding` is a link client of the telemetry recorder
(:meth:`hil.autopilot.telemetry.AutopilotTelemetry.attach`): the simulator thread offers
estimates, the recorder's thread sends the frames.
"""

from __future__ import annotations

from collections import deque
from typing import Any, Final

from fusion.estimate import NavEstimate
from hil.autopilot.param_file import PARAM_TYPE_INT32, PARAM_TYPE_REAL32, ParamValue
from hil.codec import mavlink2
from hil.shadow import CompanionEncoder

__all__ = ["AIDING_RATE_HZ", "CompanionAiding", "aiding_off_params", "aiding_params"]

ARDUPILOT_GPS_ID: Final = 1
"""GPS_INPUT's ``gps_id`` for ArduPilot's second GPS instance (``GPS2_TYPE``)."""
AIDING_RATE_HZ: Final = {"ardupilot": 5.0, "px4": 30.0}
"""Frames per second of simulated time: GPS_INPUT (ArduPilot), ODOMETRY (PX4)."""
_PARAMS: Final = {
    "ardupilot": (("GPS2_TYPE", 14.0, PARAM_TYPE_REAL32), ("GPS_AUTO_SWITCH", 1.0,
                                                           PARAM_TYPE_REAL32)),
    "px4": (("EKF2_EV_CTRL", 5.0, PARAM_TYPE_INT32),),
}
_OFF: Final = {
    "ardupilot": (("GPS2_TYPE", 0.0, PARAM_TYPE_REAL32),),
    "px4": (("EKF2_EV_CTRL", 0.0, PARAM_TYPE_INT32),),
}


def aiding_params(autopilot: str) -> tuple[ParamValue, ...]:
    """What ``autopilot`` needs set to navigate on hilnav's frames (see the module docstring);
    ``line`` 0: not from the parameter file."""
    return tuple(ParamValue(name, value, kind, 0) for name, value, kind in _PARAMS[autopilot])


def aiding_off_params(autopilot: str) -> tuple[ParamValue, ...]:
    """What turns ``autopilot``'s use of hilnav's frames off (its second GPS of type MAVLink;
    external vision); ``line`` 0: not from the parameter file."""
    return tuple(ParamValue(name, value, kind, 0) for name, value, kind in _OFF[autopilot])


class CompanionAiding:
    """Sends hilnav's estimates to the autopilot (see the module docstring).

    Parameters
    ----------
    autopilot : ``"ardupilot"`` or ``"px4"``
    system_id : int
        The vehicle's system id (the autopilot's; SITL: 1).
    """

    def __init__(self, autopilot: str, *, system_id: int = 1) -> None:
        if autopilot not in AIDING_RATE_HZ:
            raise ValueError(f"aiding: hilnav needs ardupilot or px4, not {autopilot!r}")
        self.autopilot = autopilot
        self.period_us = round(1e6 / AIDING_RATE_HZ[autopilot])
        self._encoder = CompanionEncoder(system_id,
                                         int(mavlink2.MAV_COMP_ID_ONBOARD_COMPUTER))
        self._out: deque[bytes] = deque()
        self._next_us: int | None = None
        self.sent = 0
        """Frames handed to the link."""

    def offer(self, est: NavEstimate) -> None:
        """A new estimate of hilnav's filter (simulator thread): framed when one is due."""
        if est.mode == "initializing":
            return
        t = int(est.time_us)
        if self._next_us is not None and t < self._next_us:
            return
        # on a fixed grid (the filter's epochs need not divide the period), never a burst
        self._next_us = t + self.period_us if self._next_us is None \
            or self._next_us + self.period_us <= t else self._next_us + self.period_us
        frame = (self._encoder.gps_input(est, gps_id=ARDUPILOT_GPS_ID)
                 if self.autopilot == "ardupilot"
                 else self._encoder.odometry(est))
        self._out.append(frame)

    # -- the link client (the recorder's thread) --
    def deliver(self, msg: Any) -> None:
        """Nothing is read back (the autopilot's use of the frames shows in its estimate)."""

    def take_outgoing(self) -> list[Any]:
        out = []
        while self._out:
            out.append(self._out.popleft())
        self.sent += len(out)
        return out

    def counters(self) -> dict[str, int]:
        return {"aiding_frames_sent": self.sent}
