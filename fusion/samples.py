"""What :class:`fusion.filter.NavFilter` reads from a sample: structural protocols, and a reader
for their vector fields.

The attribute names are those of ``sim.samples`` (so its frozen dataclasses, and anything else
with these read-only attributes, satisfy the protocols without ``fusion`` importing ``sim``).
SI units, frames in the names; ``time_us`` is the time of validity.
"""

from __future__ import annotations

from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray

Vec3 = NDArray[np.float64]


class ImuSample(Protocol):
    """Specific force and angular rate in body FRD, averaged over ``(time_us - dt_s, time_us]``."""

    @property
    def time_us(self) -> int: ...
    @property
    def dt_s(self) -> float: ...
    @property
    def specific_force_b_mps2(self) -> Vec3: ...
    @property
    def angular_rate_b_rps(self) -> Vec3: ...


class GnssFix(Protocol):
    """Receiver fix; ``eph_m``/``epv_m``/``speed_accuracy_mps`` are 1-sigma accuracies."""

    @property
    def time_us(self) -> int: ...
    @property
    def lat_rad(self) -> float: ...
    @property
    def lon_rad(self) -> float: ...
    @property
    def alt_msl_m(self) -> float: ...
    @property
    def v_ned_mps(self) -> Vec3: ...
    @property
    def eph_m(self) -> float: ...
    @property
    def epv_m(self) -> float: ...
    @property
    def speed_accuracy_mps(self) -> float: ...
    @property
    def fix_type(self) -> int: ...


class BaroSample(Protocol):
    """Static pressure (Pa) and sensor temperature (K)."""

    @property
    def time_us(self) -> int: ...
    @property
    def pressure_pa(self) -> float: ...
    @property
    def temperature_k(self) -> float: ...


class MagSample(Protocol):
    """Magnetic flux density in body FRD, tesla."""

    @property
    def time_us(self) -> int: ...
    @property
    def field_b_tesla(self) -> Vec3: ...


class AirspeedSample(Protocol):
    """Pitot-static differential pressure (Pa, total minus static) and sensor temperature (K)."""

    @property
    def time_us(self) -> int: ...
    @property
    def diff_pressure_pa(self) -> float: ...
    @property
    def temperature_k(self) -> float: ...


class ActuatorSample(Protocol):
    """Normalised actuator controls, PX4 HIL_ACTUATOR_CONTROLS order (roll, pitch, yaw in
    [-1, 1], throttle in [0, 1], ...)."""

    @property
    def time_us(self) -> int: ...
    @property
    def controls(self) -> tuple[float, ...]: ...


class RpmSample(Protocol):
    """Propeller speed, rev/min."""

    @property
    def time_us(self) -> int: ...
    @property
    def rpm(self) -> float: ...


Sample = (
    ImuSample | GnssFix | BaroSample | MagSample | AirspeedSample | ActuatorSample | RpmSample
)


def as_vec3(a: Any) -> tuple[float, float, float]:
    """Three floats from a sample's vector field, array or sequence (``ValueError`` /
    ``TypeError`` if it is not three numbers)."""
    try:
        x, y, z = a.tolist()
    except AttributeError:
        x, y, z = a
    return float(x), float(y), float(z)
