"""NavFilter's link to air data: the air-data clock, the static air and the vehicle inputs.

Air data (:mod:`fusion.aiding.airspeed`, layouts ``+air``): pitot samples are screened and
batched as they arrive; every ``1 / AirspeedTuning.fuse_rate_hz`` of IMU time one air-data
epoch starts the dormant wind and airspeed-scale states (first airspeed above
``min_airspeed_mps``), fuses the true airspeed through the pitot monitor
(:mod:`fusion.aiding.pitot_monitor`: a blocked pitot is only tested), the synthetic sideslip
of a fixed-wing, and, with GNSS lost and no usable pitot, the synthetic airspeed. With GNSS
lost and an airspeed fused within ``timeout_s`` the mode is ``dead-reckoning``.

:class:`AirDataLink` keeps what the epochs need besides the filter's state: when the next
epoch is due, the static pressure and temperature of the last accepted baro sample (the
airspeed conversion's air density, with ISA where there is none), and the latest control
surfaces and propeller speed (the inputs of a learned airspeed model,
:class:`~fusion.airspeed_model.AirspeedInputs`).
"""

from __future__ import annotations

import math

from fusion.airspeed_model import AirspeedInputs
from fusion.estimate import AirDataStatus
from fusion.rotations import dcm_from_quat, euler_from_quat
from fusion.samples import ActuatorSample, RpmSample
from fusion.strapdown import InsState
from physconst.airdata import air_density_kgpm3
from physconst.isa import isa_pressure_pa, isa_temperature_k

NEVER_US = 1 << 62
"""The air-data epoch time of a filter without air data."""
AIR_OFF = AirDataStatus()
_INPUT_MAX_AGE_US = 1_000_000  # controls / rpm older than this: the learned model has no inputs


class AirDataLink:
    """The air-data epoch clock and the air-data inputs (module docstring).

    Parameters
    ----------
    period_us : int
        Interval between air-data epochs, µs.
    """

    def __init__(self, period_us: int) -> None:
        self._period_us = period_us
        self.next_us = NEVER_US
        """Time of the next air-data epoch (:data:`NEVER_US` before a start)."""
        self.status = AIR_OFF
        """The air-data status after the last epoch."""
        self._static_pa = math.nan  # last accepted baro pressure and temperature
        self._static_temp_k = math.nan
        self._controls = (0.0, 0.0, 0.0)  # latest aileron, elevator (pitch), throttle
        self._controls_us = self._rpm_us = -NEVER_US
        self._rpm = 0.0

    def start(self, time_us: int) -> None:
        """The filter (re)started at ``time_us``: the first epoch is one period later."""
        self.next_us = time_us + self._period_us

    def advance(self, t_us: int) -> None:
        """An epoch is due at ``t_us`` (``t_us >= next_us``): move the clock on by one period,
        or to one period after ``t_us`` after a gap."""
        self.next_us += self._period_us
        if self.next_us <= t_us:
            self.next_us = t_us + self._period_us

    def on_static(self, pressure_pa: float, temperature_k: object) -> None:
        """An accepted baro sample's pressure (Pa) and temperature (K; anything that is not a
        number counts as unknown)."""
        self._static_pa = pressure_pa
        try:
            self._static_temp_k = float(temperature_k)  # type: ignore[arg-type]
        except (TypeError, ValueError):
            self._static_temp_k = math.nan

    def on_controls(self, s: ActuatorSample) -> None:
        """The latest control surfaces and throttle (aileron, elevator, throttle: channels 0,
        1 and 3)."""
        c = s.controls
        if len(c) >= 4:
            self._controls = (float(c[0]), float(c[1]), float(c[3]))
            self._controls_us = int(s.time_us)

    def on_rpm(self, s: RpmSample) -> None:
        """The first propeller's speed (RAW_RPM index 0)."""
        if getattr(s, "index", 0) == 0:
            self._rpm = float(s.rpm)
            self._rpm_us = int(s.time_us)

    def static_air(self, ins: InsState) -> tuple[float, float]:
        """Static pressure (Pa) and temperature (K) for the airspeed conversion: the last
        baro sample's, ISA at the INS height where it has none."""
        p, temp = self._static_pa, self._static_temp_k
        if not math.isfinite(p):  # no baro yet: ISA at the INS height
            p = isa_pressure_pa(ins.alt_msl_m)
            temp = math.nan
        if not 150.0 <= temp <= 350.0:
            temp = isa_temperature_k(ins.alt_msl_m)
        return p, temp

    def model_inputs(
        self, t_us: int, ins: InsState, f_n_mps2: tuple[float, float, float], p: float,
        temp: float,
    ) -> AirspeedInputs | None:  # fmt: skip
        """The learned airspeed model's inputs now (``None`` without fresh controls and rpm).

        Parameters
        ----------
        t_us : int
        ins : InsState
        f_n_mps2 : 3 floats
            Specific force in NED, m/s^2.
        p, temp : float
            Static pressure (Pa) and temperature (K).
        """
        if t_us - self._controls_us > _INPUT_MAX_AGE_US or t_us - self._rpm_us > _INPUT_MAX_AGE_US:
            return None
        roll, pitch, _ = euler_from_quat(ins.q_nb)
        c = dcm_from_quat(ins.q_nb)  # C_nb row-major: f_b = C_nb^T f_n
        fn, fe, fd = f_n_mps2
        fx_b, fz_b = c[0] * fn + c[3] * fe + c[6] * fd, c[2] * fn + c[5] * fe + c[8] * fd
        aileron, elevator, throttle = self._controls
        return AirspeedInputs(
            throttle=throttle, elevator=elevator, aileron=aileron, rpm_krpm=1e-3 * self._rpm,
            density_kgpm3=air_density_kgpm3(p, temp), roll_rad=roll, pitch_rad=pitch,
            fx_b_mps2=fx_b, fz_b_mps2=fz_b, climb_rate_mps=-ins.v_ned_mps[2],
        )  # fmt: skip
