"""fusion.nominal: the immutable nominal state and its hot-path replacements."""

from __future__ import annotations

from fusion.nominal import NominalState, initial_nominal, with_baro_bias, with_ins
from fusion.rotations import quat_normalize
from fusion.strapdown import InsState

INS = InsState(0.8, 0.2, 350.0, (40.0, -3.0, 1.5), tuple(quat_normalize([0.9, 0.1, -0.2, 0.3])))


def test_initial_nominal_has_every_sensor_error_zero() -> None:
    state = initial_nominal(INS, 1_000)
    assert state.ins == INS and state.gnss_bias_time_us == 1_000
    zero3, zero6 = (0.0, 0.0, 0.0), (0.0,) * 6
    assert (state.accel_bias_b_mps2, state.gyro_bias_b_rps) == (zero3, zero3)
    assert (state.accel_scale_b, state.gyro_scale_b, state.gnss_bias_ned_m) == (zero3,) * 3
    assert (state.accel_misalignment_b, state.gyro_misalignment_b) == (zero6, zero6)
    assert (state.baro_bias_m, state.baro_scale, state.baro_reference_alt_m) == (0.0, 0.0, 0.0)


def test_hot_path_replacements_change_only_their_field() -> None:
    # GIVEN a nominal state with every field distinct
    state = NominalState(INS, (1.0, 2.0, 3.0), (4.0, 5.0, 6.0), (7.0, 8.0, 9.0),
                         (10.0, 11.0, 12.0), (0.1,) * 6, (0.2,) * 6, 13.0, 14.0, 15.0,
                         (16.0, 17.0, 18.0), 19)  # fmt: skip
    moved = INS._replace(alt_msl_m=1.0)
    # THEN with_ins and with_baro_bias are _replace on their field
    assert with_ins(state, moved) == state._replace(ins=moved)
    assert with_baro_bias(state, -1.5) == state._replace(baro_bias_m=-1.5)
    assert type(with_ins(state, moved)) is NominalState
    assert type(with_baro_bias(state, -1.5)) is NominalState
