"""Named sensor configurations, with where their numbers come from.

Every preset is a validated, frozen configuration; derive variants with
``imu_preset("tactical").model_copy(update={"gyro": {"turn_on_bias_deg_per_h": 0.0}})``
(validated: a negative value raises a ``ValidationError`` naming the field).

"Datasheet class" means: the figures a public datasheet of the named part gives (quoted from
its feature list / specification table), rounded; where a datasheet gives no figure (bias
correlation time, rate random walk, and a few others marked *class value*) a value typical of
the sensor class is chosen and marked as such. Tolerances that datasheets give as "±x" are used
as 1σ. None of this claims to reproduce a particular unit.

Conversions used: ``N[°/√h] = 60·density[°/s/√Hz]``; ``VRW[m/s/√h] = 5.884e-4 ·
density[µg/√Hz]``; cross-axis sensitivity 1 % ≈ 10 mrad.
"""

from __future__ import annotations

from typing import TypeVar

from sim.baro import BaroConfig
from sim.gnss import GnssConfig
from sim.imu import AccelConfig, GyroConfig, ImuConfig
from sim.imu_thermal import ImuThermalConfig, ImuThermalPart
from sim.mag import MagConfig
from sim.pitot import PitotConfig
from sim.sensors import SensorSuiteConfig

T = TypeVar("T")

_IMU_PRESETS: dict[str, ImuConfig] = {
    # Phone / drone class: TDK InvenSense ICM-42688-P datasheet (DS-000347) figures.
    "consumer-mems": ImuConfig(
        gyro=GyroConfig(
            range_dps=2000.0,  # ±2000 °/s full scale
            angle_random_walk_deg_per_rth=0.17,  # 0.0028 °/s/√Hz noise density × 60
            bias_instability_deg_per_h=5.0,  # class value (not on the datasheet)
            bias_correlation_time_s=100.0,  # class value
            rate_random_walk_deg_per_h_per_rth=5.0,  # class value
            turn_on_bias_deg_per_h=1800.0,  # ZRO tolerance ±0.5 °/s (uncalibrated part)
            scale_factor_ppm=5000.0,  # sensitivity tolerance ±0.5 %
            misalignment_mrad=12.5,  # cross-axis sensitivity ±1.25 %
            resolution_dps=1.0 / 131.0,  # 20-bit high-resolution FIFO, 131 LSB/(°/s)
        ),
        accel=AccelConfig(
            range_g=16.0,  # ±16 g full scale
            velocity_random_walk_mps_per_rth=0.041,  # 70 µg/√Hz noise density
            bias_instability_ug=50.0,  # class value
            bias_correlation_time_s=100.0,  # class value
            rate_random_walk_ug_per_rth=30.0,  # class value
            turn_on_bias_mg=20.0,  # zero-g offset ±20 mg
            scale_factor_ppm=5000.0,  # sensitivity tolerance ±0.5 %
            misalignment_mrad=10.0,  # cross-axis sensitivity ±1 %
            resolution_mg=1000.0 / 8192.0,  # high-resolution FIFO, 8192 LSB/g
        ),
    ),
    # Industrial MEMS: Analog Devices ADIS16465-1 datasheet feature list (range of the -2
    # variant so aerobatic rates do not clip).
    "industrial-mems": ImuConfig(
        gyro=GyroConfig(
            range_dps=500.0,  # ADIS16465-2 ±500 °/s
            angle_random_walk_deg_per_rth=0.15,  # 0.15 °/√h ARW
            bias_instability_deg_per_h=2.0,  # 2 °/h in-run bias stability (Allan floor)
            bias_correlation_time_s=100.0,  # class value
            rate_random_walk_deg_per_h_per_rth=1.0,  # class value
            turn_on_bias_deg_per_h=180.0,  # class value (0.05 °/s bias repeatability)
            scale_factor_ppm=1000.0,  # class value (factory-calibrated, ~0.1 %)
            misalignment_mrad=0.87,  # ±0.05° axis-to-axis misalignment
            resolution_dps=0.0,  # 32-bit outputs: quantisation negligible
        ),
        accel=AccelConfig(
            range_g=8.0,  # ±8 g
            velocity_random_walk_mps_per_rth=0.012,  # datasheet class, from memory of the table
            bias_instability_ug=3.6,  # 3.6 µg in-run bias stability (Allan floor)
            bias_correlation_time_s=100.0,  # class value
            rate_random_walk_ug_per_rth=3.0,  # class value
            turn_on_bias_mg=1.5,  # class value
            scale_factor_ppm=1000.0,  # class value
            misalignment_mrad=0.87,  # ±0.05° axis-to-axis misalignment
            resolution_mg=0.0,  # 32-bit outputs
        ),
    ),
    # Tactical grade (≈1 °/h): Honeywell HG1700-AG58 class figures (RLG gyros, pendulous
    # accelerometers): gyro bias 1 °/h, ARW 0.125 °/√h, gyro scale factor 150 ppm,
    # accelerometer bias 1 mg, accelerometer scale factor 300 ppm.
    "tactical": ImuConfig(
        gyro=GyroConfig(
            range_dps=1000.0,  # ±1000 °/s
            angle_random_walk_deg_per_rth=0.125,
            bias_instability_deg_per_h=1.0,
            bias_correlation_time_s=300.0,  # class value (floor near 10 min)
            rate_random_walk_deg_per_h_per_rth=0.3,  # class value
            turn_on_bias_deg_per_h=1.0,
            scale_factor_ppm=150.0,
            misalignment_mrad=0.5,  # class value
        ),
        accel=AccelConfig(
            range_g=37.0,  # ±37 g
            velocity_random_walk_mps_per_rth=0.03,  # class value
            bias_instability_ug=50.0,  # class value
            bias_correlation_time_s=300.0,  # class value
            rate_random_walk_ug_per_rth=10.0,  # class value
            turn_on_bias_mg=1.0,
            scale_factor_ppm=300.0,
            misalignment_mrad=0.5,  # class value
        ),
    ),
    # Paper P2 (docs/methods.md): "gyro drift 0.1 °/h as first-order Markov, correlation
    # time 100 s". P2 states nothing else about the IMU; the rest is the smallest
    # plausible companion of such a gyro, marked assumption.
    "paper-p2": ImuConfig(
        gyro=GyroConfig(
            range_dps=500.0,  # assumption
            angle_random_walk_deg_per_rth=0.005,  # assumption (negligible over 900 s)
            bias_instability_deg_per_h=0.1,  # P2
            bias_instability_spec="gm_sigma",  # P2 gives the Markov process sigma
            bias_correlation_time_s=100.0,  # P2
        ),
        accel=AccelConfig(
            range_g=10.0,  # assumption
            velocity_random_walk_mps_per_rth=0.005,  # assumption
            bias_instability_ug=100.0,  # assumption: the 1e-4 g customarily paired with 0.1 °/h
            bias_instability_spec="gm_sigma",
            bias_correlation_time_s=100.0,  # assumption (same Markov model as the gyro)
        ),
    ),
}

_GNSS_PRESETS: dict[str, GnssConfig] = {
    # Modern single-frequency multi-constellation receiver (u-blox M8/M9 class: 1.5-2.0 m
    # CEP horizontal, 0.05 m/s velocity accuracy). Per-axis 1σ horizontal ≈ 1.5 m, mostly
    # slowly varying (atmosphere / orbit errors: class value τ = 120 s) plus receiver noise.
    "modern": GnssConfig(
        rate_hz=5.0,
        latency_s=0.1,  # class value (fix output some 50-100 ms after its epoch)
        fix_type=3,
        satellites_visible=14,
        horizontal_gm_sigma_m=1.4,
        horizontal_gm_tau_s=120.0,
        horizontal_white_sigma_m=0.5,  # total sqrt(1.4² + 0.5²) = 1.49 m per axis
        vertical_gm_sigma_m=2.4,
        vertical_gm_tau_s=120.0,
        vertical_white_sigma_m=0.8,  # total 2.53 m (vertical ≈ 1.7 × horizontal)
        velocity_gm_sigma_mps=0.02,
        velocity_gm_tau_s=10.0,
        velocity_white_sigma_mps=0.045,  # total 0.049 m/s
        vertical_velocity_gm_sigma_mps=0.03,
        vertical_velocity_white_sigma_mps=0.07,
    ),
    # Paper P2: position error 20 m with correlation time 10 s, velocity error 0.1 m/s with
    # correlation time 5 s (all axes; P2 gives no white part). Rate: P2 gives none; 5 Hz as P0.
    "paper-p2": GnssConfig(
        rate_hz=5.0,
        latency_s=0.0,
        horizontal_gm_sigma_m=20.0,
        horizontal_gm_tau_s=10.0,
        horizontal_white_sigma_m=0.0,
        vertical_gm_sigma_m=20.0,
        vertical_gm_tau_s=10.0,
        vertical_white_sigma_m=0.0,
        velocity_gm_sigma_mps=0.1,
        velocity_gm_tau_s=5.0,
        velocity_white_sigma_mps=0.0,
        vertical_velocity_gm_sigma_mps=0.1,
        vertical_velocity_white_sigma_mps=0.0,
    ),
}

_BARO_PRESETS: dict[str, BaroConfig] = {
    # TE MS5611-01BA03 class: RMS resolution 0.012 mbar at OSR 4096, output in 0.01 mbar,
    # temperature in 0.01 °C. Slow bias (thermal / package drift, P4's Gauss-Markov baro
    # bias): class value 10 Pa (≈ 0.8 m), 10 min. Standard atmosphere, no weather.
    "ms5611": BaroConfig(
        noise_pa=1.2,
        resolution_pa=1.0,
        lag_time_constant_s=0.0,
        bias_gm_sigma_pa=10.0,
        bias_gm_tau_s=600.0,
        temperature_noise_k=0.01,
        temperature_resolution_k=0.01,
    ),
    # Noise-free: exactly the (non-)standard atmosphere; for tests and model studies.
    "ideal": BaroConfig(noise_pa=0.0),
}

_MAG_PRESETS: dict[str, MagConfig] = {
    # AKM AK09916 class (0.15 µT/LSB); noise class value 0.2 µT; hard-iron residual after a
    # typical in-field calibration, class value of about 1 µT.
    "consumer": MagConfig(noise_ut=0.2, resolution_ut=0.15, hard_iron_ut=(1.0, -0.6, 0.8)),
    "ideal": MagConfig(noise_ut=0.0),
}


# Pitot-static airspeed sensors. Both presets share the probe figures: probe misalignment
# k = 0.3 /rad² in angle of attack and sideslip (class value: a simple open-ended total-
# pressure tube stays within ~1 % of q_c up to ~±10° of flow inclination, Gracey, NASA
# RP-1046, 1980), 0.02 s pneumatic lag (class value: some 30 cm of 1.5 mm tubing) and the
# temperature the sensor reports (in the fuselage: class value +2 K over the air).
_PROBE = dict(
    k_alpha_per_rad2=0.3,
    k_beta_per_rad2=0.3,
    lag_time_constant_s=0.02,
    temperature_offset_k=2.0,
)
_PITOT_PRESETS: dict[str, PitotConfig | None] = {
    # TE Connectivity MS4525DO-DS5AI001DP ("001PD": ±1 psi differential, output type A):
    # 14-bit bridge output spanning 10 %..90 % of 2^14 counts over -1..+1 psi, i.e.
    # 13107 counts over 13790 Pa = 1.052 Pa/LSB; 11-bit temperature over -50..150 °C
    # (0.098 K/LSB). Total error band ±1 % of span over -10..85 °C (datasheet, as recalled:
    # check the current revision) = ±138 Pa, mostly the zero: autopilots zero it at power-on
    # (PX4 SENS_DPRES_OFF, ArduPilot's airspeed calibration), so what remains is the zero's
    # thermal drift: 1 % span / 95 K ≈ 1.5 Pa/K, a 2 K change in the fuselage ≈ 3 Pa
    # (Gauss-Markov 3 Pa, 10 min: class value) plus a turn-on residual of 1.5 Pa (class
    # value). Noise 2 Pa: ArduPilot's SITL airspeed noise SIM_ARSPD_RND default (class
    # value; a few LSB at 50 Hz). Scale error 2 % 1σ: class value (installation pressure
    # coefficient, ArduPilot's ARSPD_RATIO calibration absorbs it).
    "ms4525do": PitotConfig(
        noise_pa=2.0,
        resolution_pa=13790.0 / 13107.0,
        full_scale_pa=6894.76,
        offset_sigma_pa=1.5,
        offset_gm_sigma_pa=3.0,
        offset_gm_tau_s=600.0,
        scale_error_sigma=0.02,
        temperature_noise_k=0.05,
        temperature_resolution_k=200.0 / 2047.0,
        **_PROBE,
    ),
    # Sensirion SDP33 (SDP3x family, ±1500 Pa): scale factor 20 counts/Pa (0.05 Pa/LSB);
    # zero point accuracy 0.2 Pa and no zero drift (thermal CMOSens sensor, "no drift, no
    # offset"); span accuracy 3 % of reading, used as 1σ; temperature 200 counts/°C.
    # (Figures as recalled from the SDP3x datasheet table; check the current revision.)
    # Noise 0.2 Pa at 50 Hz: class value. Its ±1500 Pa range saturates near 50 m/s true
    # airspeed at sea level (q_c 1530 Pa): a small-UAV sensor, as on the real part.
    "sdp33": PitotConfig(
        noise_pa=0.2,
        resolution_pa=0.05,
        full_scale_pa=1500.0,
        offset_sigma_pa=0.2,
        scale_error_sigma=0.03,
        temperature_noise_k=0.05,
        temperature_resolution_k=1.0 / 200.0,
        **_PROBE,
    ),
    # Noise-free: exactly the impact pressure (no probe or sensor error); for tests.
    "ideal": PitotConfig(noise_pa=0.0),
    # An aircraft without a pitot: no airspeed samples at all.
    "none": None,
}

# The same sensors with a static-source position error that grows with the angle of attack
# (sim.pitot: 0.3 of q_c per rad, a class value inside 14 CFR 23.1323(b)'s 3 % system-error
# limit), named ``<sensor>-pe``; the presets above have none.
_STATIC_POSITION_ERROR_PER_RAD = 0.3
for _name in ("ms4525do", "sdp33"):
    _base = _PITOT_PRESETS[_name]
    assert _base is not None
    _PITOT_PRESETS[f"{_name}-pe"] = _base.model_copy(
        update={"static_error_alpha_per_rad": _STATIC_POSITION_ERROR_PER_RAD})

DEFAULT_PITOT_PRESET = "ms4525do"
"""The default aircraft (c172x) carries a pitot-static probe; this is the sensor fitted."""


# Thermal behaviour of IMU parts (sim.imu_thermal), a separate choice from the IMU preset:
# ``sensors.imu.thermal.preset`` in a scenario. Natural pairs: consumer-mems (its noise figures
# are the ICM-42688-P's) with icm42688p, bmi088 or icm20948; industrial-mems (ADIS16465) with
# adis1646x. "Verified" below means the figure was read in the cited document's text; "as
# quoted" that it is the commonly quoted datasheet figure whose table was not available to
# check here; "class value" that no datasheet gives it. Tempcos given as "±x" are used as 1σ.
# The self-heating, warm-up and case time constants of every part are class values for an
# IMU on a flight-controller board (or, for the ADIS, in its aluminium housing): the die
# settles some 5-10 K above its case over a few minutes, the case follows the air over a
# quarter of an hour.
_IMU_THERMAL_PRESETS: dict[str, ImuThermalPart] = {
    # Bosch Sensortec BMI088, data sheet BST-BMI088-DS001-13 (rev. 1.3, May 2018).
    "bmi088": ImuThermalPart(
        gyro_tempco_dps_per_k=0.015,  # zero-rate offset TCO ±0.015 °/s/K (as quoted, Table 2)
        accel_tempco_mg_per_k=0.2,  # offset temperature drift < 0.2 mg/K (as quoted, Table 1)
        gyro_scale_tempco_ppm_per_k=100.0,  # class value
        accel_scale_tempco_ppm_per_k=100.0,  # class value
        gyro_hysteresis_dps=0.02,  # class value
        accel_hysteresis_mg=0.5,  # class value
        gyro_rate_dps_per_k_per_min=0.005,  # class value
        accel_rate_mg_per_k_per_min=0.05,  # class value
        self_heating_k=10.0,  # class value
        warmup_time_constant_s=240.0,  # class value
        ambient_time_constant_s=900.0,  # class value
        # Temperature sensor, verified (section 5.3.7, registers 0x22-0x23): 11-bit two's
        # complement, 0.125 °C/LSB, value = n·0.125 + 23 °C, updated every 1.28 s.
        temperature_resolution_k=0.125,
        temperature_zero_c=23.0,
        temperature_update_s=1.28,
        temperature_offset_k=1.0,  # class value
        temperature_min_c=-104.0,  # the register's span: -1024·0.125 + 23
        temperature_max_c=150.875,  # 1023·0.125 + 23
    ),
    # TDK InvenSense ICM-42688-P, datasheet DS-000347.
    "icm42688p": ImuThermalPart(
        gyro_tempco_dps_per_k=0.005,  # ZRO variation vs temperature ±0.005 °/s/°C (as quoted)
        accel_tempco_mg_per_k=0.15,  # zero-g level change vs temperature ±0.15 mg/°C (as quoted)
        gyro_scale_tempco_ppm_per_k=100.0,  # class value
        accel_scale_tempco_ppm_per_k=100.0,  # class value
        gyro_hysteresis_dps=0.01,  # class value
        accel_hysteresis_mg=0.3,  # class value
        gyro_rate_dps_per_k_per_min=0.002,  # class value
        accel_rate_mg_per_k_per_min=0.04,  # class value
        self_heating_k=8.0,  # class value
        warmup_time_constant_s=240.0,  # class value
        ambient_time_constant_s=900.0,  # class value
        # Temperature register TEMP_DATA/132.48 + 25 °C (as recalled from DS-000347; the FIFO
        # carries an 8-bit value of 1/2.07 °C per LSB instead); updated with each sample.
        temperature_resolution_k=1.0 / 132.48,
        temperature_zero_c=25.0,
        temperature_offset_k=1.0,  # class value
    ),
    # TDK InvenSense ICM-20948, datasheet DS-000189 (rev. 1.3).
    "icm20948": ImuThermalPart(
        gyro_tempco_dps_per_k=0.05,  # ZRO variation over temperature ±0.05 °/s/°C (as quoted,
        # Table 1)
        accel_tempco_mg_per_k=0.80,  # zero-g level change vs temperature ±0.80 mg/°C, 0..85 °C
        # (verified, Table 2)
        gyro_scale_tempco_ppm_per_k=200.0,  # class value
        accel_scale_tempco_ppm_per_k=260.0,  # sensitivity change vs temperature ±0.026 %/°C,
        # -40..85 °C (verified, Table 2)
        gyro_hysteresis_dps=0.05,  # class value
        accel_hysteresis_mg=2.0,  # class value
        gyro_rate_dps_per_k_per_min=0.015,  # class value
        accel_rate_mg_per_k_per_min=0.2,  # class value
        self_heating_k=8.0,  # class value
        warmup_time_constant_s=240.0,  # class value
        ambient_time_constant_s=900.0,  # class value
        # TEMP_degC = (TEMP_OUT - RoomTemp_Offset)/333.87 + 21 (as recalled from DS-000189).
        temperature_resolution_k=1.0 / 333.87,
        temperature_zero_c=21.0,
        temperature_offset_k=1.0,  # class value
    ),
    # Analog Devices ADIS1646x (ADIS16465 / ADIS16460 family), factory-compensated over
    # -40..85 °C. Hysteresis: ADI's engineers on EngineerZone (thread "ADIS16460: Gyro bias of
    # cold-to-hot vs hot-to-cold question"): "on individual units, the bias hysteresis can be
    # in the 0.1 deg/sec region" -- used as 2σ of the heating-to-cooling difference. The
    # residual tempcos after the factory compensation are class values: the ADIS16465
    # datasheet's temperature coefficients were not available to check here.
    "adis1646x": ImuThermalPart(
        gyro_tempco_dps_per_k=0.001,  # class value (compensated part)
        accel_tempco_mg_per_k=0.01,  # class value
        gyro_scale_tempco_ppm_per_k=20.0,  # class value
        accel_scale_tempco_ppm_per_k=20.0,  # class value
        gyro_hysteresis_dps=0.05,  # ADI EngineerZone: "can be in the 0.1 °/s region" (2σ)
        accel_hysteresis_mg=0.1,  # class value
        hysteresis_width_k=5.0,  # class value
        gyro_rate_dps_per_k_per_min=0.002,  # class value
        accel_rate_mg_per_k_per_min=0.01,  # class value
        self_heating_k=6.0,  # class value (some 0.15 W in the housing)
        warmup_time_constant_s=420.0,  # class value (aluminium housing)
        ambient_time_constant_s=1200.0,  # class value
        # TEMP_OUT 0.1 °C/LSB (as recalled from the ADIS16465 datasheet), updated with each
        # sample; the kernel driver calls it "a coarse measurement of the temperature inside".
        temperature_resolution_k=0.1,
        temperature_zero_c=25.0,
        temperature_offset_k=2.0,  # class value
        temperature_min_c=-40.0,
        temperature_max_c=105.0,
    ),
}

IMU_THERMAL_OFF = "off"
"""The thermal preset name that leaves the IMU without a temperature model (the default)."""


def _lookup(kind: str, table: dict[str, T], name: str) -> T:
    try:
        return table[name]
    except (KeyError, TypeError):
        choices = ", ".join(sorted(table))
        raise ValueError(f"unknown {kind} preset {name!r}; valid choices: {choices}") from None


def available_imu_presets() -> list[str]:
    """Names accepted by :func:`imu_preset`, sorted."""
    return sorted(_IMU_PRESETS)


def available_imu_thermal_presets() -> list[str]:
    """Names accepted by :func:`imu_thermal_preset`, sorted, and ``off``."""
    return sorted([*_IMU_THERMAL_PRESETS, IMU_THERMAL_OFF])


def imu_thermal_preset(name: str) -> ImuThermalPart | None:
    """An IMU part's thermal figures by name; None for ``off``.

    Raises
    ------
    ValueError
        Unknown name; the message lists the valid choices.
    """
    if name == IMU_THERMAL_OFF:
        return None
    return _lookup("IMU thermal", {**_IMU_THERMAL_PRESETS, IMU_THERMAL_OFF: None}, name)


def available_gnss_presets() -> list[str]:
    """Names accepted by :func:`gnss_preset`, sorted."""
    return sorted(_GNSS_PRESETS)


def available_baro_presets() -> list[str]:
    """Names accepted by :func:`baro_preset`, sorted."""
    return sorted(_BARO_PRESETS)


def available_mag_presets() -> list[str]:
    """Names accepted by :func:`mag_preset`, sorted."""
    return sorted(_MAG_PRESETS)


def available_pitot_presets() -> list[str]:
    """Names accepted by :func:`pitot_preset`, sorted (``none``: no pitot fitted)."""
    return sorted(_PITOT_PRESETS)


def pitot_preset(name: str) -> PitotConfig | None:
    """Pitot configuration by name (see :func:`available_pitot_presets`); None for ``none``.

    Raises
    ------
    ValueError
        Unknown name; the message lists the valid choices.
    """
    return _lookup("pitot", _PITOT_PRESETS, name)


def imu_preset(name: str) -> ImuConfig:
    """IMU configuration by name (see :func:`available_imu_presets`).

    Raises
    ------
    ValueError
        Unknown name; the message lists the valid choices.
    """
    return _lookup("IMU", _IMU_PRESETS, name)


def gnss_preset(name: str) -> GnssConfig:
    """GNSS configuration by name (see :func:`available_gnss_presets`).

    Raises
    ------
    ValueError
        Unknown name; the message lists the valid choices.
    """
    return _lookup("GNSS", _GNSS_PRESETS, name)


def baro_preset(name: str) -> BaroConfig:
    """Barometer configuration by name (see :func:`available_baro_presets`).

    Raises
    ------
    ValueError
        Unknown name; the message lists the valid choices.
    """
    return _lookup("barometer", _BARO_PRESETS, name)


def mag_preset(name: str) -> MagConfig:
    """Magnetometer configuration by name (see :func:`available_mag_presets`).

    Raises
    ------
    ValueError
        Unknown name; the message lists the valid choices.
    """
    return _lookup("magnetometer", _MAG_PRESETS, name)


def _thermal_config(name: str) -> ImuThermalConfig | None:
    part = imu_thermal_preset(name)
    return None if part is None else ImuThermalConfig(part=part, preset=name)


def suite_config(
    imu: str = "industrial-mems",
    gnss: str = "modern",
    baro: str = "ms5611",
    mag: str = "consumer",
    pitot: str = DEFAULT_PITOT_PRESET,
    *,
    imu_thermal: str = IMU_THERMAL_OFF,
    imu_rate_hz: float | None = None,
    baro_rate_hz: float = 50.0,
    mag_rate_hz: float = 50.0,
    pitot_rate_hz: float = 50.0,
) -> SensorSuiteConfig:
    """A :class:`~sim.sensors.SensorSuiteConfig` assembled from preset names.

    ``imu_thermal``: a part's thermal preset (the IMU powered on at the start, the air's
    temperature around it, no heater), or ``off``.

    Raises
    ------
    ValueError
        Unknown preset name.
    pydantic.ValidationError
        Bad rate.
    """
    return SensorSuiteConfig(
        imu=imu_preset(imu),
        gnss=gnss_preset(gnss),
        baro=baro_preset(baro),
        mag=mag_preset(mag),
        pitot=pitot_preset(pitot),
        imu_thermal=_thermal_config(imu_thermal),
        imu_rate_hz=imu_rate_hz,
        baro_rate_hz=baro_rate_hz,
        mag_rate_hz=mag_rate_hz,
        pitot_rate_hz=pitot_rate_hz,
    )
