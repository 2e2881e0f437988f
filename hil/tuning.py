"""Filter tuning from sensor datasheets: what the fusion should assume about the sensors.

A user configures the navigation filter from the IMU's datasheet (its Allan parameters), not
from the truth of a particular run. hilnav's sensor presets *are* datasheet descriptions, so
this module maps a :class:`sim.sensors.SensorSuiteConfig` onto the filter's
:class:`fusion.config.FilterConfig`. It lives in ``hil`` because it is the one place allowed to
know both ``sim`` and ``fusion``.
"""

from __future__ import annotations

import math
import typing

from fusion.config import (
    DEFAULT_AIRSPEED_MODE,
    FilterConfig,
    GnssTuning,
    ImuTuning,
    airspeed_tuning,
)
from fusion.state_layout import LayoutName
from sim.gnss import GnssConfig
from sim.imu import ImuParams
from sim.presets import gnss_preset, imu_preset
from sim.sensors import ImuConfig


def filter_imu_config(imu: ImuConfig, base: ImuTuning | None = None) -> ImuTuning:
    """The filter's IMU error model for a sensor described by ``imu`` (datasheet units).

    White noise densities are the datasheet ARW / VRW (plus the quantisation noise
    ``LSB / sqrt(12 * rate)`` folded into the density at 200 Hz). The Gauss-Markov bias sigma
    is the in-run part, with the rate random walk over one correlation time added in
    quadrature (``K^2 * tau / 2``); the filter drives its random-walk bias states with that
    process's noise (:mod:`fusion.error_model`). The turn-on bias is the initial covariance
    of the bias states, and it stays until a manoeuvre observes it; scale factor and
    misalignment likewise.
    """
    p = ImuParams.from_config(imu)
    base = base or ImuTuning()

    def white(axis: int) -> float:
        q = p.resolution[axis]
        quant = (q * q / 12.0) / 200.0 if q > 0 else 0.0  # LSB^2/12 per sample at 200 Hz
        return math.sqrt(p.white_density[axis] ** 2 + quant)

    def gm(axis: int) -> float:
        return math.sqrt(p.gm_sigma[axis] ** 2 + p.rate_random_walk[axis] ** 2
                         * p.gm_tau_s[axis] / 2.0)

    return base.model_copy(update={
        "accel_noise_density_mps2_rthz": max(white(0), 1e-7),
        "gyro_noise_density_rps_rthz": max(white(3), 1e-9),
        "accel_bias_sigma_mps2": max(gm(0), 1e-7),
        "gyro_bias_sigma_rps": max(gm(3), 1e-10),
        "accel_bias_tau_s": float(p.gm_tau_s[0]),
        "gyro_bias_tau_s": float(p.gm_tau_s[3]),
        "accel_turn_on_sigma_mps2": float(p.turn_on_sigma[0]),
        "gyro_turn_on_sigma_rps": float(p.turn_on_sigma[3]),
        "accel_scale_sigma": max(float(p.scale_sigma[0]), 1e-7),
        "gyro_scale_sigma": max(float(p.scale_sigma[3]), 1e-7),
        "accel_misalignment_sigma_rad": max(float(p.misalignment_sigma_rad[0]), 1e-7),
        "gyro_misalignment_sigma_rad": max(float(p.misalignment_sigma_rad[3]), 1e-7),
        "accel_range_mps2": float(p.range[0]),
        "gyro_range_rps": float(p.range[3]),
    })


def datasheet_layout(layout: LayoutName) -> LayoutName:
    """``layout`` widened to carry every sensor error a datasheet specifies: bias, scale
    factor and misalignment (``ins35``), keeping its GNSS position-bias block if it has one,
    plus the air-data block (``+air``: wind and airspeed scale).

    The simulator's IMU (and a real one) has scale-factor and cross-axis errors; without their
    states the filter is overconfident in turns (``docs/results.md``, "Consistency":
    NEES 74 with ``ins16+gnss``). The air-data block is dormant until the stream
    carries air data (or a fixed-wing without a pitot flies), so it costs a stream without
    air data nothing but three zero rows of the covariance.
    """
    return "ins35+gnss+air" if "+gnss" in layout else "ins35+air"


def filter_config_for_imu(preset: str, base: FilterConfig | None = None) -> FilterConfig:
    """A :class:`FilterConfig` assuming the IMU ``preset``, with the sensor-error states its
    datasheet calls for (:func:`datasheet_layout`; ValueError names valid presets) and the
    commands' air-data default (:data:`fusion.config.DEFAULT_AIRSPEED_MODE`)."""
    base = base or FilterConfig()
    return base.model_copy(update={
        "imu": filter_imu_config(imu_preset(preset), base.imu),
        "state_layout": datasheet_layout(base.state_layout),
        "airspeed": airspeed_tuning(DEFAULT_AIRSPEED_MODE, base.airspeed),
    })


def filter_gnss_config(gnss: GnssConfig, base: GnssTuning | None = None) -> GnssTuning:
    """The filter's GNSS error model for a receiver described by ``gnss``.

    The Gauss-Markov part of the receiver's position error becomes the sigma and correlation
    time (horizontal and vertical) of the filter's GNSS position-bias states, which
    :func:`gnss_state_layout` switches on when the receiver has such a part. A receiver
    without a correlated part gets the sigmas floored so the tuning stays valid (they are not
    used by a layout without the bias states).
    """
    base = base or GnssTuning()
    return base.model_copy(update={
        "bias_sigma_h_m": max(float(gnss.horizontal_gm_sigma_m), 1e-3),
        "bias_sigma_v_m": max(float(gnss.vertical_gm_sigma_m), 1e-3),
        "bias_tau_h_s": float(gnss.horizontal_gm_tau_s),
        "bias_tau_v_s": float(gnss.vertical_gm_tau_s),
    })


def gnss_state_layout(gnss: GnssConfig, layout: LayoutName = "ins16") -> LayoutName:
    """``layout`` with the GNSS position-bias states when the receiver ``gnss`` has a
    time-correlated (Gauss-Markov) position error, without them otherwise.

    The receiver reports its total accuracy in ``eph`` / ``epv``; with the bias states the
    filter fuses only the white remainder; otherwise it would take the whole accuracy as white
    noise and be overconfident. With them the position's rms(error / sigma) is about 1 on the
    ``modern`` receiver (``docs/results.md``, "Accuracy").
    """
    correlated = gnss.horizontal_gm_sigma_m > 0.0 or gnss.vertical_gm_sigma_m > 0.0
    air = "+air" if layout.endswith("+air") else ""
    base = layout.split("+")[0]
    if base not in ("ins16", "ins22", "ins35"):
        base = "ins16"
    return typing.cast(LayoutName, f"{base}{'+gnss' if correlated else ''}{air}")


def filter_config_for_presets(
    imu: str, gnss: str, base: FilterConfig | None = None
) -> FilterConfig:
    """A :class:`FilterConfig` assuming the IMU preset ``imu`` and the GNSS preset ``gnss``
    (:func:`filter_config_for_imu` plus :func:`filter_gnss_config` and
    :func:`gnss_state_layout`; ValueError names the valid presets)."""
    cfg = filter_config_for_imu(imu, base)
    receiver = gnss_preset(gnss)
    return cfg.model_copy(update={
        "gnss": filter_gnss_config(receiver, cfg.gnss),
        "state_layout": gnss_state_layout(receiver, cfg.state_layout),
    })
