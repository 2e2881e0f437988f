"""fusion.air_data_link: the air-data epoch clock, the static air and the learned model's
inputs."""

from __future__ import annotations

import math
from dataclasses import dataclass

import pytest

from fusion.air_data_link import NEVER_US, AirDataLink
from fusion.strapdown import InsState
from physconst.isa import isa_pressure_pa as height_to_pressure

INS = InsState(0.8, 0.2, 1_000.0, (30.0, 0.0, -2.0), (1.0, 0.0, 0.0, 0.0))


@dataclass(frozen=True)
class _Controls:
    time_us: int
    controls: tuple[float, ...]


@dataclass(frozen=True)
class _Rpm:
    time_us: int
    rpm: float
    index: int = 0


def test_the_clock_ticks_every_period_and_skips_a_gap() -> None:
    link = AirDataLink(20_000)
    assert link.next_us == NEVER_US  # no epochs before a start
    link.start(1_000_000)
    assert link.next_us == 1_020_000
    link.advance(1_020_000)
    assert link.next_us == 1_040_000
    # after a gap the next epoch is one period after now, not a burst of missed ones
    link.advance(2_000_000)
    assert link.next_us == 2_020_000


def test_static_air_falls_back_to_isa_without_a_usable_baro() -> None:
    link = AirDataLink(20_000)
    # no baro yet: ISA pressure and temperature at the INS height
    p, temp = link.static_air(INS)
    assert p == height_to_pressure(1_000.0) and temp == pytest.approx(288.15 - 6.5)
    # a baro sample without a temperature: its pressure, ISA temperature
    link.on_static(90_000.0, None)
    assert link.static_air(INS) == (90_000.0, pytest.approx(281.65))
    link.on_static(90_000.0, 300.0)
    assert link.static_air(INS) == (90_000.0, 300.0)


def test_model_inputs_need_fresh_controls_and_rpm() -> None:
    link = AirDataLink(20_000)
    f_n = (0.0, 0.0, -9.81)
    assert link.model_inputs(5_000_000, INS, f_n, 90_000.0, 280.0) is None
    link.on_controls(_Controls(5_000_000, (0.1, -0.2, 0.0, 0.7)))
    link.on_rpm(_Rpm(5_000_000, 6_000.0, index=1))  # not the first propeller: ignored
    assert link.model_inputs(5_000_000, INS, f_n, 90_000.0, 280.0) is None
    link.on_rpm(_Rpm(5_000_000, 6_000.0))
    inputs = link.model_inputs(5_500_000, INS, f_n, 90_000.0, 280.0)
    assert inputs is not None
    assert (inputs.aileron, inputs.elevator, inputs.throttle) == (0.1, -0.2, 0.7)
    assert inputs.rpm_krpm == 6.0 and inputs.climb_rate_mps == 2.0
    assert inputs.fz_b_mps2 == -9.81 and math.isfinite(inputs.density_kgpm3)
    # older than a second: no inputs
    assert link.model_inputs(6_000_001, INS, f_n, 90_000.0, 280.0) is None
