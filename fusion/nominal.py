"""The nominal state: the INS state and every sensor-error estimate, as one immutable record.

The error-state filter estimates errors of this record (:mod:`fusion.error_model`); the
feedback (:func:`fusion.feedback.feedback`) subtracts them and returns a new record. The
filter holds exactly one :class:`NominalState` and replaces it whenever any part changes.

It is a ``NamedTuple`` (immutable, named fields) rather than a frozen dataclass because the
filter replaces it at every IMU sample (the INS moves): building a tuple costs a fraction of a
frozen dataclass's ``__init__``, which sets each field through ``object.__setattr__``. The
``with_*`` functions below are the hot-path replacements (tuple concatenation: cheaper than
unpacking into a new tuple, and than ``_replace``); elsewhere ``_replace`` is fine.
"""

from __future__ import annotations

from typing import NamedTuple

from fusion.strapdown import InsState

Vec3 = tuple[float, float, float]
_ZERO3: Vec3 = (0.0, 0.0, 0.0)
_ZERO6: tuple[float, ...] = (0.0,) * 6
_tuple_new = tuple.__new__  # NamedTuple(...) without its Python-level __new__ frame


class NominalState(NamedTuple):
    """The INS state and the sensor-error estimates (all in SI units).

    Fields a layout does not estimate keep their value (zero unless set): the feedback only
    changes the blocks of its layout (:class:`fusion.state_layout.StateLayout`).
    """

    ins: InsState
    """Position, velocity and attitude of the IMU."""
    accel_bias_b_mps2: Vec3
    """Accelerometer bias estimate, body frame, m/s^2."""
    gyro_bias_b_rps: Vec3
    """Gyro bias estimate, body frame, rad/s."""
    accel_scale_b: Vec3
    """Accelerometer scale-factor estimate per axis (dimensionless)."""
    gyro_scale_b: Vec3
    """Gyro scale-factor estimate per axis (dimensionless)."""
    accel_misalignment_b: tuple[float, ...]
    """Accelerometer misalignment estimate, six off-diagonal entries
    (:data:`fusion.state_layout.OFF_DIAGONAL`)."""
    gyro_misalignment_b: tuple[float, ...]
    """Gyro misalignment estimate, six off-diagonal entries."""
    baro_bias_m: float
    """Barometric height bias estimate, m."""
    baro_scale: float
    """Barometric scale-factor estimate (dimensionless)."""
    baro_reference_alt_m: float
    """Height at which the baro scale factor contributes nothing, m."""
    gnss_bias_ned_m: Vec3
    """Time-correlated GNSS position error estimate, m NED, at ``gnss_bias_time_us`` (zero in
    layouts without the GNSS bias block)."""
    gnss_bias_time_us: int
    """Time ``gnss_bias_ned_m`` refers to (it decays only when read, not per IMU sample)."""


def initial_nominal(ins: InsState, time_us: int) -> NominalState:
    """A nominal state at ``ins`` with every sensor-error estimate zero.

    Parameters
    ----------
    ins : InsState
    time_us : int
        Time of ``ins`` (the GNSS bias estimate's reference time).

    Returns
    -------
    NominalState
    """
    return NominalState(ins, _ZERO3, _ZERO3, _ZERO3, _ZERO3, _ZERO6, _ZERO6, 0.0, 0.0, 0.0,
                        _ZERO3, time_us)  # fmt: skip


def with_ins(state: NominalState, ins: InsState) -> NominalState:
    """``state`` with the INS replaced (every IMU sample: a tuple, no ``_replace``)."""
    return _tuple_new(NominalState, (ins,) + state[1:])  # noqa: RUF005  (module docstring)


def with_baro_bias(state: NominalState, baro_bias_m: float) -> NominalState:
    """``state`` with the baro bias replaced (at every covariance propagation)."""
    return _tuple_new(NominalState, state[:7] + (baro_bias_m,) + state[8:])  # noqa: RUF005
