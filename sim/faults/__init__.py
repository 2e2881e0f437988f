"""Fault injection: a scenario's timeline of GNSS, barometer, IMU, magnetometer and pitot faults
applied to the sensor stream between :class:`sim.sensors.SensorSuite` and the encoder.

Modules: :mod:`sim.faults.events` (the event types), :mod:`sim.faults.timeline` (the check
that a timeline is consistent), :mod:`sim.faults.injector` (the runtime applying it to the
samples), :mod:`sim.faults.px4` (PX4's failure-injection words for each event).
"""

from sim.faults.events import (
    EVENT_TYPES,
    AirspeedFailure,
    BaroDrift,
    BaroFreeze,
    BaroGlitch,
    FaultEvent,
    GnssDegradation,
    GnssDelay,
    GnssJamming,
    GnssOutage,
    GnssRate,
    GnssSpoofDrift,
    GnssSpoofHijack,
    ImuBiasStep,
    ImuSaturation,
    ImuStuck,
    MagAnomaly,
    PitotBlockage,
    PitotDrift,
    WeatherFront,
)
from sim.faults.injector import GNSS_TAIL_S, PREARM_S, FaultInjector, FaultLogEntry
from sim.faults.px4 import PX4_FAILURE, px4_failure
from sim.faults.timeline import check_events

__all__ = [
    "EVENT_TYPES",
    "GNSS_TAIL_S",
    "PREARM_S",
    "PX4_FAILURE",
    "AirspeedFailure",
    "BaroDrift",
    "BaroFreeze",
    "BaroGlitch",
    "FaultEvent",
    "FaultInjector",
    "FaultLogEntry",
    "GnssDegradation",
    "GnssDelay",
    "GnssJamming",
    "GnssOutage",
    "GnssRate",
    "GnssSpoofDrift",
    "GnssSpoofHijack",
    "ImuBiasStep",
    "ImuSaturation",
    "ImuStuck",
    "MagAnomaly",
    "PitotBlockage",
    "PitotDrift",
    "WeatherFront",
    "check_events",
    "px4_failure",
]
