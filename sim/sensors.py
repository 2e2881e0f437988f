"""The sensor suite: turns the simulator's truth into IMU, GNSS, barometer, magnetometer and
(when a pitot is fitted) airspeed samples, each sensor with its own seeded random generator.

The error models live in ``sim.imu``, ``sim.gnss``, ``sim.baro``, ``sim.mag`` and
``sim.pitot`` (re-exported here); the atmosphere in ``sim.atmosphere``; named presets in
``sim.presets``.

Timing (all from simulated time, ``Truth.time_us``):

- IMU: every ``sim_rate / imu_rate``-th step (the ratio must be an integer), starting with the
  first step. A sample is the trapezoidal average of the truth over its interval
  (``0.5·x0 + x1 + … + 0.5·xN``)/N, ``time_us`` the end of the interval, ``dt_s`` its length
  (the very first sample has no past and uses the first truth as it is).
- GNSS, barometer, magnetometer, pitot: at their own rates on a drift-free schedule
  (``sim._sensor_common.RateSchedule``), sampled at the step whose time reaches the due time.
  A GNSS fix is valid at that step's time but is *emitted* ``latency_s`` later; it keeps its
  time of validity in ``GnssFix.time_us``.
- :meth:`SensorSuite.step` returns the samples due at a step in time order: delayed GNSS
  fixes first (their time is earlier or equal), then IMU, barometer, magnetometer, airspeed.
- The barometer's optional static-port position error takes the truth's air-relative body
  velocity (``sim.pitot.air_velocity_b_mps``).

Determinism: ``numpy.random.SeedSequence(seed).spawn(6)`` gives the IMU, GNSS, barometer,
magnetometer, pitot and IMU-thermal generators (in that order; a child does not depend on how
many are spawned after it), so one sensor's configuration never changes another sensor's
noise -- fitting a pitot or a thermal IMU model or not leaves the other streams bit-identical
-- and the same scenario and seed give bit-identical streams.

A thermal IMU model (``imu_thermal``, off by default) adds its bias to the IMU's error and
its scale-factor error to the true input, and the IMU sample then carries the temperature the
part reports instead of the air's.

Cost: about 17-19 µs per :meth:`SensorSuite.step` at 200 Hz with 200 Hz IMU, 50 Hz baro and
magnetometer, 5 Hz GNSS (2-core CI-class machine; 2.5 µs of it is building the frozen
``ImuSample``). Random numbers are drawn in blocks and the per-step path works on Python
floats.
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np

from physconst.geomag import DEFAULT_DECIMAL_YEAR
from sim._sensor_common import Finite, Positive, RateSchedule, SensorConfigModel
from sim.baro import BaroConfig, BaroModel
from sim.gnss import GnssConfig, GnssModel
from sim.imu import AccelConfig, GyroConfig, ImuConfig, ImuModel
from sim.imu_thermal import ImuThermalConfig, ImuThermalModel
from sim.mag import MagConfig, MagModel
from sim.pitot import PitotConfig, PitotModel, air_velocity_b_mps
from sim.samples import AirspeedSample, BaroSample, GnssFix, ImuSample, MagSample, Truth

__all__ = [
    "AccelConfig",
    "BaroConfig",
    "BaroModel",
    "GnssConfig",
    "GnssModel",
    "GyroConfig",
    "ImuConfig",
    "ImuModel",
    "ImuThermalConfig",
    "ImuThermalModel",
    "MagConfig",
    "MagModel",
    "PitotConfig",
    "PitotModel",
    "SensorSuite",
    "SensorSuiteConfig",
]

SensorSample = ImuSample | GnssFix | BaroSample | MagSample | AirspeedSample


class SensorSuiteConfig(SensorConfigModel):
    """All sensors of one vehicle.

    Attributes
    ----------
    imu, gnss, baro, mag : the sensor configurations (GNSS rate is ``gnss.rate_hz``).
    pitot : the pitot-static airspeed sensor; None = the aircraft has none.
    imu_rate_hz : IMU output rate, Hz; None = the simulation rate. Must divide it.
    baro_rate_hz, mag_rate_hz, pitot_rate_hz : Hz, at most the simulation rate (the pitot's
        default 50 Hz is what PX4's simulator sends in HIL_SENSOR).
    decimal_year : the simulated date, e.g. 2026.5: the magnetometer's Earth field is the
        World Magnetic Model's at this date (:mod:`physconst.geomag`).
    imu_thermal : the IMU's temperature and thermal errors (:mod:`sim.imu_thermal`); None
        (the default): none, and the IMU's samples carry the air's temperature.
    """

    imu: ImuConfig
    gnss: GnssConfig
    baro: BaroConfig
    mag: MagConfig
    imu_rate_hz: Positive | None = None
    baro_rate_hz: Positive = 50.0
    mag_rate_hz: Positive = 50.0
    pitot: PitotConfig | None = None
    pitot_rate_hz: Positive = 50.0
    decimal_year: Finite = DEFAULT_DECIMAL_YEAR
    imu_thermal: ImuThermalConfig | None = None


class SensorSuite:
    """Steps every sensor with each truth sample.

    Parameters
    ----------
    config : SensorSuiteConfig
    seed : int
        Non-negative scenario seed; one independent generator per sensor is spawned from it.
    sim_rate_hz : float
        Rate at which :meth:`step` is called (the truth rate), Hz.

    Attributes
    ----------
    imu : ImuModel
    gnss : GnssModel
    baro : BaroModel
    mag : MagModel or None
        Built at the first step; follows the truth's position (World Magnetic Model).
    pitot : PitotModel or None
        None when no pitot is configured.
    imu_thermal : ImuThermalModel or None
        None when no thermal model is configured.
    imu_decimation : int
        Simulation steps per IMU sample.

    Raises
    ------
    ValueError
        Negative seed, a sensor rate above the simulation rate, or an IMU rate that does not
        divide the simulation rate.
    """

    def __init__(self, config: SensorSuiteConfig, seed: int, sim_rate_hz: float) -> None:
        if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or seed < 0:
            raise ValueError(f"seed must be a non-negative integer (got {seed!r})")
        if not (math.isfinite(sim_rate_hz) and sim_rate_hz > 0.0):
            raise ValueError(f"sim_rate_hz must be positive and finite (got {sim_rate_hz!r})")
        imu_rate = config.imu_rate_hz if config.imu_rate_hz is not None else sim_rate_hz
        ratio = sim_rate_hz / imu_rate
        decimation = round(ratio)
        if decimation < 1 or abs(ratio - decimation) > 1e-9 * ratio:
            raise ValueError(
                f"imu_rate_hz ({imu_rate} Hz) must divide the simulation rate ({sim_rate_hz} Hz)"
            )
        for name, rate in (
            ("gnss.rate_hz", config.gnss.rate_hz),
            ("baro_rate_hz", config.baro_rate_hz),
            ("mag_rate_hz", config.mag_rate_hz),
            ("pitot_rate_hz", config.pitot_rate_hz if config.pitot is not None else 0.0),
        ):
            if rate > sim_rate_hz * (1.0 + 1e-12):
                raise ValueError(
                    f"{name} ({rate} Hz) exceeds the simulation rate ({sim_rate_hz} Hz)"
                )

        self.config = config
        self.sim_rate_hz = float(sim_rate_hz)
        self.imu_decimation = decimation
        rng_imu, rng_gnss, rng_baro, rng_mag, rng_pitot, rng_thermal = (
            np.random.default_rng(s) for s in np.random.SeedSequence(int(seed)).spawn(6)
        )
        self.imu = ImuModel(config.imu, rng_imu, imu_rate)
        self.gnss = GnssModel(config.gnss, rng_gnss)
        self.baro = BaroModel(config.baro, rng_baro)
        self.mag: MagModel | None = None
        self._rng_mag = rng_mag
        self._imu_dt_s = decimation / self.sim_rate_hz
        self._gnss_schedule = RateSchedule(config.gnss.rate_hz)
        self._baro_schedule = RateSchedule(config.baro_rate_hz)
        self._mag_schedule = RateSchedule(config.mag_rate_hz)
        self.pitot = PitotModel(config.pitot, rng_pitot) if config.pitot is not None else None
        self._pitot_schedule = RateSchedule(config.pitot_rate_hz)
        self.imu_thermal = (
            None if config.imu_thermal is None
            else ImuThermalModel(config.imu_thermal, rng_thermal,
                                 config.baro.sea_level_temperature_offset_k)
        )
        self._baro_air = config.baro.has_position_error
        self._gnss_latency_us = self.gnss.params.latency_us
        self._gnss_queue: deque[tuple[int, GnssFix]] = deque()
        self._prev: list[float] | None = None
        self._acc = [0.0] * 6
        self._count = 0

    def pending_gnss(self) -> int:
        """Number of fixes measured but not yet emitted (latency queue)."""
        return len(self._gnss_queue)

    def step(self, truth: Truth) -> list[SensorSample]:
        """Advance every sensor to ``truth.time_us``; return the samples due now, in time order.

        Parameters
        ----------
        truth : Truth
            The true state at this simulation step (steps at ``sim_rate_hz``).

        Returns
        -------
        list of ImuSample | GnssFix | BaroSample | MagSample | AirspeedSample
        """
        t = truth.time_us
        out: list[SensorSample] = []

        gs = self._gnss_schedule
        if t >= gs.next_us and gs.due(t):
            fix = self.gnss.measure(truth)
            self._gnss_queue.append((t + self._gnss_latency_us, fix))
        queue = self._gnss_queue
        while queue and queue[0][0] <= t:
            out.append(queue.popleft()[1])

        # Plain floats: a NumPy call on a 3-vector costs ~1 µs, more than the arithmetic.
        x = truth.specific_force_b_mps2.tolist() + truth.omega_b_rps.tolist()
        prev = self._prev
        u: list[float] | None
        if prev is None:
            u = x
            self._prev = x
        elif self.imu_decimation == 1:
            p0, p1, p2, p3, p4, p5 = prev
            x0, x1, x2, x3, x4, x5 = x
            u = [(p0 + x0) * 0.5, (p1 + x1) * 0.5, (p2 + x2) * 0.5,
                 (p3 + x3) * 0.5, (p4 + x4) * 0.5, (p5 + x5) * 0.5]
            self._prev = x
        else:
            self._count += 1
            if self._count < self.imu_decimation:
                acc = self._acc
                for i in range(6):
                    acc[i] += x[i]
                u = None
            else:
                n = self.imu_decimation
                u = [(s + 0.5 * (a + b)) / n for s, a, b in zip(self._acc, prev, x, strict=True)]
                self._acc = [0.0] * 6
                self._count = 0
                self._prev = x
        if u is not None:
            thermal = self.imu_thermal
            if thermal is None:
                y = np.array(self.imu.measure_list(u))
                out.append(ImuSample(t, self._imu_dt_s, y[:3], y[3:], truth.temperature_k))
            else:
                thermal.step(t, truth.alt_msl_m)
                u = [v * (1.0 + s) for v, s in zip(u, thermal.scale, strict=True)]
                y = np.array(self.imu.measure_list(u, thermal.bias))
                out.append(ImuSample(t, self._imu_dt_s, y[:3], y[3:],
                                     thermal.reported_temperature_k))

        bs = self._baro_schedule
        if t >= bs.next_us and bs.due(t):
            air = air_velocity_b_mps(truth) if self._baro_air else None
            out.append(self.baro.measure(t, truth.alt_msl_m, air))

        mag = self.mag
        if mag is None:
            mag = self.mag = MagModel(
                self.config.mag, self._rng_mag, truth.lat_rad, truth.lon_rad, truth.alt_msl_m,
                self.config.decimal_year,
            )
        ms = self._mag_schedule
        if t >= ms.next_us and ms.due(t):
            mag.move_to(truth.lat_rad, truth.lon_rad, truth.alt_msl_m)
            out.append(mag.measure(t, truth.q_nb))
        pitot = self.pitot
        if pitot is not None:
            ps = self._pitot_schedule
            if t >= ps.next_us and ps.due(t):
                out.append(pitot.measure(truth))
        return out
