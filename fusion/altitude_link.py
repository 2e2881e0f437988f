"""NavFilter's link to the altitude method: feeds the altitude channel, screens the barometer
for the EKF, and says whose vertical the estimate carries.

With a loop method (``loop`` / ``loop-mpc`` / ``loop-kf``, paper P4's baro-inertial channel)
the estimate's altitude and vertical velocity come from
:class:`fusion.altitude.channel.AltitudeChannel`, fed with the INS vertical acceleration of each
strapdown step, every baro sample and the fused GNSS heights. The EKF keeps its own baro update
for its internal state, but only with the samples the channel accepted (range, freeze and
glitch checks); the channel's output is not fed back. Why: (1) the EKF's vertical stays bounded
by the barometer through an outage exactly as with ``ekf``, and the horizontal solution is
*identical* to ``ekf`` whenever the barometer is healthy (only faulty samples differ, and those
are better left out of the EKF too); (2) the channel's height is a filtered, time-correlated
signal that already contains the GNSS heights the EKF fused: feeding it back as a white
pseudo-measurement would double-count GNSS and make the EKF overconfident in height, vertical
velocity and the accelerometer bias; (3) the altitude methods then differ only in the output
vertical, which is what a comparison of them should measure.

With ``ekf`` there is no channel: the barometer is screened by a
:class:`~fusion.altitude.baro_monitor.BaroMonitor` (frozen sensor) before the EKF update. Every
method also holds back readings repeated for longer than ``ekf_repeat_hold_s``.
"""

from __future__ import annotations

import math

from fusion.altitude.baro_monitor import BaroMonitor
from fusion.altitude.channel import AltitudeChannel, AltitudeChannelConfig
from fusion.config import AltitudeConfig
from fusion.estimate import AltitudeStatus, HealthCounters
from fusion.rotations import dcm_from_quat
from fusion.samples import BaroSample, GnssFix
from fusion.strapdown import InsState


class AltitudeLink:
    """The altitude method as seen from :class:`fusion.filter.NavFilter` (module docstring).

    Parameters
    ----------
    config : AltitudeConfig
        The method (validated by the filter) and its channel settings.
    lever_arm_b_m : 3 floats
        GNSS antenna w.r.t. the IMU in body FRD, m.
    counters : HealthCounters
        Where baro and calibration events are counted.
    """

    def __init__(
        self, config: AltitudeConfig, lever_arm_b_m: tuple[float, float, float],
        counters: HealthCounters,
    ) -> None:  # fmt: skip
        method = config.method
        self._method = method
        self._cfg: AltitudeChannelConfig | None = (
            None if method == "ekf" else config.channel.model_copy(update={"method": method})
        )
        self.loop = self._cfg is not None
        """A loop method: the channel runs beside the EKF."""
        self._omega_s2 = config.channel.omega_s2
        self._freeze_tol_pa = config.channel.monitor.freeze_tolerance_pa
        self._repeat_hold_s = config.ekf_repeat_hold_s
        self._lever_arm_b_m = lever_arm_b_m
        self._c = counters
        # the loop methods' channel is created at the first IMU or baro epoch after alignment
        self.channel: AltitudeChannel | None = None
        self._ready = False
        self._monitor = BaroMonitor(config.channel.monitor)
        self._run: tuple[float, int] | None = None  # (pressure, since time_us) of a repeat run
        # no channel: the status has one variable field, so it is built once per value
        # (AltitudeStatus is immutable; its __init__ with 17 fields costs ~3 us)
        self._status_idle: dict[bool, AltitudeStatus] = {}

    def restart(self) -> None:
        """The filter (re)started: so does the channel, at its next input."""
        self.channel = None
        self._ready = False

    def _new_channel(self, start_us: int) -> AltitudeChannel:
        assert self._cfg is not None
        self.channel = AltitudeChannel(self._cfg, start_us * 1e-6)
        return self.channel

    # ------------------------------------------------------------------ inputs
    def on_imu(self, time_us: int, dt_s: float, vd0_mps: float, ins: InsState) -> None:
        """One strapdown step (loop methods) of ``dt_s`` ending at ``time_us``.

        The mechanised vertical acceleration of this epoch's step alone (no feedback in it):
        specific force less the EKF's bias estimates, normal gravity at the INS height,
        Coriolis and transport terms. The channel wants ``f_up - g(lat, 0)`` and adds
        ``2 ws^2 h`` of its *own* height back (P4 eq. 5), hence the shift by the INS height's
        free-air term.

        Parameters
        ----------
        time_us : int
        dt_s : float
        vd0_mps : float
            INS down velocity at the start of the step, m/s.
        ins : InsState
            INS at the end of the step.
        """
        ch = self.channel or self._new_channel(time_us - round(dt_s * 1e6))
        ch.update_imu((vd0_mps - ins.v_ned_mps[2]) / dt_s - 2.0 * self._omega_s2 * ins.alt_msl_m,
                      dt_s)  # fmt: skip

    def coast(self, ins_alt_m: float, gap_s: float) -> None:
        """An IMU gap the INS coasted over: the channel (if running) coasts on zero
        acceleration."""
        if self.channel is not None:
            self.channel.update_imu(-2.0 * self._omega_s2 * ins_alt_m, gap_s)

    def on_gnss_height(
        self, fix: GnssFix, past: InsState, ins: InsState, sigma_m: float, now_us: int
    ) -> None:
        """A fused GNSS height into the channel (loop methods), moved from the antenna to the
        IMU and from its time of validity to now with the INS height change (0.1 s of latency
        at 2.5 m/s of climb would otherwise be a 0.25 m bias in the calibration and the MPC
        reference).

        Parameters
        ----------
        fix : GnssFix
        past : InsState
            The INS at the fix's time of validity.
        ins : InsState
            The INS now.
        sigma_m : float
            The fix's vertical sigma, m.
        now_us : int
            INS time.
        """
        ch = self.channel or self._new_channel(now_us)
        h = float(fix.alt_msl_m) + (ins.alt_msl_m - past.alt_msl_m)
        ax, ay, az = self._lever_arm_b_m
        if ax or ay or az:  # antenna height = IMU height - (C_nb arm)_D
            c_nb = dcm_from_quat(past.q_nb)
            h += c_nb[6] * ax + c_nb[7] * ay + c_nb[8] * az
        hh, c = ch.health, self._c
        n_cal, n_rej = hh.calibration_updates, hh.gnss_rejected
        ch.update_gnss_height(h, sigma_m, now_us * 1e-6)
        c.altitude_calibration_updates += hh.calibration_updates - n_cal
        c.altitude_gnss_rejected += hh.gnss_rejected - n_rej

    def screen_baro(self, s: BaroSample, pressure_pa: float, time_us: int, now_us: int) -> bool:
        """Freeze (and, for the loop methods, the channel's gate and the channel's own
        update): whether the EKF may use the sample (its pressure is in range). Rejections are
        counted, never raised.

        Parameters
        ----------
        s : BaroSample
        pressure_pa : float
            The sample's pressure (checked in range), Pa.
        time_us : int
            The sample's time.
        now_us : int
            INS time.
        """
        c = self._c
        p, t = pressure_pa, time_us
        if self._cfg is None:
            if self._monitor.check(p, t * 1e-6) is None:  # in range (checked before): frozen
                c.baro_frozen += 1
                return False
            return True
        try:
            temp: float | None = float(s.temperature_k)
        except (TypeError, ValueError, AttributeError):
            temp = None
        if temp is not None and not (math.isfinite(temp) and temp > 0.0):
            temp = None
        ch = self.channel or self._new_channel(now_us)
        hb = ch.health.baro
        n_frozen, n_gate, n_realign = hb.frozen_samples, hb.gate_rejections, hb.realignments
        used = ch.update_baro(p, temp, t * 1e-6)
        c.baro_frozen += hb.frozen_samples - n_frozen
        c.baro_glitches += hb.gate_rejections - n_gate
        c.baro_realignments += hb.realignments - n_realign
        return used

    def repeat_ok(self, pressure_pa: float, time_us: int) -> bool:
        """False (counted) for a reading unchanged for more than ``ekf_repeat_hold_s``."""
        p, t = pressure_pa, time_us
        run = self._run
        if run is None or abs(p - run[0]) > self._freeze_tol_pa:
            self._run = (p, t)
            return True
        if (t - run[1]) * 1e-6 > self._repeat_hold_s:
            self._c.baro_repeats_held += 1
            return False
        return True

    # ------------------------------------------------------------------ outputs
    def vertical(self) -> tuple[float, float] | None:
        """The channel's ``(height m, vertical speed up m/s)`` once the estimate carries it
        (loop methods), else ``None`` (the EKF's vertical)."""
        ch = self.channel
        if ch is not None and (self._ready or self._check_ready(ch)):
            return ch.height_m, ch.vz_mps
        return None

    def _check_ready(self, ch: AltitudeChannel) -> bool:
        """The channel's output is used from its first GNSS calibration (if it learns one) and
        its compensator's first reference (if it has one) on: before that it would show the
        uncalibrated baro height and then jump by the calibration (tens of metres)."""
        hh = ch.health
        if not hh.initialised:
            return False
        bc = ch.config.baro
        if bc.mode == "calibrated" and bc.calibration.use_gnss and hh.calibration_updates == 0:
            return False
        comp = ch.mpc if ch.mpc is not None else ch.kf
        self._ready = comp is None or comp.started
        return self._ready

    def status(self) -> AltitudeStatus:
        """The altitude method's state now."""
        ch = self.channel
        if ch is None:
            frozen = self._monitor.health.frozen
            cached = self._status_idle.get(frozen)
            if cached is None:
                cached = AltitudeStatus(self._method, baro_frozen=frozen)
                self._status_idle[frozen] = cached
            return cached
        cal = ch.altimeter.calibration
        hh = ch.health
        return AltitudeStatus(
            ch.method, self._ready, hh.initialised, ch.gnss_valid, cal.frozen, cal.scale,
            cal.bias_m, cal.sea_level_dt_k, cal.sea_level_dp_pa, ch.loop_height_m, ch.baro_height_m,
            ch.correction_m, hh.compensator_steps, hh.qp_active, hh.undamped, hh.baro.frozen,
            hh.baro.rejecting,
        )  # fmt: skip
