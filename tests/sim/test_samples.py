"""The sample makers of ``sim.samples`` make the objects the constructors make."""

from __future__ import annotations

import dataclasses
import math
import pickle
from typing import Any

import numpy as np
import pytest

from sim.samples import GnssFix, ImuSample, Truth, make_gnss_fix, make_imu_sample, make_truth


@pytest.mark.parametrize(("cls", "make", "args"), [
    (ImuSample, make_imu_sample, (123, 0.005, np.array([0.1, 0.2, -9.8]),
                                  np.array([0.01, 0.0, -0.02]), 290.0, 2)),
    (GnssFix, make_gnss_fix, (456, 0.8, 0.1, 500.0, np.array([50.0, -3.0, 0.5]), 1.5,
                              math.nan, math.nan, 3, 12, 1)),
    (Truth, make_truth, (789, 0.8, 0.1, 500.0, np.array([50.0, -3.0, 0.5]),
                         np.array([1.0, 0.0, 0.0, 0.0]), np.array([0.01, 0.0, 0.1]),
                         np.array([0.2, 0.0, -9.8]), math.nan, math.nan, 51.0, 49.5,
                         math.nan, math.nan, np.full(3, math.nan))),
])
def test_a_made_sample_is_the_constructed_one(cls: type, make: Any, args: tuple[object, ...]
                                              ) -> None:
    made = make(*args)
    built = cls(*args)
    with pytest.raises(dataclasses.FrozenInstanceError):
        made.time_us = 0
    assert dataclasses.replace(made, time_us=7).time_us == 7
    assert type(made) is cls
    fields = dataclasses.fields(built)
    assert len(fields) == len(args)  # every field given: a new field must be added to the maker
    for f, arg in zip(fields, args, strict=True):
        assert getattr(made, f.name) is arg is getattr(built, f.name)
    assert repr(made) == repr(built)
    assert repr(pickle.loads(pickle.dumps(made))) == repr(built)
