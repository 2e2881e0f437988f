"""Pitot fault detection: a blocked or stuck pitot is dropped, and trusted again only after it
passes a consistency check.

Three signatures of a failed pitot-static system (icing, water, a disconnected line, a
latched sensor), each checked on the averaged batches the filter fuses
(:class:`fusion.aiding.airspeed.AirspeedAiding`):

- **stuck** — over ``stuck_window_s`` the readings vary less than ``stuck_ratio`` times what
  the sensor noise plus the predicted change of impact pressure would make, while the
  predicted airspeed changed by at least ``stuck_min_change_mps`` over the window (a pitot
  that keeps its last value through a climb or a throttle change); or the readings are
  bit-identical over the window (a latched sensor) while flying. The predicted change is
  the inertial acceleration along the air-relative flight path: the INS velocity's changes
  (with the filter's corrections within the window undone: a fused stuck reading pulls the
  corrected velocity towards itself) projected on the body's air-velocity direction
  ``C_nb (cos a, 0, sin a)`` at the angle of attack ``a`` (no sideslip). Since the INS
  turns its velocity with its own attitude, that projection is the specific force along
  the path plus gravity's share, which depends on roll and pitch but not on the heading
  nor on the wind estimate: a wrong heading (after an IMU fault) makes a wrong wind, and
  ``|v - w|`` then swings through every turn while the true airspeed is steady. A stuck
  reading in steady flight is not detectable, and harmless while it lasts: it
  still reads the airspeed;
- **zero** — the reading is below ``zero_airspeed_mps`` for ``zero_time_s`` while the
  predicted airspeed is above ``flying_speed_mps`` (the pitot worked before: the wind
  states are running only after it read a flying airspeed);
- **rejected** — every batch rejected by the innovation gate for ``reject_time_s``.

While blocked, each batch is still tested against the current wind and velocity (without
being fused). The pitot is trusted again only after ``recover_time_s`` of batches that pass
the gate and the zero and stuck checks; after a *stuck* fault one of those windows must also
show the readings following a predicted airspeed change (a stuck pitot passes everything in
steady flight).
"""

from __future__ import annotations

import math
from collections import deque

from fusion.config import AirspeedTuning
from fusion.rotations import dcm_from_quat
from physconst.airdata import impact_pressure_pa

Vec3 = tuple[float, float, float]
Quat = tuple[float, float, float, float]


class PitotMonitor:
    """Pitot health: the three fault checks and the recovery test (see module docstring).

    Parameters
    ----------
    cfg : AirspeedTuning

    Attributes
    ----------
    blocked : bool
        The pitot is declared blocked (not fused).
    fault : str
        ``stuck``, ``zero`` or ``rejected`` while blocked, ``""`` otherwise.
    """

    def __init__(self, cfg: AirspeedTuning) -> None:
        self.cfg = cfg
        self.blocked = False
        self.fault = ""
        self._window_us = round(cfg.stuck_window_s * 1e6)
        self._zero_us = round(cfg.zero_time_s * 1e6)
        self._reject_us = round(cfg.reject_time_s * 1e6)
        self._recover_us = round(cfg.recover_time_s * 1e6)
        self._readings: deque[tuple[int, float]] = deque()
        # t, INS velocity at the batch, cumulative feedback velocity correction at the batch,
        # air-velocity direction in NED (None: no attitude given)
        self._predicted: deque[tuple[int, Vec3, Vec3, Vec3 | None]] = deque()
        self._zero_since_us: int | None = None
        self._rejected_since_us: int | None = None
        self._pass_since_us: int | None = None
        self._followed = False  # a stuck-evaluable window passed during recovery

    def add_reading(self, time_us: int, diff_pressure_pa: float) -> None:
        """One valid raw reading (the stuck check looks at their spread)."""
        r = self._readings
        r.append((time_us, diff_pressure_pa))
        while r and r[0][0] < time_us - self._window_us:
            r.popleft()

    def assess(
        self, time_us: int, tas_mps: float, v_ned_mps: Vec3, correction_ned_mps: Vec3,
        wind_ne_mps: tuple[float, float], scale: float, static_pa: float, temp_k: float,
        q_nb: Quat | None = None, alpha_rad: float = 0.0,
    ) -> str:  # fmt: skip
        """The fault the current batch shows, ``""`` if none.

        Parameters
        ----------
        time_us : int
            Batch time.
        tas_mps : float
            Measured TAS of the batch, m/s.
        v_ned_mps : 3 floats
            INS velocity at the batch time, m/s.
        correction_ned_mps : 3 floats
            Sum of every velocity correction the filter's feedback made so far, m/s: the
            stuck check undoes the corrections made within its window, so that its predicted
            airspeed is the inertial one (a fused stuck reading pulls the corrected velocity
            towards itself and would hide the change it failed to follow).
        wind_ne_mps, scale : the current wind and airspeed-scale estimates.
        static_pa, temp_k : static pressure and temperature (the predicted impact pressure).
        q_nb : 4 floats, optional
            INS attitude at the batch time: the stuck check's airspeed change is the inertial
            acceleration along the air-velocity direction it gives (see the module
            docstring). Without it the change is that of ``|v - w|`` (the wind estimate's).
        alpha_rad : float
            Angle of attack at the batch time, rad (0 if not finite).
        """
        cfg = self.cfg
        p = self._predicted
        u = None if q_nb is None else _air_direction_ned(q_nb, alpha_rad)
        p.append((time_us, v_ned_mps, correction_ned_mps, u))
        while p and p[0][0] < time_us - self._window_us:
            p.popleft()
        g = 1.0 + scale
        wn, we = wind_ne_mps
        predicted_tas_mps = g * math.sqrt((v_ned_mps[0] - wn) ** 2 + (v_ned_mps[1] - we) ** 2
                                          + v_ned_mps[2] ** 2)  # fmt: skip
        flying = predicted_tas_mps > cfg.flying_speed_mps
        # zero while flying
        if tas_mps < cfg.zero_airspeed_mps and flying:
            if self._zero_since_us is None:
                self._zero_since_us = time_us
            if time_us - self._zero_since_us >= self._zero_us:
                return "zero"
        else:
            self._zero_since_us = None
        return self._stuck(time_us, flying, wind_ne_mps, g, correction_ned_mps, static_pa,
                           temp_k)  # fmt: skip

    def _stuck(
        self, time_us: int, flying: bool, wind_ne_mps: tuple[float, float], gain: float,
        corr_now: Vec3, static_pa: float, temp_k: float,
    ) -> str:  # fmt: skip
        r, p = self._readings, self._predicted
        # the window must be (nearly) full: judged on the readings' own span, not on the batch
        # time (a 1 Hz batch's mean time is 0.5 s before its last reading, so a 4 s window's
        # span by batch times is 3.5 s, under 0.9 of it: the check would never run)
        if not r or r[-1][0] - r[0][0] < 0.9 * self._window_us or len(r) < 5 or len(p) < 3:
            return ""
        values = [q for _, q in r]
        if flying and max(values) == min(values):
            return "stuck"
        wn, we = wind_ne_mps
        tas_pred = []
        for _, v, c, _u in p:
            # the velocity as the INS alone would have carried it to now: corrections made
            # since this batch undone
            vn = v[0] + corr_now[0] - c[0] - wn
            ve = v[1] + corr_now[1] - c[1] - we
            vd = v[2] + corr_now[2] - c[2]
            tas_pred.append(gain * math.sqrt(vn * vn + ve * ve + vd * vd))
        if all(e[3] is not None for e in p):
            tas_pred = _along_path(p, tas_pred[-1])
        if max(tas_pred) - min(tas_pred) < self.cfg.stuck_min_change_mps:
            return ""  # no predicted change: nothing to follow
        std_meas = _std(values)
        std_pred = _std([impact_pressure_pa(v, static_pa, temp_k) for v in tas_pred])
        expected = math.hypot(self.cfg.diff_pressure_noise_pa, std_pred)
        if std_meas < self.cfg.stuck_ratio * expected:
            return "stuck"
        if self.blocked:
            self._followed = True
        return ""

    def on_batch(self, time_us: int, fault: str, gate_ok: bool) -> str:
        """Advance the state with one batch's verdicts.

        Parameters
        ----------
        time_us : int
        fault : str
            :meth:`assess`'s result for the batch.
        gate_ok : bool
            The batch passed the innovation gate (fused, or, while blocked, tested).

        Returns
        -------
        str
            ``"blocked"`` when the pitot was just declared blocked, ``"recovered"`` when it was
            just trusted again, ``""`` otherwise.
        """
        if not self.blocked:
            if gate_ok:
                self._rejected_since_us = None
            elif self._rejected_since_us is None:
                self._rejected_since_us = time_us
            if not fault and self._rejected_since_us is not None and (
                time_us - self._rejected_since_us >= self._reject_us
            ):
                fault = "rejected"
            if fault:
                self.blocked = True
                self.fault = fault
                self._pass_since_us = None
                self._followed = False
                self._rejected_since_us = None
                return "blocked"
            return ""
        if fault or not gate_ok:
            self._pass_since_us = None
            self._followed = False
            return ""
        if self._pass_since_us is None:
            self._pass_since_us = time_us
        passed = time_us - self._pass_since_us >= self._recover_us
        if passed and (self.fault != "stuck" or self._followed):
            self.blocked = False
            self.fault = ""
            self._pass_since_us = None
            self._zero_since_us = None
            return "recovered"
        return ""

    def on_low(self, time_us: int) -> None:
        """A batch too slow to fuse while blocked: it does not count towards recovery."""
        if self.blocked:
            self._pass_since_us = None
            self._followed = False


def _air_direction_ned(q_nb: Quat, alpha_rad: float) -> Vec3:
    """``C_nb (cos a, 0, sin a)``: the air-relative velocity's direction at angle of attack
    ``a`` and no sideslip, NED."""
    a = alpha_rad if math.isfinite(alpha_rad) else 0.0
    ca, sa = math.cos(a), math.sin(a)
    c = dcm_from_quat(q_nb)  # row-major C_nb
    return (c[0] * ca + c[2] * sa, c[3] * ca + c[5] * sa, c[6] * ca + c[8] * sa)


def _along_path(p: deque[tuple[int, Vec3, Vec3, Vec3 | None]], tas_now: float) -> list[float]:
    """The airspeed over the window from the inertial acceleration along the flight path:
    each step's inertial velocity change (feedback corrections undone) projected on the mean
    air-velocity direction of its two ends, summed, and ending at ``tas_now``."""
    path = [0.0]
    prev = p[0]
    for cur in list(p)[1:]:
        u0, u1 = prev[3], cur[3]
        if u0 is None or u1 is None:  # the caller checked: every batch has its attitude
            return [tas_now] * len(p)
        d = [cur[1][i] - cur[2][i] - prev[1][i] + prev[2][i] for i in range(3)]
        path.append(path[-1] + 0.5 * sum(d[i] * (u0[i] + u1[i]) for i in range(3)))
        prev = cur
    return [tas_now + s - path[-1] for s in path]


def _std(values: list[float]) -> float:
    n = len(values)
    mean = sum(values) / n
    return math.sqrt(max(0.0, sum((v - mean) ** 2 for v in values) / n))
