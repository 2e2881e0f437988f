"""Compiled INS mechanisation (fusion/_strapdown.c), bit for bit the Python reference in
:mod:`fusion.strapdown`; optional (built only where a C compiler was available)."""

from collections.abc import Callable, Sequence

from fusion.strapdown import InsState

_Vec3 = tuple[float, float, float]

def bind(
    ins_state_type: type[InsState],
    references: tuple[Callable[..., object], ...],
    constants: tuple[float, ...],
) -> None: ...
def update(
    state: InsState,
    dtheta_b: Sequence[float],
    dv_b: Sequence[float],
    dtheta_prev_b: Sequence[float],
    dv_prev_b: Sequence[float],
    dt_s: float,
) -> InsState: ...
def increments(
    fw: Sequence[float],
    dt_s: float,
    accel_bias_b_mps2: Sequence[float],
    gyro_bias_b_rps: Sequence[float],
) -> tuple[_Vec3, _Vec3]: ...
def increments_scaled(
    fw: Sequence[float],
    dt_s: float,
    accel_bias_b_mps2: Sequence[float],
    gyro_bias_b_rps: Sequence[float],
    accel_scale_b: Sequence[float],
    gyro_scale_b: Sequence[float],
) -> tuple[_Vec3, _Vec3]: ...
def increments_compensated(
    fw: Sequence[float],
    dt_s: float,
    accel_bias_b_mps2: Sequence[float],
    gyro_bias_b_rps: Sequence[float],
    accel_inverse: Sequence[float],
    gyro_inverse: Sequence[float],
) -> tuple[_Vec3, _Vec3]: ...
