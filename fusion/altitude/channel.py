"""The baro-inertial altitude channel of paper P4: altimeter, baro monitor, damping loop and
compensator, stepped together on IMU, baro and GNSS samples."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from numpy.typing import NDArray
from pydantic import Field, PositiveFloat

from fusion.altitude.altimeter import BaroAltimeter, BaroAltimeterConfig
from fusion.altitude.atmosphere import geometric_from_geopotential, geopotential_from_geometric
from fusion.altitude.baro_monitor import BaroHealth, BaroMonitor, BaroMonitorConfig
from fusion.altitude.calibration import BaroCalibrationConfig
from fusion.altitude.common import OMEGA_S2, Frozen, check_dt, check_finite
from fusion.altitude.loop import LoopGains, ThirdOrderLoop
from fusion.altitude.mpc import MpcCompensator, MpcConfig
from fusion.altitude.vertical_kf import VerticalKalman, VerticalKfConfig

FloatArray = NDArray[np.float64]

AltitudeMethod = Literal["loop", "loop-mpc", "loop-kf"]


class AltitudeChannelConfig(Frozen):
    """Everything an :class:`AltitudeChannel` needs (SI)."""

    method: AltitudeMethod = "loop-mpc"
    loop: LoopGains = LoopGains()
    baro: BaroAltimeterConfig = BaroAltimeterConfig()
    monitor: BaroMonitorConfig = BaroMonitorConfig()
    mpc: MpcConfig = MpcConfig()
    kf: VerticalKfConfig = VerticalKfConfig()
    gnss_timeout_s: PositiveFloat = 1.0
    """GNSS counts as valid while its last height is at most this old, s."""
    baro_hold_s: PositiveFloat = 1.0
    """The loop holds the last accepted baro height (advanced with its own ``vz``) this long
    across missing or rejected samples, then runs undamped (free inertial, ``a_c`` frozen), s."""
    max_baro_gnss_skew_s: PositiveFloat = 0.5
    """Calibrate only with a baro sample at most this far from the GNSS time, s."""
    freeze_rollback_m: PositiveFloat = 0.5
    """When a frozen sensor is declared, the loop is rolled back (see :class:`AltitudeChannel`)
    if its repeated readings had moved the loop's height by more than this (more than baro
    noise can: in level flight a stuck reading is harmless and the loop keeps its damped
    state), m."""
    freeze_rollback_mps: PositiveFloat = 0.2
    """... or its vertical speed by more than this, m/s."""
    omega_s2: float = Field(default=OMEGA_S2, ge=0.0)

    @classmethod
    def p4(
        cls, method: AltitudeMethod = "loop-mpc", *, gnss_calibration: bool = False
    ) -> AltitudeChannelConfig:
        """Paper P4's channel: its loop gains (K1 = 3.00, K2 = 0.6452, K3 = 0.8710), the
        untuned MPC (:meth:`MpcConfig.p4`) and P4's KF (:meth:`VerticalKfConfig.p4`).

        Parameters
        ----------
        method : {"loop", "loop-mpc", "loop-kf"}
        gnss_calibration : bool
            ``False`` (P4's set-up): the baro scale ``s`` comes from the sensed temperature
            only and ``b`` is not learned; GNSS reaches the altitude only through the
            compensator. ``True``: ``(s, b)`` learned from GNSS height as in the defaults, with
            an untuned random walk of ``b``, 0.02 m/√s.
        """
        cal = BaroCalibrationConfig(
            bias_random_walk_m_per_rth_s=0.02,
            use_gnss=gnss_calibration,
            use_temperature=not gnss_calibration,
        )
        return cls(
            method=method,
            loop=LoopGains.p4(),
            baro=BaroAltimeterConfig(calibration=cal),
            mpc=MpcConfig.p4(),
            kf=VerticalKfConfig.p4(),
        )


@dataclass(slots=True)
class AltitudeHealth:
    """Counters and flags of an :class:`AltitudeChannel`."""

    baro: BaroHealth = field(default_factory=BaroHealth)
    gnss_updates: int = 0
    gnss_rejected: int = 0
    calibration_updates: int = 0
    compensator_steps: int = 0
    qp_active: int = 0
    undamped: bool = False
    """The loop ran without baro feedback at the last IMU step."""
    freeze_rollbacks: int = 0
    """Frozen-sensor declarations that rolled the loop back (see :class:`AltitudeChannel`)."""
    initialised: bool = False


class AltitudeChannel:
    """Baro-inertial altitude: altimeter + monitor + third-order loop + compensator.

    Methods (``config.method``): ``loop`` (P4's damping loop alone), ``loop-mpc`` (P4: loop
    plus the Laguerre-MPC compensator, ``h_T = h − δh``), ``loop-kf`` (loop plus P4's Kalman
    comparator). (The fourth altitude method, ``ekf``, is the main filter's own baro
    update, not here.) In every method the barometer is calibrated for the non-standard
    atmosphere from GNSS height while GNSS is valid and frozen during outages; a calibration
    step moves the loop's datum with it (so it never shows as a loop transient or a gate
    rejection). ``BaroCalibrationConfig(use_gnss=False)`` reproduces P4's set-up instead, where
    GNSS reaches the altitude only through the compensator.

    Baro faults never raise: a sample out of the atmosphere model, a frozen sensor (identical
    readings for ``freeze_time_s``) or a jump beyond ``gate_m`` from the loop's height is
    counted in :attr:`health` and skipped; the loop bridges with the held sample, then
    inertially. A step that persists ``realign_after_rejected_s`` is taken as a new baro datum:
    the calibration bias is moved so that the baro agrees with the loop's height (no jump), and
    GNSS re-calibrates it when valid. GNSS heights that fail the calibration's innovation gate
    are counted (``gnss_rejected``) and not used.

    A frozen sensor is recognised only after ``freeze_time_s`` of identical readings, and until
    then its readings look valid. When the freeze is declared, the loop is rolled back to its
    state before the first repeated reading and re-run from there on the recorded IMU steps
    (and datum shifts) without them, as if they had been rejected at once: with P4's stiff
    gains two seconds of a stuck barometer in a 5 m/s climb leave the loop with a vertical
    speed ~3 m/s and an ``a_c`` ~2 m/s² wrong and, undamped afterwards, put the altitude
    hundreds of metres off. The rollback is applied only if the repeated readings had moved the
    loop by more than ``freeze_rollback_m`` / ``freeze_rollback_mps`` (in level flight they
    are harmless and the damped state is the better one). The compensator (MPC or KF) is rolled
    back with the loop: to its state at the checkpoint, then run on without measurements for
    the periods since (MPC: its outage mode; KF: prediction only), because its GNSS references
    and baro residuals in that time were taken against the corrupted loop. So is the baro
    calibration, which had fitted GNSS heights to the stuck pressure altitude (the datum shifts
    it made meanwhile are undone).

    Call order: :meth:`update_imu` at the IMU rate; :meth:`update_baro` and
    :meth:`update_gnss_height` as samples arrive (time-ordered, same time base as the IMU's).
    The channel initialises on the first accepted baro sample.

    Parameters
    ----------
    config : AltitudeChannelConfig
    start_time_s : float
        Time of the first IMU sample's start, s.
    """

    def __init__(self, config: AltitudeChannelConfig | None = None, start_time_s: float = 0.0):
        self.config = cfg = config or AltitudeChannelConfig()
        check_finite("start_time_s", start_time_s)
        self.health = AltitudeHealth()
        self.altimeter = BaroAltimeter(cfg.baro)
        self.monitor = BaroMonitor(cfg.monitor, self.health.baro)
        self.loop = ThirdOrderLoop.from_gains(
            cfg.loop, omega_s2=cfg.omega_s2, max_hold_s=cfg.baro_hold_s
        )
        self.mpc = MpcCompensator(cfg.mpc, cfg.omega_s2) if cfg.method == "loop-mpc" else None
        self.kf = VerticalKalman(cfg.kf, cfg.omega_s2) if cfg.method == "loop-kf" else None
        period = cfg.mpc.period_s if cfg.method == "loop-mpc" else cfg.kf.period_s
        self._comp_period = period
        self.time_s = float(start_time_s)
        self._next_comp_s = self.time_s + period
        self._last_gnss_s: float | None = None
        self._residual: float | None = None
        self._residual_sum = 0.0
        self._residual_n = 0
        self._residual_sigma = 1.0
        self._last_hp: float | None = None
        self._last_hp_time = -math.inf
        self._last_temperature: float | None = None
        self._last_baro_h: float | None = None
        self._last_baro_time = -math.inf
        self._pending_baro: float | None = None
        # Frozen-sensor rollback: loop state, pending baro height and last baro (height, time)
        # when the latest fresh (changed) reading was accepted, and since then the IMU steps
        # (az, dt) and datum shifts (None, delta) applied to the loop; also the calibration's
        # state and the pressure altitude (Hp, time) it calibrates against at that moment.
        self._run_p: float | None = None
        self._ckpt: (
            tuple[tuple[float, float, float, float | None, float, bool], float, float, float] | None
        ) = None
        self._cal_ckpt: (
            tuple[tuple[float, float, float, float, float, float | None, bool], float | None, float]
            | None
        ) = None
        self._since_ckpt: list[tuple[float | None, float]] = []
        # ... and the compensator's state at (or, unchanged, before) that checkpoint, with the
        # number of compensator periods run since the snapshot.
        self._comp_ckpt: object = None
        self._comp_steps_since = 0

    # ---- outputs -----------------------------------------------------------------------
    @property
    def method(self) -> AltitudeMethod:
        """The configured method."""
        return self.config.method

    @property
    def gnss_valid(self) -> bool:
        """A GNSS height arrived within ``gnss_timeout_s``."""
        return (
            self._last_gnss_s is not None
            and self.time_s - self._last_gnss_s <= self.config.gnss_timeout_s
        )

    def _period_fraction(self) -> float:
        return 1.0 - (self._next_comp_s - self.time_s) / self._comp_period

    @property
    def correction_m(self) -> float:
        """The compensator's ``δh`` now (0 for ``loop``), m."""
        if self.mpc is not None:
            return self.mpc.delta_at(self._period_fraction())[0]
        if self.kf is not None:
            return self.kf.delta_h_m
        return 0.0

    @property
    def loop_height_m(self) -> float:
        """The damping loop's own height ``h``, m."""
        return self.loop.h_m

    @property
    def height_m(self) -> float:
        """Best height above MSL, m: ``h − δh`` (NaN before initialisation)."""
        if not self.health.initialised:
            return math.nan
        return self.loop.h_m - self.correction_m

    @property
    def vz_mps(self) -> float:
        """Best vertical speed, up positive, m/s (NaN before initialisation)."""
        if not self.health.initialised:
            return math.nan
        if self.mpc is not None:
            return self.loop.vz_mps - self.mpc.delta_at(self._period_fraction())[1]
        if self.kf is not None:
            return self.loop.vz_mps - self.kf.delta_vz_mps
        return self.loop.vz_mps

    @property
    def baro_height_m(self) -> float:
        """Last calibrated baro height that passed the checks, m (NaN if none)."""
        return math.nan if self._last_baro_h is None else self._last_baro_h

    # ---- inputs ------------------------------------------------------------------------
    def update_imu(self, az_up_mps2: float, dt_s: float) -> None:
        """Advance the loop by one IMU interval.

        Parameters
        ----------
        az_up_mps2 : float
            ``f_up − g(φ, 0)``, m/s², up positive (module docstring).
        dt_s : float
            Interval, s (> 0).

        Raises
        ------
        ValueError
            Non-finite ``az`` or bad ``dt_s``.
        """
        if not math.isfinite(az_up_mps2):
            raise ValueError(f"az_up_mps2 must be finite (got {az_up_mps2!r})")
        check_dt(dt_s)
        self.time_s += dt_s
        if not self.health.initialised:
            return
        baro, self._pending_baro = self._pending_baro, None
        self.loop.step(az_up_mps2, baro, dt_s)
        self.health.undamped = not self.loop.damped
        if self._ckpt is not None:
            if self.time_s - self._ckpt[3] > self.config.monitor.freeze_time_s + 2.0:
                self._ckpt, self._since_ckpt = None, []  # no baro any more: nothing to undo
            else:
                self._since_ckpt.append((az_up_mps2, dt_s))
        gnss_ok = self.gnss_valid
        if gnss_ok:
            self.altimeter.unfreeze()
        else:
            self.altimeter.freeze()
        while self.time_s >= self._next_comp_s - 1e-9:
            self._next_comp_s += self._comp_period
            self._compensator_step(gnss_ok)

    def _compensator_step(self, gnss_ok: bool) -> None:
        if self.mpc is None and self.kf is None:
            return
        self.health.compensator_steps += 1
        self._comp_steps_since += 1
        fresh = self._residual_n > 0
        if fresh:
            self._residual = self._residual_sum / self._residual_n
            self._residual_sum, self._residual_n = 0.0, 0
        ref = self._residual if (gnss_ok and self._residual is not None) else None
        if self.mpc is not None:
            before = self.mpc.qp_active
            self.mpc.step(ref)
            self.health.qp_active += self.mpc.qp_active - before
        elif self.kf is not None:
            kf = self.kf
            if kf.started:
                kf.predict()
            if gnss_ok and fresh and self._residual is not None:
                kf.update_gnss(self._residual, self._residual_sigma)
            if (
                kf.started
                and kf.config.use_baro
                and self._last_baro_h is not None
                and self.time_s - self._last_baro_time <= self.config.baro_hold_s
            ):
                kf.update_baro(self.loop.h_m - self._last_baro_h)

    def update_baro(self, pressure_pa: float, temperature_k: float | None, time_s: float) -> bool:
        """One barometer sample.

        Bad samples (pressure ≤ 0, out of the atmosphere model, non-finite, a frozen sensor,
        a jump beyond the gate) are counted in :attr:`health` and not used; never raised.

        Parameters
        ----------
        pressure_pa : float
            Static pressure, Pa.
        temperature_k : float or None
            Sensor temperature, K.
        time_s : float
            Sample time, s.

        Returns
        -------
        bool
            Whether the sample was used.
        """
        hb = self.health.baro
        n_freeze = hb.freeze_events
        hp = self.monitor.check(pressure_pa, time_s)
        if hb.freeze_events != n_freeze:
            self._rollback()
        if hp is None:
            return False
        fresh = self._run_p is None or (
            abs(pressure_pa - self._run_p) > self.config.monitor.freeze_tolerance_pa
        )
        if fresh:
            self._run_p = pressure_pa
        self._last_hp, self._last_hp_time = hp, time_s
        if temperature_k is not None and math.isfinite(temperature_k) and temperature_k > 0.0:
            self._last_temperature = temperature_k
        h_baro = self.altimeter.altitude_from_hp(hp)
        if not self.health.initialised:
            self.loop.reset(h_baro)
            self.loop.set_baro(h_baro)
            self.health.initialised = True
            self.health.baro.accepted += 1
            self._last_baro_h, self._last_baro_time = h_baro, time_s
            return True
        if not self.monitor.gate(h_baro, self.loop.h_m, time_s):
            if fresh:
                self._ckpt, self._since_ckpt = None, []
            if self.monitor.rejecting_for_s(time_s) < self.config.monitor.realign_after_rejected_s:
                return False
            # A persistent step (sensor change, re-zeroed, cabin pressure): move the baro datum
            # onto the loop's height so the altitude stays continuous; GNSS re-calibrates it.
            shift = geopotential_from_geometric(self.loop.h_m) - geopotential_from_geometric(h_baro)
            self.altimeter.calibration.shift_bias(shift)
            self.monitor.clear_rejection()
            self.health.baro.realignments += 1
            h_baro = self.altimeter.altitude_from_hp(hp)
        if fresh:
            self._ckpt = (self.loop.snapshot(), h_baro, h_baro, time_s)
            self._cal_ckpt = (self.altimeter.calibration.snapshot(), hp, time_s)
            self._since_ckpt = []
            if self._comp_steps_since or self._comp_ckpt is None:
                # The compensator changes only at its period (0.2 s): a new snapshot only if
                # it stepped since the last one (baro samples come at up to 50 Hz).
                self._comp_ckpt = self._comp_snapshot()
                self._comp_steps_since = 0
        self._pending_baro = h_baro
        self._last_baro_h, self._last_baro_time = h_baro, time_s
        return True

    def _rollback(self) -> None:
        """Undo the repeated readings of a sensor just declared frozen (see class docstring)."""
        ck = self._ckpt
        if ck is None:
            return
        state, pending, last_h, last_t = ck
        loop = self.loop
        current = loop.snapshot()
        loop.restore(state)
        baro: float | None = pending
        for az, x in self._since_ckpt:
            if az is None:  # a calibration step moved the datum meanwhile
                loop.shift(x)
                last_h += x
                if baro is not None:
                    baro += x
            else:
                loop.step(az, baro, x)
                baro = None
        cfg = self.config
        if (
            abs(current[0] - loop.h_m) <= cfg.freeze_rollback_m
            and abs(current[1] - loop.vz_mps) <= cfg.freeze_rollback_mps
        ):
            loop.restore(current)  # the repeats agreed with inertia: keep the damped state
            self._ckpt, self._since_ckpt = None, []
            return
        self.health.freeze_rollbacks += 1
        self._comp_rollback()
        if self._cal_ckpt is not None:
            # The calibration had learned from GNSS heights against the stuck Hp: back to its
            # state at the checkpoint, and the datum shifts it made since are undone.
            cal_state, self._last_hp, self._last_hp_time = self._cal_ckpt
            self.altimeter.calibration.restore(cal_state)
            undo = -sum(x for az, x in self._since_ckpt if az is None)
            if undo:
                loop.shift(undo)
                last_h += undo
                if baro is not None:
                    baro += undo
        if baro is not None:  # no IMU step since the checkpoint: still to be applied
            self._pending_baro = baro
        else:
            self._pending_baro = None
        self.health.undamped = not loop.damped
        self._last_baro_h, self._last_baro_time = last_h, last_t
        self._ckpt, self._since_ckpt = None, []

    def _comp_snapshot(self) -> object:
        if self.mpc is not None:
            return self.mpc.snapshot()
        if self.kf is not None:
            return self.kf.snapshot()
        return None

    def _comp_rollback(self) -> None:
        """Roll the compensator back with the loop: restore its state at the checkpoint and
        re-run the periods since without measurements. Its references and baro residuals in
        that time were made against the loop the stuck readings had pulled away; kept, they
        would carry that error into ``h − δh`` after the loop itself was repaired."""
        state, n = self._comp_ckpt, self._comp_steps_since
        if state is None:
            return
        if self.mpc is not None:
            self.mpc.restore(state)  # type: ignore[arg-type]
            for _ in range(n):
                self.mpc.step(None)  # the outage behaviour (hold by default)
        elif self.kf is not None:
            self.kf.restore(state)  # type: ignore[arg-type]
            if self.kf.started:
                for _ in range(n):
                    self.kf.predict()
        # Residuals gathered since were against the wrong loop height: drop them.
        self._residual = None
        self._residual_sum, self._residual_n = 0.0, 0
        self._comp_ckpt, self._comp_steps_since = None, 0  # re-snapshot at the next checkpoint

    def update_gnss_height(
        self,
        height_m: float,
        sigma_m: float,
        time_s: float,
        *,
        reference: Literal["msl", "ellipsoid"] = "msl",
        geoid_undulation_m: float = 0.0,
    ) -> None:
        """One GNSS height.

        Parameters
        ----------
        height_m : float
            GNSS height, m (above MSL or above the ellipsoid, per ``reference``).
        sigma_m : float
            Its 1σ (e.g. ``epv``), m (> 0).
        time_s : float
            Time of validity, s (same time base as the IMU; treated as "now").
        reference : {"msl", "ellipsoid"}
        geoid_undulation_m : float
            ``N`` for ``reference="ellipsoid"``, m.

        Raises
        ------
        ValueError
            Non-finite values, ``sigma_m ≤ 0``, unknown ``reference``.
        """
        for name, v in (
            ("height_m", height_m),
            ("time_s", time_s),
            ("geoid_undulation_m", geoid_undulation_m),
        ):
            check_finite(name, v)
        if not (math.isfinite(sigma_m) and sigma_m > 0.0):
            raise ValueError(f"sigma_m must be finite and > 0 (got {sigma_m!r})")
        if reference == "ellipsoid":
            h_msl = height_m - geoid_undulation_m
        elif reference == "msl":
            h_msl = height_m
        else:
            raise ValueError(f"reference must be 'msl' or 'ellipsoid' (got {reference!r})")
        self._last_gnss_s = time_s
        self.health.gnss_updates += 1
        self.altimeter.unfreeze()
        cal = self.altimeter.calibration
        if (
            self.config.baro.mode == "calibrated"
            and self._last_hp is not None
            and abs(time_s - self._last_hp_time) <= self.config.max_baro_gnss_skew_s
        ):
            # Bring the last Hp to the GNSS time with the loop's vertical speed.
            hp = self._last_hp + self.loop.vz_mps * (time_s - self._last_hp_time) / (
                1.0 + cal.scale
            )
            h_before = self.altimeter.altitude_from_hp(hp)
            upd = cal.update(
                h_msl, hp, time_s, sigma_m=sigma_m, temperature_k=self._last_temperature
            )
            if upd.rejected:
                self.health.gnss_rejected += 1
                return
            if upd.delta_altitude_m != 0.0:
                self.health.calibration_updates += 1
                shift = (
                    geometric_from_geopotential(
                        geopotential_from_geometric(h_before) + upd.delta_altitude_m
                    )
                    - h_before
                )
                if self.health.initialised:
                    # The datum moved: carry the loop with it (no transient, no gate trip).
                    self.loop.shift(shift)
                    if self._ckpt is not None:
                        self._since_ckpt.append((None, shift))
                    if self._last_baro_h is not None:
                        self._last_baro_h += shift
                    if self._pending_baro is not None:
                        self._pending_baro += shift
        if self.health.initialised:
            # The compensators get the mean residual since their last step.
            self._residual_sum += self.loop.h_m - h_msl
            self._residual_n += 1
            self._residual_sigma = sigma_m
