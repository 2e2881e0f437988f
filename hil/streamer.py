"""Sensor streamer: one simulator step's truth and samples -> MAVLink 2 frames.

The streamer is the only place where simulator output meets the wire. Per IMU sample it sends one
HIL_SENSOR carrying the IMU fields plus any baro / magnetometer / airspeed sample of the same
step (their ``fields_updated`` bits set only then; the airspeed as ``diff_pressure``, bit 10;
with a thermal IMU the IMU frame carries its temperature and the others follow in a frame of
their own),
HIL_GPS for each GNSS fix (emitted when the receiver outputs it, stamped with its time of
validity), and the truth as HIL_STATE_QUATERNION from the simulator's truth component at
``truth_rate_hz``. The vehicle state a flight controller would report
(:mod:`sim.vehicle_state`) follows, from the autopilot component: HIL_ACTUATOR_CONTROLS for each
ActuatorSample, then RAW_RPM for each RpmSample of the step (RAW_RPM has no timestamp, so it
comes last, after frames of its own time). An optional :class:`sim.faults.FaultInjector`
applies the scenario's fault timeline to each step's samples before they are encoded.
:mod:`hil.pipeline` drives it, in lockstep or paced live.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from hil.codec import Encoder
from sim.faults import FaultInjector, FaultLogEntry
from sim.samples import (
    ActuatorSample,
    AirspeedSample,
    BaroSample,
    GnssFix,
    ImuSample,
    MagSample,
    RpmSample,
    Sample,
    Truth,
)


@dataclass(frozen=True)
class GnssWindow:
    """GNSS switched off (no HIL_GPS sent) for fixes valid in [start_s, start_s + duration_s)."""

    start_s: float
    duration_s: float

    def covers(self, time_us: int) -> bool:
        t = time_us * 1e-6
        return self.start_s <= t < self.start_s + self.duration_s

    @classmethod
    def parse(cls, text: str) -> GnssWindow:
        """Parse ``START:DURATION`` in seconds, e.g. ``300:60``."""
        try:
            start, duration = (float(p) for p in text.split(":"))
        except ValueError:
            raise ValueError(
                f"GNSS outage {text!r} must be START:DURATION in seconds, e.g. 300:60"
            ) from None
        if start < 0 or duration <= 0:
            raise ValueError(f"GNSS outage {text!r}: start must be >= 0 and duration > 0")
        return cls(start, duration)


class SensorStreamer:
    """Encodes simulator output into frames, in the order a real sensor bus would emit them.

    Parameters
    ----------
    encoder : Encoder, optional
    truth_rate_hz : float
        Rate of the HIL_STATE_QUATERNION truth frames, Hz.
    gnss_off : sequence of GnssWindow
        Windows (by time of validity) whose fixes are not sent (counted in
        ``gnss_suppressed``).
    faults : FaultInjector, optional
        Applied to every step's samples before encoding (and before ``gnss_off``).
    imu_temperature : bool
        Send each IMU sample's temperature (a thermal IMU model): every IMU frame carries it
        in HIL_SENSOR ``temperature`` (bit 12), and the barometer, magnetometer and airspeed
        of the step go in a second HIL_SENSOR frame of the same time with the barometer's
        temperature. Off (the default): one frame per step, the temperature only with the
        barometer.
    """

    def __init__(
        self,
        encoder: Encoder | None = None,
        *,
        truth_rate_hz: float = 50.0,
        gnss_off: Sequence[GnssWindow] = (),
        faults: FaultInjector | None = None,
        imu_temperature: bool = False,
    ) -> None:
        if truth_rate_hz <= 0:
            raise ValueError("truth_rate_hz must be > 0")
        self.encoder = encoder or Encoder()
        self._truth_period_us = round(1e6 / truth_rate_hz)
        self._next_truth_us: int | None = None
        self._gnss_off = tuple(gnss_off)
        self.gnss_suppressed = 0
        self.faults = faults
        self.imu_temperature = imu_temperature
        self.last_samples: Sequence[Sample] = ()
        """The samples of the last :meth:`frames` call as sent: after the fault timeline (the
        GNSS windows, which drop whole fixes, not applied)."""

    @property
    def fault_log(self) -> list[FaultLogEntry]:
        """The injector's event starts and ends so far (empty without an injector)."""
        return self.faults.log if self.faults is not None else []

    @property
    def fault_counters(self) -> dict[str, int]:
        """A copy of the injector's counters (empty without an injector)."""
        return dict(self.faults.counters) if self.faults is not None else {}

    def frames(self, truth: Truth, samples: Sequence[Sample]) -> list[tuple[int, bytes]]:
        """Frames for one step: ``[(time_us, frame), ...]`` in emission order."""
        if self.faults is not None:
            samples = self.faults.apply(truth, samples)
        self.last_samples = samples
        out: list[tuple[int, bytes]] = []
        imu: ImuSample | None = None
        baro: BaroSample | None = None
        mag: MagSample | None = None
        vehicle: list[tuple[int, bytes]] = []
        airspeed: AirspeedSample | None = None
        for s in samples:
            if isinstance(s, ImuSample):
                if imu is not None:
                    out.append((imu.time_us, self.encoder.sensors(
                        imu, imu_temperature=self.imu_temperature)))
                imu = s
            elif isinstance(s, BaroSample):
                baro = s
            elif isinstance(s, MagSample):
                mag = s
            elif isinstance(s, AirspeedSample):
                airspeed = s
            elif isinstance(s, GnssFix):
                if any(w.covers(s.time_us) for w in self._gnss_off):
                    self.gnss_suppressed += 1
                else:
                    out.append((truth.time_us, self.encoder.gnss(s)))
            elif isinstance(s, ActuatorSample):
                vehicle.append((s.time_us, self.encoder.actuators(s)))
            elif isinstance(s, RpmSample):
                vehicle.append((s.time_us, self.encoder.rpm(s)))
        if self.imu_temperature and imu is not None:
            out.append((imu.time_us, self.encoder.sensors(imu, imu_temperature=True)))
            if baro is not None or mag is not None or airspeed is not None:
                out.append((imu.time_us, self.encoder.sensors(
                    None, baro, mag, time_us=imu.time_us, airspeed=airspeed)))
        elif imu is not None or baro is not None or mag is not None or airspeed is not None:
            t = imu.time_us if imu is not None else truth.time_us
            out.append(
                (t, self.encoder.sensors(imu, baro, mag, time_us=t, airspeed=airspeed))
            )
        if self._next_truth_us is None or truth.time_us >= self._next_truth_us:
            out.append((truth.time_us, self.encoder.truth(truth)))
            base = truth.time_us if self._next_truth_us is None else self._next_truth_us
            self._next_truth_us = base + self._truth_period_us
        out.extend(vehicle)
        return out
