"""The JSBSim flights of ``bench/altitude_jsbsim.py``: the set-up, one NavFilter per altitude
method on the same sensor data, the recording of the altitude channel's inputs inside the
filter and their exact replay through other channel settings, and the vertical, horizontal and
barometric metrics of a run.
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

import fusion.altitude_link as altitude_link
from fusion import earth
from fusion.altitude.atmosphere import (
    geometric_from_geopotential,
    geopotential_from_geometric,
    nonstandard_scale_bias,
    pressure_altitude_m,
)
from fusion.altitude.channel import AltitudeChannel, AltitudeChannelConfig
from fusion.config import AltitudeConfig, FilterConfig
from fusion.estimate import NavEstimate
from hil.codec import Decoder
from hil.pipeline import SimChain, SimSetup, build_filter
from hil.tuning import filter_config_for_imu
from sim.samples import BaroSample, Truth
from tests.helpers.altitude_synth import make_config

FloatArray = NDArray[np.float64]

PLAN = "climb-descent"
IMU = "industrial-mems"
START_ALT_M = 1500.0
DURATION_S = 660.0
SIM_RATE_HZ = 100.0
IMU_RATE_HZ = 50.0
OUTAGE = (480.0, 600.0)
"""GNSS fixes valid in [start, end) are not sent, s."""
WARMUP_S = 120.0
SETTLE_AFTER_S = 60.0
OSC_RATE_HZ = 10.0
OUTPUT_RATE_HZ = 10.0
LEVEL_1500 = (340.0, 415.0)
"""Level segment near 1500 m in every seed of the plan (checked against the truth), s."""
DAY_DT_K, DAY_DP_HPA = 15.0, -10.0
VARIANTS: dict[str, dict[str, float]] = {
    "calm": {},
    "front": {"pressure_drift_hpa_per_h": -6.0},
    "day": {
        "sea_level_temperature_offset_k": DAY_DT_K,
        "sea_level_pressure_offset_hpa": DAY_DP_HPA,
    },
}
LOOP_METHODS = ("loop", "loop-mpc", "loop-kf")


# ---------------------------------------------------------------------------------------------
# Recording the altitude channel's inputs inside NavFilter
# ---------------------------------------------------------------------------------------------


class RecordingChannel(AltitudeChannel):
    """An :class:`AltitudeChannel` that logs every call (and every read of its height by the
    filter's output), so the same inputs can be replayed through other channel settings."""

    def __init__(self, config: AltitudeChannelConfig | None = None, start_time_s: float = 0.0):
        super().__init__(config, start_time_s)
        self.start_s = start_time_s
        self.log: list[tuple[Any, ...]] = []

    def update_imu(self, az_up_mps2: float, dt_s: float) -> None:
        self.log.append(("i", az_up_mps2, dt_s))
        super().update_imu(az_up_mps2, dt_s)

    def update_baro(self, pressure_pa: float, temperature_k: float | None, time_s: float) -> bool:
        self.log.append(("b", pressure_pa, temperature_k, time_s))
        return super().update_baro(pressure_pa, temperature_k, time_s)

    def update_gnss_height(
        self,
        height_m: float,
        sigma_m: float,
        time_s: float,
        *,
        reference: Literal["msl", "ellipsoid"] = "msl",
        geoid_undulation_m: float = 0.0,
    ) -> None:
        assert reference == "msl" and geoid_undulation_m == 0.0  # what NavFilter passes
        self.log.append(("g", height_m, sigma_m, time_s))
        super().update_gnss_height(height_m, sigma_m, time_s)

    @property
    def height_m(self) -> float:
        self.log.append(("h",))
        return super().height_m


@dataclass
class ChannelLog:
    """The recorded inputs of one loop-method filter run."""

    start_s: float
    entries: list[tuple[Any, ...]]


def replay_mismatch(cfg: AltitudeChannelConfig, log: ChannelLog, track: RunTrack) -> float:
    """Largest difference between a replay and the filter's output altitude at the same
    epochs (0 when the replay reproduces the filter exactly), m."""
    t, h = replay(cfg, log)
    te = np.asarray(track.t)
    k = np.searchsorted(te, t - 1e-6)
    if len(t) == 0 or np.any(k >= len(te)) or np.any(np.abs(te[k] - t) > 1e-6):
        return math.inf  # the reads do not line up with the filter's output epochs
    return float(np.max(np.abs(h - np.asarray(track.alt)[k])))


def replay(
    cfg: AltitudeChannelConfig, log: ChannelLog, *, baro: bool = False,
    truth: tuple[FloatArray, ...] | None = None,
) -> tuple[FloatArray, FloatArray]:
    """Feed a recorded input log through a fresh channel; its height where the filter read it
    (``baro``: the channel's calibrated baro height instead).

    With ``truth`` the GNSS heights are replaced by the true height at the same epochs (same
    sigma), so the calibration sees a perfect height reference: the difference from the
    GNSS-fed replay is what the receiver's own vertical error puts into the calibration.

    Returns
    -------
    t_s, h_m : ndarray
        Channel time and height at each read (NaN before the channel initialised).
    """
    ch = AltitudeChannel(cfg, log.start_s)
    ts: list[float] = []
    hs: list[float] = []
    for e in log.entries:
        k = e[0]
        if k == "i":
            ch.update_imu(e[1], e[2])
        elif k == "b":
            ch.update_baro(e[1], e[2], e[3])
        elif k == "g":
            h = e[1] if truth is None else float(np.interp(e[3], truth[0], truth[1]))
            ch.update_gnss_height(h, e[2], e[3])
        else:
            ts.append(ch.time_s)
            hs.append(ch.baro_height_m if baro else ch.height_m)
    return np.asarray(ts), np.asarray(hs)


def gnss_vertical_error(log: ChannelLog, truth: tuple[FloatArray, ...]) -> dict[str, float]:
    """The GNSS heights the channel got minus the true height: means over part (c)'s windows
    and over everything before the outage (what the calibration averaged), m."""
    g = np.asarray([(e[3], e[1]) for e in log.entries if e[0] == "g"])
    t, err = g[:, 0], g[:, 1] - np.interp(g[:, 0], truth[0], truth[1])
    win = {
        "level_1500m": (t >= LEVEL_1500[0]) & (t < LEVEL_1500[1]),
        "before_outage": t < OUTAGE[0],
        # the calibration's memory of b is ~224 s (q_b 0.005 m/sqrt(s), 2.5 m at 5 Hz)
        "memory_before_level_end": (t >= LEVEL_1500[1] - 224.0) & (t < LEVEL_1500[1]),
        "memory_before_outage": (t >= OUTAGE[0] - 224.0) & (t < OUTAGE[0]),
    }
    out = {f"{k}_mean_m": float(np.mean(err[m])) for k, m in win.items()}
    out["rms_m"] = float(np.sqrt(np.mean(err[t < OUTAGE[0]] ** 2)))
    return out


def isa_bias_analytic(dt_k: float, dp_pa: float, h_m: float) -> float:
    """ISA pressure-altitude error (pressure altitude minus true height) at true height ``h_m``
    in the simulator's non-standard atmosphere (P4's relation), geometric, m."""
    s, b = nonstandard_scale_bias(dt_k, dp_pa)
    hp = (geopotential_from_geometric(h_m) - b) / (1.0 + s)
    return geometric_from_geopotential(hp) - h_m


# ---------------------------------------------------------------------------------------------
# Flights
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class RunSpec:
    """One NavFilter run on one baro variant."""

    name: str
    variant: str
    method: str
    setup: str = "gnss-calibrated"
    params: dict[str, Any] = field(default_factory=dict)


@dataclass
class RunTrack:
    """Output of one filter run (at the filter's output rate)."""

    t: list[float] = field(default_factory=list)
    lat: list[float] = field(default_factory=list)
    lon: list[float] = field(default_factory=list)
    alt: list[float] = field(default_factory=list)
    baro_h: list[float] = field(default_factory=list)
    scale: list[float] = field(default_factory=list)
    bias: list[float] = field(default_factory=list)

    def add(self, e: NavEstimate) -> None:
        self.t.append(e.time_us * 1e-6)
        self.lat.append(e.lat_rad)
        self.lon.append(e.lon_rad)
        self.alt.append(e.alt_msl_m)
        a = e.altitude
        self.baro_h.append(math.nan if a is None else a.baro_height_m)
        self.scale.append(math.nan if a is None else a.calibration_scale)
        self.bias.append(math.nan if a is None else a.calibration_bias_m)


def filter_config(method: str, params: dict[str, Any], setup: str) -> FilterConfig:
    """The datasheet-tuned filter with the given altitude method and channel parameters."""
    base = filter_config_for_imu(IMU)
    if method == "ekf":
        channel = AltitudeChannelConfig()
    else:
        channel = make_config(method, params, setup)  # type: ignore[arg-type]
    alt = AltitudeConfig.model_validate({"method": method, "channel": channel})
    # estimates at 10 Hz: what the metrics use, and a fifth of the output cost of 50 Hz
    rates = base.rates.model_copy(update={"output_rate_hz": OUTPUT_RATE_HZ})
    return base.model_copy(update={"altitude": alt, "rates": rates})


def fly(seed: int, runs: list[RunSpec]) -> dict[str, Any]:
    """Fly one seed; run every filter of ``runs`` on its variant's data, streaming.

    Returns the truth (100 Hz), per-run tracks, health and channel logs, and the baro samples
    (time, pressure) of each variant.
    """
    request = SimSetup.build(
        plan=PLAN,
        duration_s=DURATION_S,
        seed=seed,
        rate_hz=SIM_RATE_HZ,
        imu=IMU,
        alt_msl_m=START_ALT_M,
        gnss_off=[f"{OUTAGE[0]}:{OUTAGE[1] - OUTAGE[0]}"],
    )
    variants = sorted({r.variant for r in runs})
    setups = {}
    for v in variants:
        baro = request.sensors.baro.model_copy(update=VARIANTS[v])
        # the magnetometer at 10 Hz (the filter fuses heading at 5 Hz): cheaper, same result
        sensors = request.sensors.model_copy(
            update={"baro": baro, "imu_rate_hz": IMU_RATE_HZ, "mag_rate_hz": 10.0}
        )
        # truth is taken from the flight directly (100 Hz); its frames are not needed
        setups[v] = dataclasses.replace(request, sensors=sensors, truth_rate_hz=0.1)
    navs = {r.name: build_filter(filter_config(r.method, r.params, r.setup)) for r in runs}
    by_variant = {v: [(r.name, navs[r.name]) for r in runs if r.variant == v] for v in variants}
    tracks = {r.name: RunTrack() for r in runs}
    filter_s = dict.fromkeys(navs, 0.0)
    truth_t: list[float] = []
    truth_alt: list[float] = []
    truth_lat: list[float] = []
    truth_lon: list[float] = []
    baro_tp: dict[str, list[tuple[float, float]]] = {v: [] for v in variants}
    ended = None
    t_wall = time.perf_counter()
    # The filters create their altitude channel lazily (first IMU epoch after alignment): the
    # recording subclass must be in place while they run.
    saved = altitude_link.AltitudeChannel
    altitude_link.AltitudeChannel = RecordingChannel  # type: ignore[misc]
    try:
        # one pipeline flight per baro variant: the same seed flies the same trajectory and
        # the same IMU / GNSS / magnetometer streams; only the barometer differs
        for i, v in enumerate(variants):
            dec = Decoder()
            with SimChain(setups[v]) as chain:
                for step in chain.steps():
                    truth = step.truth
                    if i == 0:
                        truth_t.append(truth.time_us * 1e-6)
                        truth_alt.append(truth.alt_msl_m)
                        truth_lat.append(truth.lat_rad)
                        truth_lon.append(truth.lon_rad)
                    for _t, frame in step.frames:
                        for d in dec.feed(frame):
                            s = d.sample
                            if isinstance(s, Truth):
                                continue
                            if isinstance(s, BaroSample):
                                baro_tp[v].append((s.time_us * 1e-6, s.pressure_pa))
                            for name, nav in by_variant[v]:
                                c0 = time.process_time()
                                for e in nav.step(s):
                                    tracks[name].add(e)
                                filter_s[name] += time.process_time() - c0
            if chain.ended is not None:
                ended = str(chain.ended)
    finally:
        altitude_link.AltitudeChannel = saved  # type: ignore[misc]
    logs: dict[str, ChannelLog] = {}
    for name, nav in navs.items():
        ch = nav.altitude_channel
        if isinstance(ch, RecordingChannel):
            logs[name] = ChannelLog(ch.start_s, ch.log)
    return {
        "seed": seed,
        "ended_early": ended,
        "wall_s": time.perf_counter() - t_wall,
        "truth": (
            np.asarray(truth_t),
            np.asarray(truth_alt),
            np.asarray(truth_lat),
            np.asarray(truth_lon),
        ),
        "tracks": tracks,
        "health": {name: dataclasses.asdict(nav.health) for name, nav in navs.items()},
        "filter_cpu_s": filter_s,
        "logs": logs,
        "baro": {v: np.asarray(baro_tp[v]) for v in variants},
    }


# ---------------------------------------------------------------------------------------------
# Metrics
# ---------------------------------------------------------------------------------------------


def vertical_metrics(
    t: FloatArray, h: FloatArray, truth: tuple[FloatArray, ...]
) -> dict[str, float]:
    """Outage / GNSS-on vertical errors and the oscillation of the estimated height."""
    tt, th = truth[0], truth[1]
    err = h - np.interp(t, tt, th)
    t0, t1 = OUTAGE
    out = (t >= t0) & (t < t1)
    on = (t >= WARMUP_S) & ((t < t0) | (t >= t1 + SETTLE_AFTER_S))
    k_end = int(np.searchsorted(t, t1)) - 1
    # oscillation: 10 Hz samples of the output (nearest output epoch), second difference
    grid = np.arange(t0, t1, 1.0 / OSC_RATE_HZ)
    idx = np.clip(np.searchsorted(t, grid), 0, len(t) - 1)
    d2h = np.diff(h[idx], 2)
    d2e = np.diff(err[idx], 2)
    return {
        "outage_rmse_m": float(np.sqrt(np.mean(err[out] ** 2))),
        "outage_max_m": float(np.max(np.abs(err[out]))),
        "outage_end_error_m": float(err[k_end]),
        "outage_end_abs_error_m": float(abs(err[k_end])),
        "gnss_on_rmse_m": float(np.sqrt(np.mean(err[on] ** 2))),
        "osc_rms_d2_height_m": float(np.sqrt(np.mean(d2h**2))),
        "osc_rms_d2_error_m": float(np.sqrt(np.mean(d2e**2))),
    }


def horizontal_metrics(tr: RunTrack, truth: tuple[FloatArray, ...]) -> dict[str, float]:
    """Horizontal RMSE over the outage and with GNSS on (m)."""
    t = np.asarray(tr.t)
    tt, _th, tlat, tlon = truth
    lat_t = np.interp(t, tt, tlat)
    lon_t = np.interp(t, tt, tlon)
    lat, lon = np.asarray(tr.lat), np.asarray(tr.lon)
    rn = earth.local_terms(float(lat_t[0]), START_ALT_M)
    dn = (lat - lat_t) * rn.rho_n_m
    de = (lon - lon_t) * rn.rho_e_m * rn.cos_lat
    hor = np.hypot(dn, de)
    t0, t1 = OUTAGE
    out = (t >= t0) & (t < t1)
    on = (t >= WARMUP_S) & ((t < t0) | (t >= t1 + SETTLE_AFTER_S))
    return {
        "outage_horizontal_rmse_m": float(np.sqrt(np.mean(hor[out] ** 2))),
        "gnss_on_horizontal_rmse_m": float(np.sqrt(np.mean(hor[on] ** 2))),
    }


def baro_bias(t: FloatArray, h_baro: FloatArray, truth: tuple[FloatArray, ...]) -> dict[str, float]:
    """Mean (and RMS) of baro height minus true height in the windows of part (c)."""
    ok = np.isfinite(h_baro)
    t, h_baro = t[ok], h_baro[ok]
    th = np.interp(t, truth[0], truth[1])
    b = h_baro - th
    t0, t1 = OUTAGE
    wins = {
        "level_1500m": (t >= LEVEL_1500[0]) & (t < LEVEL_1500[1]),
        "gnss_on": (t >= WARMUP_S) & (t < t0),
        "outage": (t >= t0) & (t < t1),
    }
    res: dict[str, float] = {}
    for k, m in wins.items():
        res[f"{k}_mean_m"] = float(np.mean(b[m])) if m.any() else math.nan
        res[f"{k}_rms_m"] = float(np.sqrt(np.mean(b[m] ** 2))) if m.any() else math.nan
    res["level_1500m_true_height_m"] = float(np.mean(th[wins["level_1500m"]]))
    res["flight_min_m"] = float(np.min(b[t >= WARMUP_S]))
    res["flight_max_m"] = float(np.max(b[t >= WARMUP_S]))
    return res


def isa_height(p: FloatArray) -> FloatArray:
    """Geometric height of the ISA pressure altitude of each pressure, m."""
    return np.array([geometric_from_geopotential(pressure_altitude_m(float(x))) for x in p])


# ---------------------------------------------------------------------------------------------
# Tuning
# ---------------------------------------------------------------------------------------------

