"""Reading an IMU thermal calibration file, as PX4 or ArduPilot store it, into
:class:`fusion.thermal.tuning.ThermalCalibration` (SI, kelvin).

Accepted files: a parameter list with one parameter per line, ``NAME VALUE``, ``NAME,VALUE``
or ``NAME=VALUE`` (ArduPilot's ``.parm``, Mission Planner's export), or QGroundControl's
``.params`` (``vehicle component NAME VALUE type``, tab-separated); ``#`` starts a comment.

- PX4 (``sensors`` module, thermal compensation): ``TC_G0_X{3,2,1,0}_{0,1,2}``,
  ``TC_G0_TREF``, ``TC_G0_TMIN``, ``TC_G0_TMAX`` for the first gyro and the same ``TC_A0_*``
  for the first accelerometer; temperatures in degC, offsets in rad/s and m/s^2; the
  correction is ``raw - offset(T)``, ``T`` clamped to ``[TMIN, TMAX]``, ``x = T - TREF``.
- ArduPilot (``AP_InertialSensor_tempcal.cpp``): ``INS_TCAL1_ENABLE`` (must be 1),
  ``INS_TCAL1_TMIN``, ``INS_TCAL1_TMAX``, ``INS_TCAL1_{ACC,GYR}{1,2,3}_{X,Y,Z}``: the 1st to
  3rd order coefficients scaled by 1e6, no constant term, reference temperature fixed at
  35 degC; the correction is ``raw - (p(T - 35) - p(T_cal - 35))`` where ``T_cal`` is the
  temperature of the ordinary offset calibration (``INS_GYR1_CALTEMP``,
  ``INS_ACC1_CALTEMP``; 35 degC when absent, which makes that term zero).

Bad input raises :class:`ValueError` with one line naming the file and what is wrong.
"""

from __future__ import annotations

import math
from pathlib import Path

from fusion.choices import THERMAL_MODES
from fusion.thermal.tuning import ThermalCalibration, ThermalPolynomial, ThermalTuning
from sim.imu_thermal import ImuThermalPart

_C0_K = 273.15
_AP_TREF_C = 35.0
_AP_SCALE = 1e-6


def read_params(text: str) -> dict[str, float]:
    """``NAME -> value`` of a parameter file (formats in the module docstring)."""
    out: dict[str, float] = {}
    for raw in text.splitlines():
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        parts = line.replace(",", " ").replace("=", " ").split()
        if len(parts) >= 4 and parts[0].isdigit() and parts[1].isdigit():  # QGC .params
            parts = parts[2:4]
        if len(parts) < 2:
            raise ValueError(f"line {raw!r} is not 'NAME VALUE'")
        try:
            value = float(parts[1])
        except ValueError:
            raise ValueError(f"parameter {parts[0]} has no number: {parts[1]!r}") from None
        if not math.isfinite(value):
            raise ValueError(f"parameter {parts[0]} is not finite")
        out[parts[0].upper()] = value
    return out


def _need(p: dict[str, float], name: str) -> float:
    if name not in p:
        raise ValueError(f"missing parameter {name}")
    return p[name]


def _px4(p: dict[str, float], s: str) -> ThermalPolynomial:
    coeffs = tuple(
        tuple(_need(p, f"TC_{s}0_X{power}_{axis}") for axis in range(3))
        for power in range(4)
    )
    t_min, t_max = _need(p, f"TC_{s}0_TMIN"), _need(p, f"TC_{s}0_TMAX")
    if not t_min < t_max:
        raise ValueError(f"TC_{s}0_TMIN must be below TC_{s}0_TMAX")
    return ThermalPolynomial(coeffs=coeffs, t_ref_k=_need(p, f"TC_{s}0_TREF") + _C0_K,  # type: ignore[arg-type]
                             t_min_k=t_min + _C0_K, t_max_k=t_max + _C0_K)  # fmt: skip


def _ardupilot(p: dict[str, float], s: str, cal_temp: str) -> ThermalPolynomial:
    zero = (0.0, 0.0, 0.0)
    coeffs = (zero, *(
        tuple(_need(p, f"INS_TCAL1_{s}{order}_{axis}") * _AP_SCALE for axis in "XYZ")
        for order in (1, 2, 3)
    ))
    t_min, t_max = _need(p, "INS_TCAL1_TMIN"), _need(p, "INS_TCAL1_TMAX")
    if not t_min < t_max:
        raise ValueError("INS_TCAL1_TMIN must be below INS_TCAL1_TMAX")
    return ThermalPolynomial(coeffs=coeffs, t_ref_k=_AP_TREF_C + _C0_K,  # type: ignore[arg-type]
                             t_min_k=t_min + _C0_K, t_max_k=t_max + _C0_K,
                             cal_temp_k=p.get(cal_temp, _AP_TREF_C) + _C0_K)  # fmt: skip


def calibration_from_params(p: dict[str, float]) -> ThermalCalibration:
    """The calibration in a parameter set (PX4's or ArduPilot's, whichever it holds)."""
    if any(k.startswith("TC_G0_") for k in p):
        return ThermalCalibration(source="px4", gyro=_px4(p, "G"), accel=_px4(p, "A"))
    if any(k.startswith("INS_TCAL1_") for k in p):
        if _need(p, "INS_TCAL1_ENABLE") != 1.0:
            raise ValueError("INS_TCAL1_ENABLE is not 1 (no calibration to apply)")
        return ThermalCalibration(source="ardupilot",
                                  gyro=_ardupilot(p, "GYR", "INS_GYR1_CALTEMP"),
                                  accel=_ardupilot(p, "ACC", "INS_ACC1_CALTEMP"))  # fmt: skip
    raise ValueError("no PX4 (TC_G0_*) or ArduPilot (INS_TCAL1_*) thermal calibration")


def load_calibration(path: Path) -> ThermalCalibration:
    """Read ``path`` (ValueError: one line naming the file and the problem)."""
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise ValueError(f"thermal calibration {path}: cannot read it ({exc})") from None
    try:
        return calibration_from_params(read_params(text))
    except ValueError as exc:
        raise ValueError(f"thermal calibration {path}: {exc}") from None


def px4_params(cal: ThermalCalibration) -> str:
    """The calibration as PX4 parameter lines (``NAME VALUE``; a simulated unit's calibration
    file, written as the PX4 tool writes it)."""
    lines = []
    for s, poly in (("G", cal.gyro), ("A", cal.accel)):
        for power in (3, 2, 1, 0):
            for axis in range(3):
                lines.append(f"TC_{s}0_X{power}_{axis} {poly.coeffs[power][axis]:.9g}")
        lines.append(f"TC_{s}0_TREF {poly.t_ref_k - _C0_K:.3f}")
        lines.append(f"TC_{s}0_TMIN {poly.t_min_k - _C0_K:.3f}")
        lines.append(f"TC_{s}0_TMAX {poly.t_max_k - _C0_K:.3f}")
    return "\n".join(lines) + "\n"


def thermal_tuning(mode: str, calibration: Path | None = None,
                   base: ThermalTuning | None = None) -> ThermalTuning:
    """The filter's thermal strategy from the commands' ``--thermal MODE`` and
    ``--thermal-cal FILE`` (a file alone means ``cal``); ValueError names what is wrong."""
    if calibration is not None and mode in ("off", "cal"):
        mode = "cal"
    if mode not in THERMAL_MODES:
        raise ValueError(f"unknown thermal mode {mode!r}; valid: {', '.join(THERMAL_MODES)}")
    if mode == "cal" and calibration is None:
        raise ValueError("--thermal cal needs --thermal-cal FILE")
    if mode != "cal" and calibration is not None:
        raise ValueError(f"--thermal-cal is for --thermal cal, not {mode}")
    cal = load_calibration(calibration) if calibration is not None else None
    base = base or ThermalTuning()
    return base.model_copy(update={"mode": mode, "calibration": cal})


_DEG = math.pi / 180.0
_MG = 9.80665e-3


def part_thermal_tuning(part: ImuThermalPart, base: ThermalTuning | None = None) -> ThermalTuning:
    """What the filter's thermal strategies assume about a part: its datasheet temperature
    coefficients (1 sigma over units), its temperature sensor's range, resolution and update
    period (:mod:`sim.imu_thermal`'s preset figures)."""
    base = base or ThermalTuning()
    return base.model_copy(update={
        "gyro_tempco_rps_per_k": max(part.gyro_tempco_dps_per_k * _DEG, 1e-9),
        "accel_tempco_mps2_per_k": max(part.accel_tempco_mg_per_k * _MG, 1e-9),
        "min_k": part.temperature_min_c + _C0_K,
        "max_k": part.temperature_max_c + _C0_K,
        "quantum_k": part.temperature_resolution_k,
        "update_period_s": max(part.temperature_update_s, 0.01),
    })


DEFAULT_THERMAL_PART = "bmi088"
"""The part the commands' thermal strategies assume when none is named (``--thermal-part``)."""


def command_thermal_tuning(mode: str, calibration: Path | None = None,
                           part: str = DEFAULT_THERMAL_PART) -> ThermalTuning:
    """:func:`thermal_tuning` for the part named by a thermal preset (ValueError lists the
    valid ones)."""
    from sim.presets import imu_thermal_preset

    figures = imu_thermal_preset(part)
    if figures is None:
        raise ValueError(f"--thermal-part needs a part, not {part!r}")
    return thermal_tuning(mode, calibration, part_thermal_tuning(figures))
