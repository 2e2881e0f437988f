"""The shadow vehicle's state: what it tells ground stations beyond the estimate itself.

:class:`ShadowVehicle` follows the sensor samples the fusion service decodes and the
estimates the filter makes, and builds, through :class:`hil.shadow.ShadowEncoder`, the
frames of each stream group (wire units stay in :mod:`hil.shadow`):

fast (``telemetry_hz``)
    GLOBAL_POSITION_INT, ATTITUDE, ATTITUDE_QUATERNION, VFR_HUD, GPS_RAW_INT.
slow (1 Hz)
    SYS_STATUS, SYSTEM_TIME, ESTIMATOR_STATUS, EXTENDED_SYS_STATE, CURRENT_MODE,
    AVAILABLE_MODES_MONITOR; HOME_POSITION every other second (0.5 Hz) once aligned.

SYS_STATUS bits (present / enabled / healthy)
    A sensor is *present* once one of its samples was decoded; *enabled* when the filter uses
    it (the differential pressure only with air data on). *Healthy* over the last interval
    (between two SYS_STATUS, on estimate time): a sample within :data:`SAMPLE_TIMEOUT_S`, no
    new invalid sample, and for the aided sensors no rejections without an accepted update.
    GNSS is healthy only with a 3-D fix within the timeout that the filter fused within
    :data:`SAMPLE_TIMEOUT_S` (so an outage, a jammed receiver or rejected, possibly spoofed,
    fixes all clear it). The differential pressure is unhealthy while the pitot is declared
    blocked. The AHRS bit (the estimator) is healthy once aligned, except in an interval with
    a filter re-initialisation.

In air (EXTENDED_SYS_STATE)
    In air when the estimated speed is at least :data:`IN_AIR_SPEED_MPS` or the height above
    home at least :data:`IN_AIR_HEIGHT_M`; on the ground otherwise; undefined before
    alignment.
"""

from __future__ import annotations

import time
from typing import Final

import numpy as np

from fusion.estimate import Health, Mode, NavEstimate
from hil.codec import mavlink2
from hil.nav_events import NavEvent
from hil.shadow import SensorBits, ShadowEncoder
from sim.samples import AirspeedSample, BaroSample, GnssFix, ImuSample, MagSample

__all__ = ["IN_AIR_HEIGHT_M", "IN_AIR_SPEED_MPS", "SAMPLE_TIMEOUT_S", "ShadowVehicle"]

SAMPLE_TIMEOUT_S: Final = 2.0
"""A sensor without a sample (GNSS: without a fused 3-D fix) for this long is unhealthy, s."""
IN_AIR_SPEED_MPS: Final = 10.0
"""Speed from which the vehicle is in the air (a fixed wing's taxi speed is below), m/s."""
IN_AIR_HEIGHT_M: Final = 10.0
"""Height above home from which the vehicle is in the air, m."""

_S = mavlink2
_GYRO_ACCEL: Final = int(_S.MAV_SYS_STATUS_SENSOR_3D_GYRO | _S.MAV_SYS_STATUS_SENSOR_3D_ACCEL)
_KIND_BITS: Final = {
    "imu": _GYRO_ACCEL,
    "mag": int(_S.MAV_SYS_STATUS_SENSOR_3D_MAG),
    "baro": int(_S.MAV_SYS_STATUS_SENSOR_ABSOLUTE_PRESSURE),
    "gnss": int(_S.MAV_SYS_STATUS_SENSOR_GPS),
    "airspeed": int(_S.MAV_SYS_STATUS_SENSOR_DIFFERENTIAL_PRESSURE),
}
_AHRS: Final = int(_S.MAV_SYS_STATUS_AHRS)
_KINDS: Final = ((ImuSample, "imu"), (GnssFix, "gnss"), (BaroSample, "baro"),
                 (MagSample, "mag"), (AirspeedSample, "airspeed"))


class ShadowVehicle:
    """State and stream groups of the shadow vehicle (see the module docstring).

    Parameters
    ----------
    encoder : ShadowEncoder
    airspeed_enabled : bool
        The filter uses air data (``--airspeed`` not ``off``).
    """

    def __init__(self, encoder: ShadowEncoder, *, airspeed_enabled: bool = True) -> None:
        self.enc = encoder
        self.airspeed_enabled = airspeed_enabled
        self.last_fix: GnssFix | None = None
        self._last_us: dict[str, int] = {}
        self._prev_health: Health | None = None
        self._slow_ticks = 0
        self.mode: Mode | None = None

    # ------------------------------------------------------------ inputs
    def on_sample(self, sample: object) -> None:
        """Note a decoded sensor sample (other objects are ignored)."""
        for cls, kind in _KINDS:
            if isinstance(sample, cls):
                self._last_us[kind] = int(sample.time_us)
                if isinstance(sample, GnssFix):
                    self.last_fix = sample
                return

    # ------------------------------------------------------------ derived state
    def fix_lost(self, est: NavEstimate | None) -> bool:
        """No fix (any type) for :data:`SAMPLE_TIMEOUT_S` of estimate time."""
        if self.last_fix is None:
            return True
        now = self.enc.time_us if est is None else int(est.time_us)
        return now - self.last_fix.time_us > SAMPLE_TIMEOUT_S * 1e6

    def in_air(self, est: NavEstimate | None) -> bool | None:
        """In air / on ground (None before alignment), see the module docstring."""
        if est is None or est.mode == Mode.INITIALIZING or self.enc.home is None:
            return None
        speed = float(np.linalg.norm(est.v_ned_mps))
        return speed >= IN_AIR_SPEED_MPS or est.alt_msl_m - self.enc.home[2] >= IN_AIR_HEIGHT_M

    def sensor_bits(self, est: NavEstimate | None) -> SensorBits:
        """SYS_STATUS bits over the interval since the previous call (module docstring)."""
        present = _AHRS
        for kind in self._last_us:
            present |= _KIND_BITS[kind]
        enabled = present
        if not self.airspeed_enabled:
            enabled &= ~_KIND_BITS["airspeed"]
        if est is None:
            return SensorBits(present, enabled, 0)
        now = int(est.time_us)
        h, prev = est.health, self._prev_health
        self._prev_health = h
        if prev is None or h.time_rebases < prev.time_rebases:
            prev = h

        def grew(*names: str) -> bool:
            return sum(getattr(h, n) for n in names) > sum(getattr(prev, n) for n in names)

        def recent(kind: str) -> bool:
            t = self._last_us.get(kind)
            return t is not None and now - t <= SAMPLE_TIMEOUT_S * 1e6

        def aided_ok(prefix: str) -> bool:
            return not (grew(f"{prefix}_rejected") and not grew(f"{prefix}_fused"))

        health = 0
        if recent("imu") and not grew("imu_nan", "imu_out_of_range"):
            health |= _KIND_BITS["imu"]
        if recent("mag") and not grew("mag_invalid") and aided_ok("mag"):
            health |= _KIND_BITS["mag"]
        if recent("baro") and not grew("baro_invalid", "baro_frozen") and aided_ok("baro"):
            health |= _KIND_BITS["baro"]
        fix = self.last_fix
        fix_ok = (fix is not None and fix.fix_type >= 3 and recent("gnss")
                  and not self.fix_lost(est))
        fused_ok = est.mode == Mode.INITIALIZING or est.time_since_gnss_s <= SAMPLE_TIMEOUT_S
        if fix_ok and fused_ok:
            health |= _KIND_BITS["gnss"]
        air = est.air_data
        blocked = air is not None and air.state == "blocked"
        if recent("airspeed") and not grew("airspeed_invalid") and not blocked:
            health |= _KIND_BITS["airspeed"]
        if est.mode != Mode.INITIALIZING and not grew("time_rebases"):
            health |= _AHRS
        return SensorBits(present, enabled, health & present)

    # ------------------------------------------------------------ stream groups
    def fast(self, est: NavEstimate) -> list[bytes]:
        """The fast group of an aligned estimate."""
        return [*self.enc.telemetry(est),
                self.enc.gps_raw_int(self.last_fix, self.fix_lost(est))]

    def slow(self, est: NavEstimate | None, unix_s: float | None = None) -> list[bytes]:
        """The 1 Hz group (``est`` None or aligning: what is known without an estimate)."""
        self._slow_ticks += 1
        mode = Mode.INITIALIZING if est is None else Mode(est.mode)
        self.mode = mode
        frames = [self.enc.sys_status(self.sensor_bits(est)),
                  self.enc.system_time(time.time() if unix_s is None else unix_s)]
        if est is not None:
            frames.append(self.enc.estimator_status(est))
        frames.append(self.enc.extended_sys_state(self.in_air(est)))
        frames.append(self.enc.current_mode(mode))
        frames.append(self.enc.available_modes_monitor())
        home = self.enc.home_position()
        if home is not None and self._slow_ticks % 2 == 1:
            frames.append(home)
        return frames

    def statustexts(self, events: list[NavEvent]) -> list[bytes]:
        """One STATUSTEXT per event (already rate-limited by the detector)."""
        return [self.enc.statustext(ev.mav_severity, ev.message) for ev in events]
