"""The barometric altimeter: height from static pressure (standard, QNH or calibrated)."""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from fusion.altitude.atmosphere import geometric_from_geopotential, pressure_altitude_m
from fusion.altitude.calibration import BaroCalibration, BaroCalibrationConfig, CalibrationUpdate
from fusion.altitude.common import Frozen

AltimeterMode = Literal["standard", "qnh", "calibrated"]


class BaroAltimeterConfig(Frozen):
    """How pressure becomes height.

    ``standard``: pressure altitude (ISA). ``qnh``: altimeter set to ``qnh_pa``. ``calibrated``:
    P4's non-standard atmosphere with ``(s, b)`` learned online from GNSS height; starts from
    ``qnh_pa`` if given (``b = −Hp(QNH)``, ``s = 0``), else from the standard atmosphere.
    """

    mode: AltimeterMode = "calibrated"
    qnh_pa: float | None = Field(default=None, ge=80000.0, le=110000.0)
    calibration: BaroCalibrationConfig = BaroCalibrationConfig()


class BaroAltimeter:
    """Pressure (+ temperature) to geometric height above MSL.

    Parameters
    ----------
    config : BaroAltimeterConfig

    Raises
    ------
    ValueError
        ``mode="qnh"`` without ``qnh_pa``.
    """

    def __init__(self, config: BaroAltimeterConfig | None = None) -> None:
        self.config = cfg = config or BaroAltimeterConfig()
        if cfg.mode == "qnh" and cfg.qnh_pa is None:
            raise ValueError("mode='qnh' needs qnh_pa")
        if cfg.qnh_pa is not None:
            b0 = -pressure_altitude_m(cfg.qnh_pa)
            self.calibration = BaroCalibration(
                cfg.calibration, 0.0, b0, cfg.calibration.qnh_bias_sigma0_m
            )
        else:
            self.calibration = BaroCalibration(cfg.calibration)

    @property
    def mode(self) -> AltimeterMode:
        """The configured mode."""
        return self.config.mode

    def altitude_gp_from_hp(self, pressure_altitude: float) -> float:
        """Geopotential altitude (m) for a pressure altitude ``Hp`` (m) in the current mode."""
        mode = self.config.mode
        if mode == "standard":
            return pressure_altitude
        if mode == "qnh":
            assert self.config.qnh_pa is not None
            return pressure_altitude - pressure_altitude_m(self.config.qnh_pa)
        return self.calibration.altitude_gp_m(pressure_altitude)

    def altitude_from_hp(self, pressure_altitude: float) -> float:
        """Geometric height above MSL (m) for a pressure altitude ``Hp`` (m)."""
        return geometric_from_geopotential(self.altitude_gp_from_hp(pressure_altitude))

    def altitude_m(self, pressure_pa: float) -> float:
        """Geometric height above MSL of a static pressure, m.

        Parameters
        ----------
        pressure_pa : float
            Static pressure, Pa.

        Raises
        ------
        ValueError
            Pressure ≤ 0, not finite, or outside the model (:func:`check_pressure`).
        """
        return self.altitude_from_hp(pressure_altitude_m(pressure_pa))

    def calibrate(
        self,
        gnss_alt_m: float,
        pressure_pa: float,
        temperature_k: float | None = None,
        *,
        time_s: float,
        sigma_m: float,
        reference: Literal["msl", "ellipsoid"] = "msl",
        geoid_undulation_m: float = 0.0,
    ) -> CalibrationUpdate:
        """Learn ``(s, b)`` from one GNSS height and a simultaneous baro sample.

        Only meaningful in ``calibrated`` mode (in the others the estimate is kept but unused).
        See :meth:`BaroCalibration.update` for the parameters.
        """
        return self.calibration.update(
            gnss_alt_m,
            pressure_altitude_m(pressure_pa),
            time_s,
            sigma_m=sigma_m,
            temperature_k=temperature_k,
            reference=reference,
            geoid_undulation_m=geoid_undulation_m,
        )

    def freeze(self) -> None:
        """Freeze the calibration (GNSS outage)."""
        self.calibration.freeze()

    def unfreeze(self) -> None:
        """Resume calibration."""
        self.calibration.unfreeze()
