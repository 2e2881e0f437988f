"""fusion.state_layout: the named error-state layouts."""

from __future__ import annotations

import pytest

from fusion import error_model
from fusion.state_layout import (
    INS16,
    INS16_GNSS,
    INS22,
    INS22_GNSS,
    INS35,
    INS35_GNSS,
    LAYOUTS,
    layout_for,
)


def test_layouts_are_contiguous_and_named() -> None:
    for layout in LAYOUTS.values():
        covered = []
        for name in ("pos", "vel", "att", "ba", "bg", "baro", "sa", "sg", "ma", "mg", "bs",
                     "gnss", "air", "therm"):
            sl = getattr(layout, name)
            if sl is not None:
                covered += list(range(layout.n))[sl]
        assert sorted(covered) == list(range(layout.n))
        assert len(layout.labels) == layout.n
    assert (INS16.POS, INS16.VEL, INS16.ATT, INS16.BA, INS16.BG, INS16.BARO) == (0, 3, 6, 9, 12, 15)
    assert INS16.sa is None and INS22.sa == slice(16, 19) and INS22.sg == slice(19, 22)
    # the GNSS bias block is appended: every other offset stays where it was
    assert (INS16_GNSS.name, INS16_GNSS.n, INS16_GNSS.GNSS) == ("ins16+gnss", 19, 16)
    assert (INS22_GNSS.name, INS22_GNSS.n, INS22_GNSS.GNSS) == ("ins22+gnss", 25, 22)
    assert INS22_GNSS.labels[:22] == INS22.labels and INS22_GNSS.sg == INS22.sg
    assert INS16_GNSS.labels[-3:] == ("gnss_bias_n_m", "gnss_bias_e_m", "gnss_bias_d_m")
    assert layout_for("ins16") is INS16 and layout_for("ins22+gnss") is INS22_GNSS
    # the air-data block is appended last: wind N, wind E, airspeed scale, gust N, gust E
    air = layout_for("ins35+gnss+air")
    assert (air.n, air.WIND, air.ASPD_SCALE, air.GUST, air.GNSS) == (43, 38, 40, 41, 35)
    assert air.has_air and air.labels[:38] == INS35_GNSS.labels
    assert air.labels[-5:] == (
        "wind_n_mps", "wind_e_mps", "airspeed_scale", "gust_n_mps", "gust_e_mps"
    )  # fmt: skip
    assert not INS35_GNSS.has_air
    assert layout_for("ins16+gnss") is INS16_GNSS and layout_for("ins22") is INS22
    assert INS22.has_scale_factors and not INS16_GNSS.has_scale_factors
    assert INS16_GNSS.has_gnss_bias and not INS22.has_gnss_bias
    assert (INS22.SA, INS22.SG) == (16, 19)
    assert (INS35.SA, INS35.MA, INS35.MG, INS35.BS, INS35_GNSS.GNSS) == (16, 22, 28, 34, 35)
    assert INS35.labels[34] == "baro_scale" and INS35_GNSS.has_baro_scale
    assert not INS22_GNSS.has_baro_scale
    assert INS35_GNSS.has_misalignment and not INS22_GNSS.has_misalignment
    assert INS35.labels[22] == "accel_misalignment_01"
    assert INS35.labels[33] == "gyro_misalignment_21"
    with pytest.raises(ValueError, match="no misalignment"):
        _ = INS22.MA
    with pytest.raises(ValueError, match="no baro scale"):
        _ = INS16.BS
    with pytest.raises(ValueError, match="no scale-factor"):
        _ = INS16.SA
    with pytest.raises(ValueError, match="no GNSS"):
        _ = INS16.GNSS
    with pytest.raises(ValueError, match="ins16, ins16\\+gnss, ins22, ins22\\+gnss, ins35"):
        layout_for("ins19")


def test_error_model_re_exports_the_same_layouts() -> None:
    assert error_model.LAYOUTS is LAYOUTS and error_model.layout_for is layout_for
    assert error_model.INS35_GNSS is INS35_GNSS
