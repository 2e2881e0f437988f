"""A small, aircraft-agnostic guidance and control law that flies a :class:`FlightPlan`.

Why our own law rather than JSBSim's autopilots: only some aircraft ship one (c172x's
``c172ap.xml``, c310's ``c310ap.xml``), their property interfaces differ, and c172ap's sensor
blocks draw noise from JSBSim's random generator. One generic law keeps every aircraft on the
same plan semantics. It writes only the standard normalised FCS inputs every JSBSim aircraft
has (``fcs/aileron-cmd-norm``, ``fcs/elevator-cmd-norm``, ``fcs/rudder-cmd-norm``,
``fcs/throttle-cmd-norm[i]``); ``sim.flight`` does that, this module is pure arithmetic.

Structure (SI, radians)::

    plan leg --> course / bank target --> bank command --> roll PI + rate damping --> aileron
             --> altitude target --> climb-rate command --> pitch command
                  --> pitch-rate command (+ turn feed-forward) --> PI --> elevator
             --> airspeed target --> throttle PI (feed-forward: trim throttle)
    sideslip PI + yaw damper --> rudder

Control-surface gains are scheduled with dynamic pressure (``qbar_trim / qbar``) so the same
gains serve the trim condition of light and heavy aircraft alike. Sign conventions follow
JSBSim's: +aileron rolls right, +elevator pitches nose down, +rudder yaws nose left.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import NamedTuple

from pydantic import BaseModel, ConfigDict, Field

from physconst import G0_MPS2
from sim import kernel
from sim.plans import FlightPlan, Leg

_PI = math.pi
_TWO_PI = 2.0 * math.pi
_RAD_3 = math.radians(3.0)  # the angle-of-attack guard's band


def _wrap(angle_rad: float) -> float:
    """Wrap an angle to [-pi, pi)."""
    return (angle_rad + math.pi) % (2.0 * math.pi) - math.pi


def _clip(x: float, lo: float, hi: float) -> float:
    return lo if x < lo else hi if x > hi else x


class GuidanceGains(BaseModel):
    """Gains and limits of the guidance law (SI / radians; tuned on c172x and c310)."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    # outer loops
    k_course: float = Field(default=0.25, gt=0, description="turn-rate per course error, 1/s")
    lookahead_s: float = Field(default=8.0, gt=0, description="track lookahead, seconds of flight")
    min_lookahead_m: float = Field(default=250.0, gt=0)
    max_intercept_rad: float = Field(default=math.radians(60.0), gt=0)
    k_alt: float = Field(default=0.15, gt=0, description="climb rate per altitude error, 1/s")
    k_hdot: float = Field(default=0.02, ge=0, description="pitch per climb-rate error, rad s/m")
    ki_hdot: float = Field(default=0.004, ge=0, description="rad/m")
    pitch_min_rad: float = math.radians(-12.0)
    pitch_max_rad: float = math.radians(15.0)
    alpha_max_rad: float = Field(
        default=math.radians(12.0), gt=0, description="angle of attack the law will not exceed"
    )
    k_alpha: float = Field(default=3.0, ge=0, description="pitch-rate cut per rad over alpha_max")
    speed_guard_mps: float = Field(default=4.0, gt=0, description="under-speed before pitch gives")
    k_speed_guard: float = Field(default=0.03, ge=0, description="pitch per m/s under/over speed")
    # inner loops (at the trim dynamic pressure; scaled with qbar_trim / qbar)
    k_phi: float = Field(default=4.0, ge=0, description="aileron per rad bank error")
    ki_phi: float = Field(default=1.0, ge=0)
    k_p: float = Field(default=1.0, ge=0, description="aileron per rad/s roll rate")
    k_theta: float = Field(default=1.5, gt=0, description="pitch-rate command per pitch error, 1/s")
    max_q_rps: float = Field(default=math.radians(10.0), gt=0)
    k_q: float = Field(default=2.5, ge=0, description="elevator per rad/s pitch-rate error")
    ki_theta: float = Field(default=1.0, ge=0, description="elevator per rad s pitch error")
    k_beta: float = Field(default=1.5, ge=0, description="rudder per rad sideslip")
    ki_beta: float = Field(default=0.5, ge=0)
    k_r: float = Field(default=1.0, ge=0, description="rudder per rad/s yaw-rate (damper)")
    k_v: float = Field(default=0.05, ge=0, description="throttle per m/s speed error")
    ki_v: float = Field(default=0.01, ge=0)
    default_bank_limit_rad: float = math.radians(30.0)
    default_turn_bank_rad: float = math.radians(25.0)
    default_climb_rate_mps: float = Field(default=2.5, gt=0)


class GuidanceInput(NamedTuple):
    """What the law needs of the aircraft state, in SI.

    ``north_m`` / ``east_m`` are offsets from the start position; angles in rad, rates in
    rad/s (body, relative to the Earth), ``qbar_pa`` the dynamic pressure. (A NamedTuple:
    built at every step, it must be cheap.)
    """

    time_s: float
    dt_s: float
    north_m: float
    east_m: float
    alt_m: float
    v_north_mps: float
    v_east_mps: float
    v_down_mps: float
    airspeed_mps: float
    phi_rad: float
    theta_rad: float
    psi_rad: float
    p_rps: float
    q_rps: float
    r_rps: float
    alpha_rad: float
    beta_rad: float
    qbar_pa: float


class Controls(NamedTuple):
    """Normalised control commands: aileron/elevator/rudder in [-1, 1], throttle in [0, 1]."""

    aileron: float
    elevator: float
    rudder: float
    throttle: float


@dataclass(frozen=True, slots=True)
class TrimPoint:
    """The trimmed condition the law starts from (its integrators start at these values)."""

    controls: Controls
    theta_rad: float
    qbar_pa: float
    phi_rad: float = 0.0


def law_python(
    s: GuidanceInput,
    course_err: float | None,
    phi_fixed: float,
    limit: float,
    pitch_direct: bool,
    theta_fixed: float,
    alt_target_m: float,
    airspeed_target_mps: float,
    climb_rate_mps: float,
    integrators: list[float],
    params: tuple[float, ...],
) -> Controls:
    """The control loops of one step (Python reference of the compiled kernel's ``law``).

    Parameters
    ----------
    s : the aircraft state.
    course_err : course error to fly, rad; None when the leg commands bank directly
        (``phi_fixed``, rad).
    limit : bank limit, rad (when ``course_err`` is given).
    pitch_direct : the leg commands pitch directly (``theta_fixed``, rad).
    alt_target_m, airspeed_target_mps, climb_rate_mps : the current targets.
    integrators : climb-rate, roll, pitch, sideslip and speed integrators; updated in place.
    params : the gains, then trim bank, pitch, dynamic pressure and controls
        (:attr:`Guidance._law_params`).
    """
    (k_course, k_alt, k_hdot, ki_hdot, pitch_min, pitch_max, alpha_max, k_alpha, speed_guard,
     k_speed_guard, k_phi, ki_phi, k_p, k_theta, max_q, k_q, ki_theta, k_beta, ki_beta, k_r,
     k_v, ki_v, trim_phi, trim_theta, trim_qbar, trim_ail, trim_ele, trim_rud,
     trim_thr) = params
    (_, dt, _, _, alt, _, _, v_down, airspeed, phi, theta, _, p, q, r, alpha, beta, qbar) = s
    # the clips are written out inline (same operations, same order, as _clip)
    v = 1.0 if 1.0 > airspeed else airspeed  # max(airspeed, 1.0), NaN included
    # angle-of-attack guard: within 3 deg of alpha_max, bank and pull are cut back
    alpha_margin = alpha_max - alpha
    if pitch_direct:
        protect = 0.0
    else:
        x = 1.0 - alpha_margin / _RAD_3
        protect = 0.0 if x < 0.0 else 1.0 if x > 1.0 else x

    # lateral: course error -> turn rate -> bank (coordinated turn: tan(phi) = V r / g)
    if course_err is None:
        phi_cmd = phi_fixed
    else:
        x = math.atan(v * k_course * course_err / G0_MPS2)
        phi_cmd = -limit if x < -limit else limit if x > limit else x
        # the trimmed bank (propeller torque, asymmetric thrust) is "wings level"
        phi_cmd += trim_phi
    phi_cmd *= 1.0 - 0.5 * protect

    # longitudinal: altitude -> climb rate -> pitch
    hdot = -v_down
    speed_err = airspeed_target_mps - airspeed
    if pitch_direct:
        theta_cmd = theta_fixed
    else:
        climb = climb_rate_mps
        x = k_alt * (alt_target_m - alt)
        hdot_cmd = -climb if x < -climb else climb if x > climb else x
        hdot_err = hdot_cmd - hdot
        x = hdot_cmd / v
        gamma_ff = math.asin(-0.5 if x < -0.5 else 0.5 if x > 0.5 else x)
        theta_unsat = trim_theta + gamma_ff + k_hdot * hdot_err + integrators[0]
        # speed guard: give up climb (or descent) rather than stall (or overspeed)
        under = max(0.0, speed_err - speed_guard)
        over = max(0.0, -speed_err - 2.0 * speed_guard)
        theta_unsat += k_speed_guard * (over - under)
        lo, hi = pitch_min, pitch_max
        theta_cmd = lo if theta_unsat < lo else hi if theta_unsat > hi else theta_unsat
        if protect == 0.0 and (
            theta_cmd == theta_unsat or (theta_cmd > theta_unsat) == (hdot_err > 0.0)
        ):
            integrators[0] += ki_hdot * hdot_err * dt

    # dynamic-pressure scheduling of the surface gains
    x = trim_qbar / (1.0 if 1.0 > qbar else qbar)  # / max(qbar, 1.0)
    sched = 0.5 if x < 0.5 else 2.0 if x > 2.0 else x

    # roll: PI on bank error with roll-rate damping
    phi_err = (phi_cmd - phi + _PI) % _TWO_PI - _PI  # _wrap
    aileron_unsat = trim_ail + sched * (k_phi * phi_err - k_p * p) + integrators[1]
    aileron = -1.0 if aileron_unsat < -1.0 else 1.0 if aileron_unsat > 1.0 else aileron_unsat
    if aileron == aileron_unsat:
        integrators[1] += sched * ki_phi * phi_err * dt

    # pitch: rate command with coordinated-turn feed-forward, PI to elevator
    sin_phi = math.sin(phi)
    phi_c = -1.2 if phi < -1.2 else 1.2 if phi > 1.2 else phi
    q_turn = G0_MPS2 / v * sin_phi * math.tan(phi_c)
    theta_err = theta_cmd - theta
    x = k_theta * theta_err
    q_cmd = (-max_q if x < -max_q else max_q if x > max_q else x) + q_turn
    if not pitch_direct and alpha_margin < 0.0:
        q_cmd = min(q_cmd, k_alpha * alpha_margin)
    pull = sched * k_q * (q_cmd - q) + integrators[2]
    elevator_unsat = trim_ele - pull
    elevator = -1.0 if elevator_unsat < -1.0 else 1.0 if elevator_unsat > 1.0 else elevator_unsat
    if elevator == elevator_unsat and (protect == 0.0 or theta_err < 0.0):
        integrators[2] += sched * ki_theta * theta_err * dt

    # yaw: sideslip PI and a yaw damper around the coordinated-turn yaw rate
    r_turn = G0_MPS2 / v * sin_phi * math.cos(theta)
    rudder_unsat = trim_rud - sched * (k_beta * beta - k_r * (r - r_turn)) + integrators[3]
    rudder = -1.0 if rudder_unsat < -1.0 else 1.0 if rudder_unsat > 1.0 else rudder_unsat
    if rudder == rudder_unsat:
        integrators[3] -= sched * ki_beta * beta * dt

    # speed: throttle PI around the trim throttle
    throttle_unsat = trim_thr + k_v * speed_err + integrators[4]
    throttle = 0.0 if throttle_unsat < 0.0 else 1.0 if throttle_unsat > 1.0 else throttle_unsat
    if throttle == throttle_unsat or (throttle > throttle_unsat) == (speed_err > 0.0):
        integrators[4] += ki_v * speed_err * dt

    return Controls(aileron, elevator, rudder, throttle)


_LawFn = Callable[
    [GuidanceInput, float | None, float, float, bool, float, float, float, float, list[float],
     tuple[float, ...]],
    Controls,
]
_compiled = kernel.bind_guidance(law_python, Controls, (G0_MPS2, _PI, _TWO_PI, _RAD_3))
#: The control loops of one step: :func:`law_python`, compiled when :data:`sim.kernel.KERNEL`
#: is ``"c"``.
law: _LawFn = law_python if _compiled is None else _compiled.law


class Guidance:
    """Flies ``plan`` leg by leg from a trimmed start.

    Parameters
    ----------
    plan : the flight plan.
    start_heading_rad : heading at the start; the "start" plan frame is rotated by it.
    start_alt_m, start_airspeed_mps : start altitude (MSL) and true airspeed; plan altitudes
        are relative to ``start_alt_m``.
    trim : controls, pitch and dynamic pressure at the trimmed start.
    gains : the law's gains and limits.
    """

    def __init__(
        self,
        plan: FlightPlan,
        start_heading_rad: float,
        start_alt_m: float,
        start_airspeed_mps: float,
        trim: TrimPoint,
        gains: GuidanceGains | None = None,
    ) -> None:
        self.plan = plan
        self.gains = gains or GuidanceGains()
        self._frame_rot = start_heading_rad if plan.frame == "start" else 0.0
        self._start_alt_m = start_alt_m
        self._trim = trim
        # current targets; legs that leave one out keep the previous value
        self.alt_target_m = start_alt_m
        self.airspeed_target_mps = start_airspeed_mps
        self.climb_rate_mps = self.gains.default_climb_rate_mps
        self._course_hold_rad = start_heading_rad
        # leg bookkeeping
        self.leg_index = 0
        self.lap = 0
        self.finished = False
        self._leg_started = False
        self._leg_t0 = 0.0
        self._leg_p0 = (0.0, 0.0)
        self._leg_course_prev = 0.0
        self._leg_turned = 0.0
        # loop integrators start at the trimmed controls / pitch
        #: climb-rate, roll, pitch, sideslip and speed integrators (law() updates them in place)
        self._integrators = [0.0, 0.0, 0.0, 0.0, 0.0]
        g, c = self.gains, trim.controls
        self._law_params: tuple[float, ...] = (
            g.k_course, g.k_alt, g.k_hdot, g.ki_hdot, g.pitch_min_rad, g.pitch_max_rad,
            g.alpha_max_rad, g.k_alpha, g.speed_guard_mps, g.k_speed_guard, g.k_phi, g.ki_phi,
            g.k_p, g.k_theta, g.max_q_rps, g.k_q, g.ki_theta, g.k_beta, g.ki_beta, g.k_r, g.k_v,
            g.ki_v, trim.phi_rad, trim.theta_rad, trim.qbar_pa, c.aileron, c.elevator,
            c.rudder, c.throttle,
        )  # fmt: skip

    # -- plan geometry ---------------------------------------------------------------------

    def _plan_to_ned(self, x_m: float, y_m: float) -> tuple[float, float]:
        c, s = math.cos(self._frame_rot), math.sin(self._frame_rot)
        return c * x_m - s * y_m, s * x_m + c * y_m

    def _leg(self) -> Leg | None:
        if self.finished:
            return None
        return self.plan.legs[self.leg_index]

    def _start_leg(self, leg: Leg, s: GuidanceInput, course: float) -> None:
        self._leg_started = True
        self._leg_t0 = s.time_s
        self._leg_p0 = (s.north_m, s.east_m)
        self._leg_course_prev = course
        self._leg_turned = 0.0
        if leg.alt_m is not None:
            self.alt_target_m = self._start_alt_m + leg.alt_m
        if leg.airspeed_mps is not None:
            self.airspeed_target_mps = leg.airspeed_mps
        if leg.climb_rate_mps is not None:
            self.climb_rate_mps = leg.climb_rate_mps

    def _next_leg(self, course: float) -> None:
        self._leg_started = False
        self._course_hold_rad = course
        self.leg_index += 1
        if self.leg_index >= len(self.plan.legs):
            if self.plan.repeat:
                self.leg_index = 0
                self.lap += 1
            else:
                self.finished = True
                self.leg_index = len(self.plan.legs) - 1

    def _course_error(self, leg: Leg | None, s: GuidanceInput, course: float) -> float | None:
        """Course error to fly (rad), or None when the leg commands bank directly.

        Advances to the next leg when the current one is complete.
        """
        if leg is None:
            return _wrap(self._course_hold_rad - course)
        if leg.kind == "heading":
            assert leg.heading_deg is not None and leg.duration_s is not None
            if s.time_s - self._leg_t0 >= leg.duration_s:
                self._next_leg(course)
            return _wrap(math.radians(leg.heading_deg) + self._frame_rot - course)
        if leg.kind == "attitude":
            assert leg.duration_s is not None
            if s.time_s - self._leg_t0 >= leg.duration_s:
                self._next_leg(course)
            return None
        if leg.kind == "turn":
            assert leg.turn_deg is not None
            self._leg_turned += _wrap(course - self._leg_course_prev)
            self._leg_course_prev = course
            remaining = math.radians(leg.turn_deg) - self._leg_turned
            if abs(remaining) < math.radians(1.0) or remaining * leg.turn_deg < 0.0:
                self._next_leg(course)
            return remaining
        # waypoint: follow the line from where the leg began to the target
        assert leg.x_m is not None and leg.y_m is not None
        tn, te = self._plan_to_ned(leg.x_m, leg.y_m)
        n0, e0 = self._leg_p0
        dn, de = tn - n0, te - e0
        length = math.hypot(dn, de)
        if length < 1.0:
            self._next_leg(course)
            return _wrap(self._course_hold_rad - course)
        un, ue = dn / length, de / length
        rn, re = s.north_m - n0, s.east_m - e0
        along = rn * un + re * ue
        cross = un * re - ue * rn  # > 0: right of the track
        if along >= length:
            self._next_leg(course)
        g = self.gains
        lookahead = max(g.min_lookahead_m, g.lookahead_s * max(s.airspeed_mps, 1.0))
        intercept = _clip(math.atan2(cross, lookahead), -g.max_intercept_rad, g.max_intercept_rad)
        return _wrap(math.atan2(ue, un) - intercept - course)

    # -- the law ---------------------------------------------------------------------------

    def update(self, s: GuidanceInput) -> Controls:
        """One control step: advance the plan, return the commands to apply now."""
        # Runs at every simulation step: the plan logic here, the loops in law() (compiled when
        # sim.kernel.KERNEL is "c").
        g = self.gains
        v_north, v_east, psi = s[5], s[6], s[11]
        ground_speed = math.hypot(v_north, v_east)
        course = math.atan2(v_east, v_north) if ground_speed > 1.0 else psi

        leg = self._leg()
        if leg is not None and not self._leg_started:
            self._start_leg(leg, s, course)
        course_err = self._course_error(leg, s, course)
        leg = self._leg()  # may have advanced; the new leg starts on the next step
        if leg is not None and not self._leg_started:
            self._start_leg(leg, s, course)

        if course_err is None:
            assert leg is not None
            phi_fixed, limit = math.radians(leg.bank_deg or 0.0), 0.0
        else:
            phi_fixed, limit = 0.0, g.default_bank_limit_rad
            if leg is not None and leg.bank_deg is not None:
                limit = math.radians(abs(leg.bank_deg))
            elif leg is not None and leg.kind == "turn":
                limit = g.default_turn_bank_rad
        pitch_direct = leg is not None and leg.kind == "attitude" and leg.pitch_deg is not None
        theta_fixed = 0.0
        if pitch_direct:
            assert leg is not None and leg.pitch_deg is not None
            theta_fixed = math.radians(leg.pitch_deg)
        return law(s, course_err, phi_fixed, limit, pitch_direct, theta_fixed,
                   self.alt_target_m, self.airspeed_target_mps, self.climb_rate_mps,
                   self._integrators, self._law_params)
