"""PX4's failure-injection words for each fault event (``failure <unit> <type>``)."""

from __future__ import annotations

from sim.faults.events import IMU_EVENTS, FaultEvent, PitotBlockage, event_type_name

__all__ = ["PX4_FAILURE", "px4_failure"]

PX4_FAILURE: dict[str, tuple[str, str]] = {
    "gnss_outage": ("gps", "off"),
    "gnss_jamming": ("gps", "intermittent"),
    "gnss_degradation": ("gps", "garbage"),
    "gnss_spoof_drift": ("gps", "wrong"),
    "gnss_spoof_hijack": ("gps", "wrong"),
    "gnss_delay": ("gps", "delayed"),
    "gnss_rate": ("gps", "slow"),
    "baro_drift": ("baro", "wrong"),
    "baro_glitch": ("baro", "wrong"),
    "baro_freeze": ("baro", "stuck"),
    # Not a sensor failure; PX4's nearest word for "the baro reads a wrong value".
    "weather_front": ("baro", "wrong"),
    # IMU events name their unit in ``sensor``; the table gives the accelerometer entry and
    # px4_failure() resolves the gyro one.
    "imu_bias_step": ("accel", "wrong"),
    "imu_stuck": ("accel", "stuck"),
    "imu_saturation": ("accel", "wrong"),
    "mag_anomaly": ("mag", "wrong"),
    # pitot_blockage in mode "zero" resolves to ("airspeed", "wrong") in px4_failure().
    "pitot_blockage": ("airspeed", "stuck"),
    "pitot_drift": ("airspeed", "wrong"),
    "airspeed_failure": ("airspeed", "off"),
}
"""Type name -> PX4 failure injection ``(unit, type)`` (``failure <unit> <type>`` in the PX4
shell; units gps/baro/accel/gyro/mag/airspeed, types off/stuck/garbage/wrong/slow/delayed/
intermittent)."""


def px4_failure(event: FaultEvent) -> tuple[str, str]:
    """PX4 failure-injection ``(unit, type)`` of one event (IMU events: their own sensor).

    Parameters
    ----------
    event : FaultEvent

    Returns
    -------
    tuple of str
        ``(unit, type)``, e.g. ``("gyro", "stuck")``.
    """
    unit, kind = PX4_FAILURE[event_type_name(event)]
    if isinstance(event, IMU_EVENTS):
        unit = event.sensor
    if isinstance(event, PitotBlockage) and event.mode == "zero":
        kind = "wrong"
    return unit, kind
