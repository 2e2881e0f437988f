"""Air-data aiding: true airspeed with wind and airspeed-scale states, synthetic sideslip,
synthetic airspeed without a pitot (PX4 EKF2 ``aid_sources/airspeed``, ``.../sideslip``;
ArduPilot EKF3 ``FuseAirspeed`` / ``FuseSideslip``; read, not copied).

*Measurement* — the pitot's impact pressure ``q_c`` becomes a true airspeed through the
isentropic relation (:func:`physconst.airdata.true_airspeed_mps`) with the static pressure of
the last accepted baro sample (ISA at the INS height without one) and the temperature of the
airspeed sample (the differential-pressure sensor's, as PX4's airspeed module uses), or the
baro's when it is missing or implausible (outside 150-350 K). TAS goes with ``sqrt(T)``: a
10 K error is 1.7 %, which the scale state absorbs.

*Models* (``z = h(INS) - measurement``, :mod:`fusion.aiding`), with the air-relative velocity
``a = v - (w_n + g_n, w_e + g_e, 0)``: the mean wind ``w`` plus the gust ``g`` (turbulence, a
Gauss-Markov process, :mod:`fusion.error_model`), no vertical wind::

    TAS:       h = (1 + k) |a|          H_v = (1 + k) a^T / |a|,  H_w = H_g = -H_v[:2],
                                        H_k = |a|
    sideslip:  h = a_b,y / a_b,x = 0    a_b = C_bn a

The scale ``k`` multiplies the speed, not ``q_c``: a calibration ratio error ``s`` on ``q_c``
is ``k = sqrt(1 + s) - 1 ≈ s / 2``; in the speed domain the Jacobian is the same at every
speed. The sideslip Jacobian follows from ``C^_bn = C_bn (I - [phi×])``:
``d a_b = C_bn (dv - dw - dg) + C_bn [a×] phi``, so with ``g' = C_nb d(beta)/d(a_b)``:
``H_v = g'``, ``H_w = H_g = -g'[:2]``, ``H_phi = g' × a``. Both are checked numerically in
the tests. With GNSS the gust is observed (the instantaneous wind is ``v - a``) and the mean
wind is what stays; in an outage the gust estimate decays to zero and its variance grows to
``gust_sigma_mps^2``: the filter dead-reckons on the mean wind, knowing how far turbulence
can carry it.

*Noise* — one batch of ``n`` samples: ``sigma_TAS^2 = (sigma_qc / (rho |a|))^2 / n + floor^2``
(``d q_c / dV ≈ rho V`` at low Mach; the floor is not averaged away: turbulence and position
error are correlated over the batch).

*When* (:class:`AirspeedAiding`): samples are screened (NaN, more negative than the noise
around zero, absurd -> counted invalid) and averaged over ``1 / fuse_rate_hz``; at each tick
(driven by the IMU clock, so it also runs without a pitot):

1. a measured batch below ``min_airspeed_mps`` is not fused (on the ground); the first batch
   above it starts the wind states (EKF2's reset: ``w = v_ne - TAS_h (cos psi, sin psi)``
   with a large variance) and the scale (prior sigma); later batches are fused through the
   pitot monitor (:mod:`fusion.aiding.pitot_monitor`): a blocked pitot is only tested;
2. a fixed-wing aircraft that is flying fuses the synthetic sideslip ``beta = 0``;
3. without a usable measured airspeed (blocked, timed out: ``synthetic_when_blocked``; or
   none on the stream: ``synthetic_when_no_pitot``) and with GNSS lost, a fixed-wing
   aircraft fuses a synthetic TAS: the airspeed estimate ``|v - w|`` latched while GNSS or
   the pitot was last trusted, with ``synthetic_noise_mps`` and no scale column (ArduPilot
   EKF3's default airspeed, which keeps it dead-reckoning). With ``synthetic_when_no_pitot``
   a fixed-wing without a pitot starts its wind states (at zero, wide) once it flies on
   GNSS, so that the sideslip fusion learns the wind the synthetic airspeed needs.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from fusion import kalman
from fusion.aiding import Observation, Update
from fusion.aiding.pitot_monitor import PitotMonitor
from fusion.aiding.position_error import PositionErrorFit
from fusion.aiding.turbulence import TurbulenceEstimator
from fusion.airspeed_model import AirspeedInputs, OnlineAirspeedModel
from fusion.config import AirspeedTuning
from fusion.estimate import AidSource, AirDataStatus, HealthCounters
from fusion.pitot_model import OnlinePitotErrorModel, PitotInputs
from fusion.rotations import dcm_from_quat, euler_from_quat
from fusion.samples import AirspeedSample
from fusion.state_layout import StateLayout
from fusion.strapdown import InsState
from fusion.wind_model import OnlineWindModel
from physconst.airdata import air_density_kgpm3, true_airspeed_mps

FloatArray = NDArray[np.float64]
Vec3 = tuple[float, float, float]
_MIN_MODEL_SPEED_MPS = 1.0  # below this the direction of the air-relative velocity is noise
_FLAG_HOLD_US = 10_000_000  # a flag stays in the status this long after its last occurrence
# The residual against the mean wind (turbulence estimate, position-error fit, learned pitot
# error) needs the airspeed the mean wind and scale predict known to this 1-sigma, m/s. Across
# the air-relative track the wind enters the airspeed only to second order (sigma^2 / 2V:
# 0.1 m/s at 3 m/s and 45 m/s, a bias the estimates' moving means absorb), so on straight
# flight, where only turns tell the crosswind from a heading error, it is bounded apart.
_RESIDUAL_MAX_SIGMA_MPS = 1.0
_RESIDUAL_MAX_CROSSWIND_SIGMA_MPS = 3.0


def tas_model(
    layout: StateLayout, v_ned_mps: Vec3, wind_ne_mps: tuple[float, float], scale: float,
    tas_mps: float, sigma_mps: float, *, with_scale: bool = True,
) -> Observation | None:  # fmt: skip
    """True-airspeed observation ``z = (1 + k) |v - w| - TAS`` (see module docstring).

    Parameters
    ----------
    layout : StateLayout
        A layout with the air-data block.
    v_ned_mps : 3 floats
        INS velocity at the measurement time, m/s.
    wind_ne_mps : 2 floats
        Wind at the aircraft (mean wind plus gust) North, East, m/s.
    scale : float
        Airspeed scale-factor estimate ``k``.
    tas_mps : float
        Measured (or synthetic) true airspeed, m/s.
    sigma_mps : float
        1-sigma of the measurement, m/s.
    with_scale : bool
        Include the scale column (a synthetic TAS does not come through the pitot).

    Returns
    -------
    Observation or None
        ``None`` for non-finite input or an air-relative speed below 1 m/s.
    """
    an = v_ned_mps[0] - wind_ne_mps[0]
    ae = v_ned_mps[1] - wind_ne_mps[1]
    ad = v_ned_mps[2]
    va = math.sqrt(an * an + ae * ae + ad * ad)
    if not (va >= _MIN_MODEL_SPEED_MPS and math.isfinite(tas_mps) and sigma_mps > 0.0):
        return None
    g = 1.0 + scale if with_scale else 1.0
    H = np.zeros((1, layout.n))
    v, w, u = layout.VEL, layout.WIND, layout.GUST
    H[0, v], H[0, v + 1], H[0, v + 2] = g * an / va, g * ae / va, g * ad / va
    H[0, w] = H[0, u] = -g * an / va
    H[0, w + 1] = H[0, u + 1] = -g * ae / va
    if with_scale:
        H[0, layout.ASPD_SCALE] = va
    return Observation(np.array([g * va - tas_mps]), H, np.array([[sigma_mps * sigma_mps]]))


def sideslip_model(
    layout: StateLayout, v_ned_mps: Vec3, q_nb: tuple[float, float, float, float],
    wind_ne_mps: tuple[float, float], sigma_rad: float,
) -> Observation | None:  # fmt: skip
    """Synthetic sideslip observation ``z = a_b,y / a_b,x - 0`` (see module docstring).

    Parameters
    ----------
    layout : StateLayout
        A layout with the air-data block.
    v_ned_mps : 3 floats
        INS velocity, m/s.
    q_nb : 4 floats
        INS attitude, body -> NED, scalar first.
    wind_ne_mps : 2 floats
        Wind at the aircraft (mean wind plus gust), m/s.
    sigma_rad : float
        1-sigma of the synthetic measurement, rad.

    Returns
    -------
    Observation or None
        ``None`` when the forward air-relative speed is below 1 m/s.
    """
    a = (v_ned_mps[0] - wind_ne_mps[0], v_ned_mps[1] - wind_ne_mps[1], v_ned_mps[2])
    c = dcm_from_quat(q_nb)  # C_nb, row-major
    # a_b = C_bn a = C_nb^T a
    bx = c[0] * a[0] + c[3] * a[1] + c[6] * a[2]
    by = c[1] * a[0] + c[4] * a[1] + c[7] * a[2]
    if not bx >= _MIN_MODEL_SPEED_MPS:
        return None
    beta = by / bx
    # d beta / d a_b = (-by / bx^2, 1 / bx, 0); g = C_nb (d beta / d a_b)
    dx, dy = -by / (bx * bx), 1.0 / bx
    g = (c[0] * dx + c[1] * dy, c[3] * dx + c[4] * dy, c[6] * dx + c[7] * dy)
    H = np.zeros((1, layout.n))
    v, w, u, p = layout.VEL, layout.WIND, layout.GUST, layout.ATT
    H[0, v], H[0, v + 1], H[0, v + 2] = g
    H[0, w] = H[0, u] = -g[0]
    H[0, w + 1] = H[0, u + 1] = -g[1]
    # H_phi = g × a
    H[0, p] = g[1] * a[2] - g[2] * a[1]
    H[0, p + 1] = g[2] * a[0] - g[0] * a[2]
    H[0, p + 2] = g[0] * a[1] - g[1] * a[0]
    return Observation(np.array([beta]), H, np.array([[sigma_rad * sigma_rad]]))


def wind_from_airspeed(
    v_ned_mps: Vec3, yaw_rad: float, tas_mps: float
) -> tuple[float, float]:
    """Wind that makes a zero-sideslip aircraft at heading ``yaw_rad`` fly ``tas_mps``
    through the air at ground velocity ``v_ned_mps`` (no vertical wind), m/s North, East."""
    tas_h = math.sqrt(max(0.0, tas_mps * tas_mps - v_ned_mps[2] ** 2))
    return (v_ned_mps[0] - tas_h * math.cos(yaw_rad), v_ned_mps[1] - tas_h * math.sin(yaw_rad))


class AirState:
    """The air-data estimates the filter feeds back into (mean wind and gust N/E, m/s;
    scale), and whether the block is running."""

    __slots__ = ("active", "gust_ne_mps", "mean_wind_ne_mps", "scale")

    def __init__(self) -> None:
        self.active = False
        self.mean_wind_ne_mps: tuple[float, float] = (0.0, 0.0)
        self.gust_ne_mps: tuple[float, float] = (0.0, 0.0)
        self.scale = 0.0

    @property
    def wind_ne_mps(self) -> tuple[float, float]:
        """The wind at the aircraft: mean wind plus gust, m/s North, East."""
        w, g = self.mean_wind_ne_mps, self.gust_ne_mps
        return (w[0] + g[0], w[1] + g[1])

    def start(self, wind_ne_mps: tuple[float, float]) -> None:
        """Start from a mean wind, no gust and no scale error."""
        self.mean_wind_ne_mps = wind_ne_mps
        self.gust_ne_mps = (0.0, 0.0)
        self.scale = 0.0

    def decay(self, factor: float) -> None:
        """The gust's Gauss-Markov decay over the propagated time."""
        g = self.gust_ne_mps
        self.gust_ne_mps = (g[0] * factor, g[1] * factor)

    def correct(self, dx: list[float], layout: StateLayout) -> None:
        """Subtract the error estimate (estimated minus true) of the air-data block."""
        w, u = layout.WIND, layout.GUST
        m, g = self.mean_wind_ne_mps, self.gust_ne_mps
        self.mean_wind_ne_mps = (m[0] - dx[w], m[1] - dx[w + 1])
        self.gust_ne_mps = (g[0] - dx[u], g[1] - dx[u + 1])
        self.scale -= dx[w + 2]


class AirspeedAiding:
    """Air-data aiding of :class:`fusion.filter.NavFilter` (see module docstring).

    Parameters
    ----------
    cfg : AirspeedTuning
    layout : StateLayout
        A layout with the air-data block.
    counters : HealthCounters
        Where samples and updates are counted (``airspeed_*``, ``sideslip_*``,
        ``synthetic_airspeed_*``, ``wind_resets``).
    update : Update
        The filter's shared measurement update.
    covariance : callable ``() -> ndarray``
        The filter's covariance at the current time (the test of a blocked pitot, the
        wind initialisation).
    activate : callable ``(wind_ne_mps, wind_variance, scale_variance) -> None``
        Starts the air-data block: estimates and their (uncorrelated) variances, process
        noise from then on.
    corrections : callable ``() -> (3 floats)``, optional
        Sum of the velocity corrections the filter's feedback made so far, m/s NED (the
        pitot monitor's stuck check; default: none).
    model : OnlineAirspeedModel, optional
        A learned vehicle model (``--bridge gmdh-airspeed``): while the airspeed is known (GNSS
        or a trusted pitot) it learns ``|v - w|`` from the epoch's :class:`AirspeedInputs`;
        with GNSS lost and no usable pitot its prediction, with its own sigma, replaces the
        latched synthetic airspeed (which remains the fallback while it has none).
    wind_model : OnlineWindModel, optional
        A learned wind profile (``--bridge gmdh-wind``): while GNSS is good and the wind is
        known it learns the mean-wind estimate against the INS height; with GNSS lost the
        mean wind moves with the profile as the height changes (counted in
        ``learned_wind_updates``).
    pitot_model : OnlinePitotErrorModel, optional
        A learned pitot position error (``--bridge gmdh-pitot``): while GNSS is good and the
        wind has converged it learns the measured TAS minus ``|v - w_mean|`` against the
        flow angles and the TAS; with GNSS lost its change from the conditions the scale state
        last absorbed is removed from each measured TAS before the monitor and the update.
    """

    def __init__(
        self, cfg: AirspeedTuning, layout: StateLayout, counters: HealthCounters,
        update: Update, covariance: Callable[[], FloatArray],
        activate: Callable[[tuple[float, float], float, float], None],
        corrections: Callable[[], Vec3] | None = None,
        model: OnlineAirspeedModel | None = None,
        wind_model: OnlineWindModel | None = None,
        pitot_model: OnlinePitotErrorModel | None = None,
    ) -> None:  # fmt: skip
        self.cfg = cfg
        self.layout = layout
        self.state = AirState()
        self.monitor = PitotMonitor(cfg)
        self.turbulence = TurbulenceEstimator(cfg)
        self.position_error = PositionErrorFit(cfg)
        self._flags_until_us: dict[str, int] = {}
        self.gate = kalman.chi2_gate(1, cfg.gate_probability)
        self.beta_gate = kalman.chi2_gate(1, cfg.sideslip_gate_probability)
        self._c = counters
        self._update = update
        self._covariance = covariance
        self._activate = activate
        self._corrections = corrections if corrections is not None else _no_corrections
        self.model = model
        self.wind_model = wind_model
        self.pitot_model = pitot_model
        self._profile_last: tuple[float, float] | None = None
        self._timeout_us = round(cfg.timeout_s * 1e6)
        self._sum_t = 0
        self._sum_q = 0.0
        self._sum_temp = 0.0
        self._n_temp = 0
        self._count = 0
        self.pitot_seen = False
        """A valid airspeed sample has arrived."""
        self.last_tas_mps = math.nan
        """Last measured batch TAS, m/s."""
        self.last_measured_fused_us: int | None = None
        self.last_fused_us: int | None = None
        """Last accepted TAS update, measured or synthetic."""
        self.synthetic_active = False
        self._trusted_tas_mps: float | None = None
        tick_hz = max(cfg.fuse_rate_hz, cfg.sideslip_rate_hz)  # the filter's epoch rate
        self._synthetic_period_us = round(1e6 / cfg.synthetic_rate_hz)
        self._last_synthetic_us = -(1 << 62)
        self._recent_v: deque[Vec3] = deque(
            maxlen=max(1, round(tick_hz * cfg.synthetic_average_s)))
        self._tas_period_us = round(1e6 / cfg.fuse_rate_hz)
        self._tas_slack_us = round(0.5e6 / tick_hz)  # half an epoch: IMU-step jitter
        self._next_tas_us = -(1 << 62)
        self._heading_wait_since_us: int | None = None  # the wind waiting for the heading

    # --------------------------------------------------------------- samples
    def add_sample(self, s: AirspeedSample, time_us: int) -> None:
        """Screen one sample and add it to the current batch (NaN, negative or absurd
        differential pressure: counted in ``airspeed_invalid``)."""
        try:
            qc = float(s.diff_pressure_pa)
        except (TypeError, ValueError):
            qc = math.nan
        if not -self.cfg.negative_tolerance_pa <= qc <= self.cfg.max_diff_pressure_pa:  # NaN too
            self._c.airspeed_invalid += 1
            return
        qc = max(qc, 0.0)  # noise around zero
        self.pitot_seen = True
        self.monitor.add_reading(time_us, qc)
        try:
            temp = float(s.temperature_k)
        except (TypeError, ValueError):
            temp = math.nan
        if 150.0 <= temp <= 350.0:
            self._sum_temp += temp
            self._n_temp += 1
        self._sum_t += time_us
        self._sum_q += qc
        self._count += 1

    def _take_batch(self) -> tuple[int, float, float, int] | None:
        n = self._count
        if n == 0:
            return None
        temp = self._sum_temp / self._n_temp if self._n_temp else math.nan
        out = (self._sum_t // n, self._sum_q / n, temp, n)
        self._sum_t, self._sum_q, self._sum_temp, self._n_temp, self._count = 0, 0.0, 0.0, 0, 0
        return out

    # --------------------------------------------------------------- status
    def air_speed_mps(self, v_ned_mps: Vec3) -> float:
        """Air-relative speed ``|v - w - g|`` at INS velocity ``v_ned_mps``, m/s."""
        return _air_speed(v_ned_mps, self.state.wind_ne_mps)

    def is_fusing(self, now_us: int) -> bool:
        """A TAS (measured or synthetic) was fused within ``timeout_s``."""
        t = self.last_fused_us
        return t is not None and now_us - t <= self._timeout_us

    def measured_ok(self, now_us: int) -> bool:
        """A measured TAS was fused within ``timeout_s`` (the pitot is usable)."""
        t = self.last_measured_fused_us
        return t is not None and now_us - t <= self._timeout_us

    def status(self, now_us: int) -> AirDataStatus:
        """The air-data status at ``now_us``."""
        st = self.state
        if self.monitor.blocked:
            mode = "blocked"
        elif self.measured_ok(now_us):
            mode = "fusing"
        elif self.synthetic_active and self.is_fusing(now_us):
            mode = "synthetic"
        elif self.last_fused_us is None:
            mode = "waiting"
        else:
            mode = "stale"
        nan2 = (math.nan, math.nan)
        turb = self.turbulence
        flags = sorted(k for k, t in self._flags_until_us.items() if now_us <= t)
        if turb.saturated and turb.source == "saturated":
            flags.append("turbulence_saturated")
        return AirDataStatus(mode, st.active, st.mean_wind_ne_mps if st.active else nan2,
                             st.scale, self.last_tas_mps, self.monitor.fault,
                             st.gust_ne_mps if st.active else nan2, turb.sigma_mps,
                             turb.source, ",".join(flags),
                             self.position_error.coefficient_per_rad,
                             turb.estimate_mps)  # fmt: skip

    def noise_factors(self, gnss_active: bool, now_us: int) -> tuple[float, float, float]:
        """Factors on the wind's level-flight and climb-driven random walk and on the scale's
        random walk now (:meth:`fusion.error_model.ErrorModel.air_process_noise`).

        In still air on a measured airspeed (turbulence in use at most
        ``outage_hold_max_turbulence_mps``) the wind walks at ``still_air_wind_noise_mps2_rthz``
        instead of ``wind_noise_mps2_rthz``, and a GNSS outage holds it: the level-flight
        wind and scale noise times ``outage_noise_factor``, the climb-driven wind noise times
        ``outage_climb_noise_factor``. In turbulence the wind keeps its noise, with GNSS and
        without: the long-wavelength part of the gusts moves the mean wind over minutes. On
        the synthetic airspeed (no usable pitot) it keeps it too: that airspeed is a latched
        guess, and the wind's freedom is what absorbs the real airspeed's excursions from it."""
        cfg = self.cfg
        if not (self.measured_ok(now_us)
                and self.turbulence.sigma_mps <= cfg.outage_hold_max_turbulence_mps):
            return 1.0, 1.0, 1.0
        still = cfg.still_air_wind_noise_mps2_rthz / cfg.wind_noise_mps2_rthz
        if not cfg.outage_hold or gnss_active:
            return still, still, 1.0
        return (still * cfg.outage_noise_factor, still * cfg.outage_climb_noise_factor,
                cfg.outage_noise_factor)

    def _flag(self, name: str, now_us: int) -> None:
        self._flags_until_us[name] = now_us + _FLAG_HOLD_US

    # --------------------------------------------------------------- the tick
    def tick(
        self, now_us: int, ins: InsState, past: Callable[[int], InsState | None],
        static_pa: float, static_temp_k: float, gnss_active: bool,
        inputs: AirspeedInputs | None = None,
    ) -> None:
        """One air-data epoch (every ``1 / max(fuse_rate_hz, sideslip_rate_hz)`` of IMU time;
        the TAS batch is fused every ``1 / fuse_rate_hz``).

        Parameters
        ----------
        now_us : int
            IMU time (labels the updates).
        ins : InsState
            The current INS.
        past : callable ``(time_us) -> InsState or None``
            The INS at an earlier time (the batch's mean time).
        static_pa, static_temp_k : float
            Static pressure (Pa) and temperature (K) for the TAS conversion and the air
            density.
        gnss_active : bool
            GNSS aiding is active (the synthetic airspeed is latched, not fused).
        inputs : AirspeedInputs, optional
            The learned model's inputs at this epoch (None: the stream has no controls or
            rpm, or no model).
        """
        cfg, st = self.cfg, self.state
        batch = None
        if now_us >= self._next_tas_us:  # the TAS at its own (slower) rate
            self._next_tas_us = now_us + self._tas_period_us - self._tas_slack_us
            batch = self._take_batch()
        if batch is not None:
            ins = self._measured(batch, now_us, ins, past, static_pa, static_temp_k, gnss_active)
        if not st.active:
            # the wind is learned (sideslip, GNSS) for the synthetic or learned airspeed
            learns = cfg.synthetic_when_no_pitot or (self.model is not None and inputs is not None)
            if (cfg.fixed_wing and learns and not self.pitot_seen
                    and gnss_active and math.hypot(*ins.v_ned_mps[:2]) > cfg.flying_speed_mps):
                self._activate((0.0, 0.0), cfg.wind_init_sigma_no_pitot_mps**2,
                               cfg.scale_sigma**2)  # fmt: skip
                st.active = True
                self._c.wind_resets += 1
            return
        if math.hypot(*st.mean_wind_ne_mps) > cfg.max_wind_mps:
            # no plausible air moves this fast: start again from the next airspeed, with the
            # conservative prior for the turbulence
            self._flag("wind_implausible", now_us)
            self._c.wind_implausible += 1
            st.active = False
            self.turbulence = TurbulenceEstimator(cfg)
            return
        ins = self._current(ins, past, now_us)
        va = _air_speed(ins.v_ned_mps, st.wind_ne_mps)
        flying = va > cfg.flying_speed_mps or self.measured_ok(now_us)
        if cfg.fixed_wing and flying:
            self._sideslip(ins, now_us)
            ins = self._current(ins, past, now_us)
            va = _air_speed(ins.v_ned_mps, st.wind_ne_mps)
        if self.wind_model is not None:
            self._learned_wind(now_us, ins, gnss_active)
        if gnss_active or self.measured_ok(now_us):
            self.synthetic_active = False
            self._trusted_tas_mps = None
            if va > cfg.min_airspeed_mps:
                self._recent_v.append(ins.v_ned_mps)
                if self.model is not None:
                    # the aided filter's air-relative speed is the best airspeed there is, once
                    # the wind is known (NaN: the model only notes that it has inputs); against
                    # the mean wind without a pitot (the gust is then seen only across track)
                    target = va if self.pitot_seen else _air_speed(ins.v_ned_mps,
                                                                   st.mean_wind_ne_mps)
                    self.model.observe(now_us, inputs, target if self._wind_known() else math.nan)
            else:
                self._recent_v.clear()
            return
        if self._learned_tas(now_us, ins, inputs):
            return
        if self._trusted_tas_mps is None and self._recent_v:
            # the cruise airspeed: the mean over the recent ground velocities against the
            # wind as known now (the best estimate), not the value of the last instant (a
            # phugoid or a throttle change would bias the whole outage)
            wn, we = st.mean_wind_ne_mps  # the gusts of the recent epochs average out
            self._trusted_tas_mps = sum(
                math.sqrt((v[0] - wn) ** 2 + (v[1] - we) ** 2 + v[2] ** 2) for v in self._recent_v
            ) / len(self._recent_v)
            self._recent_v.clear()
        trusted = self._trusted_tas_mps
        allowed = cfg.synthetic_when_blocked if self.pitot_seen else cfg.synthetic_when_no_pitot
        if cfg.fixed_wing and allowed and trusted is not None:
            self.synthetic_active = True
            if now_us - self._last_synthetic_us < self._synthetic_period_us:
                return
            self._last_synthetic_us = now_us
            obs = tas_model(self.layout, ins.v_ned_mps, st.wind_ne_mps, st.scale, trusted,
                            cfg.synthetic_noise_mps, with_scale=False)  # fmt: skip
            if obs is None:
                return
            res = self._update(obs, self.gate, AidSource.AIRSPEED, now_us)
            if res.test_ratio <= 1.0:
                self._c.synthetic_airspeed_fused += 1
                self.last_fused_us = now_us
            else:
                self._c.synthetic_airspeed_rejected += 1

    def _learned_wind(self, now_us: int, ins: InsState, gnss_active: bool) -> None:
        """Train the wind profile (GNSS good, wind known), or, with GNSS lost, move the mean
        wind by the profile's change between the last height and this one.

        The profile enters as a known input of the wind's process model (``dw = w(h) -
        w(h_last)``), not as a measurement: its error is the same at every epoch, and fused
        at 1 Hz it would be counted as hundreds of independent measurements. The wind's
        random walk keeps its variance; where the profile is flat or clipped (outside the
        heights it was trained on) nothing moves.
        """
        model, st = self.wind_model, self.state
        assert model is not None
        if gnss_active:
            self._profile_last = None
            if self._wind_known():
                model.observe(now_us, ins.alt_msl_m, st.mean_wind_ne_mps)
            return
        pred = model.predict(ins.alt_msl_m)
        if pred is None:
            return
        last, self._profile_last = self._profile_last, pred.wind_ne_mps
        if last is None:
            return
        dn, de = pred.wind_ne_mps[0] - last[0], pred.wind_ne_mps[1] - last[1]
        dn, de = (dn if math.isfinite(dn) else 0.0), (de if math.isfinite(de) else 0.0)
        if dn or de:  # an axis without skill is NaN: held flat
            m = st.mean_wind_ne_mps
            st.mean_wind_ne_mps = (m[0] + dn, m[1] + de)
            self._c.learned_wind_updates += 1

    def _wind_known(self) -> bool:
        P, w = self._covariance(), self.layout.WIND
        return max(float(P[w, w]), float(P[w + 1, w + 1])) <= self.cfg.learn_max_wind_sigma_mps**2

    def _learned_tas(self, now_us: int, ins: InsState, inputs: AirspeedInputs | None) -> bool:
        """Fuse the learned model's airspeed (GNSS lost, no usable pitot); False when it has
        no prediction (the latched synthetic airspeed is then the fallback)."""
        model = self.model
        if model is None or not self.cfg.fixed_wing:
            return False
        pred = model.predict(inputs)
        if pred is None:
            return False
        self.synthetic_active = True
        if now_us - self._last_synthetic_us < self._synthetic_period_us:
            return True
        self._last_synthetic_us = now_us
        st = self.state
        obs = tas_model(self.layout, ins.v_ned_mps, st.wind_ne_mps, st.scale, pred.tas_mps,
                        pred.sigma_mps, with_scale=False)  # fmt: skip
        if obs is None:
            return True
        res = self._update(obs, self.gate, AidSource.AIRSPEED, now_us)
        if res.test_ratio <= 1.0:
            self._c.learned_airspeed_fused += 1
            self.last_fused_us = now_us
        else:
            self._c.learned_airspeed_rejected += 1
        return True

    def _current(
        self, ins: InsState, past: Callable[[int], InsState | None], now_us: int
    ) -> InsState:
        cur = past(now_us)
        return ins if cur is None else cur

    def _measured(
        self, batch: tuple[int, float, float, int], now_us: int, ins: InsState,
        past: Callable[[int], InsState | None], static_pa: float, static_temp_k: float,
        gnss_active: bool,
    ) -> InsState:  # fmt: skip
        """One measured batch: start the wind, or fuse / test it through the monitor (and,
        with GNSS, feed the turbulence estimate). Returns the current INS (after a possible
        update)."""
        cfg, st, c, mon = self.cfg, self.state, self._c, self.monitor
        t_mean, qc, temp, n = batch
        temp_k = temp if math.isfinite(temp) else static_temp_k
        tas = true_airspeed_mps(qc, static_pa, temp_k)
        if not math.isfinite(tas):
            c.airspeed_invalid += n
            return ins
        self.last_tas_mps = tas
        at = past(t_mean)
        if at is None:
            at = ins
        alpha = _alpha_rad(at, st.wind_ne_mps) if st.active else math.nan
        tas_raw, tas = tas, self.position_error.correct(tas, alpha)
        if self.pitot_model is not None and st.active and not gnss_active:
            e = self.pitot_model.correction_mps(_pitot_inputs(at, st.mean_wind_ne_mps, tas))
            if e is not None:
                tas -= e
        if abs(tas - math.sqrt(sum(v * v for v in at.v_ned_mps))) > cfg.max_wind_mps:
            # |TAS - ground speed| <= |wind|: no plausible wind explains this reading
            self._flag("pitot_implausible", now_us)
            c.airspeed_implausible += n
            return ins
        if not st.active:
            if tas < cfg.min_airspeed_mps:
                c.airspeed_low += n
                return ins
            P = self._covariance()
            yaw_var = float(P[self.layout.ATT + 2, self.layout.ATT + 2])
            if yaw_var > math.radians(cfg.wind_start_max_heading_sigma_deg) ** 2:
                since = self._heading_wait_since_us
                if since is None or now_us < since:
                    self._heading_wait_since_us = since = now_us
                if now_us - since < cfg.wind_start_max_wait_s * 1e6:
                    return ins
            self._heading_wait_since_us = None
            sigma = self._sigma(tas, static_pa, temp_k, n)
            tas_h = math.sqrt(max(0.0, tas * tas - at.v_ned_mps[2] ** 2))
            var_w = cfg.wind_init_sigma_mps**2 + sigma * sigma + tas_h * tas_h * yaw_var
            wind = wind_from_airspeed(at.v_ned_mps, euler_from_quat(at.q_nb)[2], tas)
            self._activate(wind, var_w, cfg.scale_sigma**2)
            st.active = True
            c.wind_resets += 1
            return ins
        va = _air_speed(at.v_ned_mps, st.wind_ne_mps)
        fault = mon.assess(t_mean, tas, at.v_ned_mps, self._corrections(), st.wind_ne_mps,
                           st.scale, static_pa, temp_k, at.q_nb, alpha)  # fmt: skip
        if tas < cfg.min_airspeed_mps:
            c.airspeed_low += n
            if mon.blocked:
                c.airspeed_blocked += n
                mon.on_low(t_mean)
            elif mon.on_batch(t_mean, fault, True) == "blocked":
                c.airspeed_blockages += 1
            return ins
        obs = tas_model(self.layout, at.v_ned_mps, st.wind_ne_mps, st.scale, tas,
                        self._sigma(max(va, tas), static_pa, temp_k, n))  # fmt: skip
        if obs is None:
            c.airspeed_invalid += n
            return ins
        if mon.blocked:
            c.airspeed_blocked += n
            P = self._covariance()
            h = obs.H[0]
            s = float(h @ P @ h) + float(obs.R[0, 0])
            ok = float(obs.z[0]) ** 2 / s <= self.gate
            if mon.on_batch(t_mean, fault, ok) == "recovered":
                c.airspeed_recoveries += 1
            return ins
        if fault:  # detected on this batch: not fused
            mon.on_batch(t_mean, fault, True)
            c.airspeed_blockages += 1
            c.airspeed_blocked += n
            return ins
        if gnss_active and self._residual_ready(at.v_ned_mps):
            self._learn_air(at.v_ned_mps, tas, tas_raw, alpha, static_pa, temp_k, n)
            if self.pitot_model is not None:
                self._learn_pitot(t_mean, at, tas)
        res = self._update(obs, self.gate, AidSource.AIRSPEED, now_us)
        ok = res.test_ratio <= 1.0
        if ok:
            c.airspeed_fused += 1
            self.last_measured_fused_us = self.last_fused_us = now_us
        else:
            c.airspeed_rejected += 1
        if mon.on_batch(t_mean, "", ok) == "blocked":
            c.airspeed_blockages += 1
        return ins

    def _learn_air(
        self, v_ned_mps: Vec3, tas_mps: float, tas_raw_mps: float, alpha_rad: float,
        static_pa: float, temp_k: float, n: int,
    ) -> None:  # fmt: skip
        """With GNSS good and the residual ready (:meth:`_residual_ready`): feed the turbulence
        estimate the residual against the mean wind (:mod:`fusion.aiding.turbulence`) and the
        position-error fit the raw airspeed ratio (:mod:`fusion.aiding.position_error`)."""
        st, turb = self.state, self.turbulence
        was = turb.saturated
        va = _air_speed(v_ned_mps, st.mean_wind_ne_mps)
        if va > _MIN_MODEL_SPEED_MPS:
            self.position_error.add(alpha_rad, tas_raw_mps / va)
        r = (1.0 + st.scale) * va - tas_mps
        s_sensor = self._sensor_sigma(tas_mps, static_pa, temp_k)
        turb.add(r, s_sensor * s_sensor / n)
        if turb.saturated and not was:
            self._c.turbulence_saturated += 1

    def _residual_ready(self, v_ned_mps: Vec3) -> bool:
        """The airspeed the mean wind and scale predict is known well enough for a residual
        against it: its 1-sigma along the air-relative track (wind and scale) at most
        ``_RESIDUAL_MAX_SIGMA_MPS``, the crosswind's at most
        ``_RESIDUAL_MAX_CROSSWIND_SIGMA_MPS``."""
        st, lay = self.state, self.layout
        an = v_ned_mps[0] - st.mean_wind_ne_mps[0]
        ae = v_ned_mps[1] - st.mean_wind_ne_mps[1]
        va = math.hypot(an, ae)
        if va < _MIN_MODEL_SPEED_MPS:
            return False
        P = self._covariance()
        i = [lay.WIND, lay.WIND + 1, lay.ASPD_SCALE]
        g = 1.0 + st.scale
        h = np.array([-g * an / va, -g * ae / va, va])
        along = float(h @ P[np.ix_(i, i)] @ h)
        c = np.array([-ae / va, an / va])
        across = float(c @ P[np.ix_(i[:2], i[:2])] @ c)
        return (along <= _RESIDUAL_MAX_SIGMA_MPS**2
                and across <= _RESIDUAL_MAX_CROSSWIND_SIGMA_MPS**2)  # fmt: skip

    def _learn_pitot(self, t_us: int, at: InsState, tas_mps: float) -> None:
        """With GNSS good and the residual ready (:meth:`_residual_ready`): one pair of the
        learned pitot error, the measured TAS minus ``|v - w_mean|``, with the filter's own
        prediction of it, ``k |v - w_mean|`` (:mod:`fusion.pitot_model`)."""
        model, st = self.pitot_model, self.state
        assert model is not None
        va = _air_speed(at.v_ned_mps, st.mean_wind_ne_mps)
        if va > _MIN_MODEL_SPEED_MPS:
            model.observe(t_us, _pitot_inputs(at, st.mean_wind_ne_mps, tas_mps), tas_mps - va,
                          st.scale * va)  # fmt: skip

    def _sensor_sigma(self, speed_mps: float, static_pa: float, temp_k: float) -> float:
        """TAS sigma of one pitot sample from its pressure noise, ``sigma_qc / (rho V)``."""
        cfg = self.cfg
        rho_v = air_density_kgpm3(static_pa, temp_k) * max(speed_mps, cfg.min_airspeed_mps)
        return cfg.diff_pressure_noise_pa / rho_v

    def _sigma(self, speed_mps: float, static_pa: float, temp_k: float, n: int) -> float:
        """TAS sigma of a batch of ``n`` samples at ``speed_mps`` (module docstring)."""
        s_sensor = self._sensor_sigma(speed_mps, static_pa, temp_k)
        return math.sqrt(s_sensor * s_sensor / n + self.cfg.tas_noise_floor_mps**2)

    def _sideslip(self, ins: InsState, now_us: int) -> None:
        obs = sideslip_model(self.layout, ins.v_ned_mps, ins.q_nb, self.state.wind_ne_mps,
                             self.cfg.sideslip_noise_rad)  # fmt: skip
        if obs is None:
            return
        res = self._update(obs, self.beta_gate, AidSource.SIDESLIP, now_us)
        if res.test_ratio <= 1.0:
            self._c.sideslip_fused += 1
        else:
            self._c.sideslip_rejected += 1


def _air_speed(v_ned_mps: Vec3, wind_ne_mps: tuple[float, float]) -> float:
    an, ae = v_ned_mps[0] - wind_ne_mps[0], v_ned_mps[1] - wind_ne_mps[1]
    return math.sqrt(an * an + ae * ae + v_ned_mps[2] ** 2)


def _alpha_rad(ins: InsState, wind_ne_mps: tuple[float, float]) -> float:
    """Angle of attack of the air-relative velocity ``a = v - w`` in body axes,
    ``atan2(a_b,z, a_b,x)``, rad."""
    v = ins.v_ned_mps
    a = (v[0] - wind_ne_mps[0], v[1] - wind_ne_mps[1], v[2])
    c = dcm_from_quat(ins.q_nb)  # C_nb row-major: a_b = C_nb^T a
    bx = c[0] * a[0] + c[3] * a[1] + c[6] * a[2]
    bz = c[2] * a[0] + c[5] * a[1] + c[8] * a[2]
    return math.atan2(bz, bx)


def _pitot_inputs(ins: InsState, wind_ne_mps: tuple[float, float], tas_mps: float) -> PitotInputs:
    """The learned pitot error's inputs: angle of attack and sideslip of ``a = v - w`` in body
    axes, and the measured TAS."""
    v = ins.v_ned_mps
    a = (v[0] - wind_ne_mps[0], v[1] - wind_ne_mps[1], v[2])
    c = dcm_from_quat(ins.q_nb)  # C_nb row-major: a_b = C_nb^T a
    bx = c[0] * a[0] + c[3] * a[1] + c[6] * a[2]
    by = c[1] * a[0] + c[4] * a[1] + c[7] * a[2]
    bz = c[2] * a[0] + c[5] * a[1] + c[8] * a[2]
    speed = math.sqrt(bx * bx + by * by + bz * bz)
    beta = math.asin(max(-1.0, min(1.0, by / speed))) if speed > 0.0 else math.nan
    return PitotInputs(math.atan2(bz, bx), beta, tas_mps)


def _no_corrections() -> Vec3:
    return (0.0, 0.0, 0.0)
