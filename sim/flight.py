"""JSBSim flight adapter: loads an aircraft, starts it trimmed in the air (or at rest on a
runway), flies a plan, and returns truth in SI.

This is the only module that knows JSBSim's units (feet, slugs, lbf, psf, Rankine); every
property is converted once, here.

What the truth fields are, and why (checked against JSBSim 1.3.3's source and by the
kinematic-consistency test in ``tests/sim/test_flight.py``):

* Position: ``position/lat-geod-rad``, ``position/long-gc-rad`` (WGS-84 geodetic) and
  ``position/h-sl-meters``. JSBSim's "sea level" *is* the WGS-84 ellipsoid (it has no geoid),
  so ``alt_msl_m`` is the ellipsoidal height; hilnav treats it as MSL.
* Velocity: ``velocities/v-{north,east,down}-fps``, Earth-relative, in JSBSim's local frame,
  which in 1.3.3 is the geodetic NED frame (verified: level flight due north gives
  ``v_down`` = ``-h_dot`` to 1e-3 m/s, not the 0.17 m/s a geocentric frame would give).
* Attitude: ``attitude/{phi,theta,psi}-rad`` (3-2-1 Euler, body w.r.t. that NED frame) turned
  into the Hamilton scalar-first quaternion ``q_nb`` (body FRD -> NED).
* Body rates: ``velocities/{p,q,r}i-rad_sec``, the rate w.r.t. *inertial* space (what a gyro
  measures), not ``velocities/{p,q,r}-rad_sec`` (w.r.t. the Earth).
* Specific force: ``forces/fb{x,y,z}-total-lbs / inertia/mass-slugs``, i.e. the sum of all
  non-gravitational forces (aero, propulsion, ground, external) over mass, body FRD, at the
  CG. JSBSim 1.3.3 runs Propagate *first* in ``FGFDMExec::Run`` and the force models after it,
  so after ``run()`` these forces belong to the state just propagated: the same instant as the
  position, velocity and attitude read with them (the kinematic test finds residuals of
  ~1e-4 m/s^2 RMS, 4e-3 m/s^2 at most, this way; pairing them with the state before the step
  gives ~4e-3 m/s^2 RMS). ``accelerations/N{x,y,z}`` is
  computed by FGAuxiliary *before* the forces of the frame and lags one step;
  ``accelerations/a-pilot-*`` is at the pilot's eye point. Neither is used.
* Atmosphere: ``atmosphere/P-psf`` and ``atmosphere/T-R`` (static, at the aircraft);
  airspeeds ``velocities/vtrue-fps`` (true) and ``velocities/vc-fps`` (calibrated, reported
  as ``indicated_airspeed_mps``); ``aero/alpha-rad`` and ``aero/beta-rad`` (angle of attack
  and sideslip of the air-relative velocity, winds and turbulence included) as ``alpha_rad``
  and ``beta_rad``.

All of a truth sample is instantaneous at ``time_us``. JSBSim integrates the velocity with
Adams-Bashforth 2 and the attitude with a rectangular (Euler) step using the body rate at the
start of the step; a strapdown fed with these samples reproduces JSBSim's trajectory best when
it integrates the same way (the differences telescope and do not accumulate).

Gravity inside JSBSim is its WGS-84 J2 gravitation plus the centrifugal term (the test file
has the exact formula), not the Somigliana normal gravity; the two differ by ~1e-5 m/s^2.

Start: the aircraft is placed in the air at the requested state, the gear is retracted, every
engine gets full mixture and is started (``propulsion/set-running = -1``), and JSBSim's full
trim (``do_trim(1)``) is run. JSBSim 1.3.3's trim does not refresh FCS-driven propulsion
inputs in its engine steady-state search (JSBSim issue #1440), which makes it fail for
aircraft such as the c310 unless the throttle is already near its trimmed value; when the
first trim fails the adapter therefore flies the start condition with the guidance law for up
to two minutes, puts the aircraft back at the requested state with the settled controls, and
trims again. Only if that fails too does it raise ``ValueError``.

Start on the ground (``StartState.kind = "ground"``, for an autopilot that takes off itself):
JSBSim's terrain is raised to the runway elevation (``ic/terrain-elevation-ft``), the aircraft
is placed at rest just above it on ``heading_deg`` with its gear down, every engine is started
with full mixture and idle throttle, JSBSim's ground trim (``do_trim(2)``) sets it on its gear,
and it then stands for ``GROUND_SETTLE_S`` with the brakes set, before the flight's time 0,
while the engine's start-up transient decays to idle and the struts settle; the brakes are
then released. Measured (c172x, 200 Hz): at idle it stays put (no drift in 30 s), pitch
+0.38 deg and roll +0.29 deg on its gear, specific force (0, 0, -9.80) m/s^2, engine ~750 rpm.
The nose wheel is steered with the rudder (``fcs/steer-cmd-norm`` = the yaw command, + = nose
right, as the C172's pedals do; see :mod:`sim.aircraft` for the generic Autopilot system that
would otherwise hold it at 0). On the ground the flight ends only if the simulation diverges
or control is lost (bank > 100 deg, pitch > 70 deg); touching the ground and low airspeed are
normal there, and a stall counts only once airborne.

Turbulence: ``FlightConfig.turbulence`` in [0, 1] drives JSBSim's MIL-F-8785C (Dryden,
``atmosphere/turb-type = 3``) model: probability-of-exceedance index ``ceil(7 t)`` (about
0.43 light, 0.57 moderate, 0.86 severe) above 2000 ft AGL, and a 20-ft wind of ``52.5 t``
knots for the low-altitude model below 1000 ft; JSBSim blends the two in between. JSBSim's
random generator is seeded with ``FlightConfig.seed`` (``simulation/randomseed``), so the
same configuration gives bit-identical truth.

Vehicle state (:meth:`Flight.vehicle_state`, what a flight controller would report in
HIL_ACTUATOR_CONTROLS and RAW_RPM): JSBSim's pilot commands plus their trims, converted to
PX4's order and signs. Measured (jsbsim 1.3.3, c172x, c310 and J3Cub trimmed at their
suggested start, +0.2 on one command for 0.5 s): ``fcs/aileron-cmd-norm`` > 0 rolls right
(p > 0, PX4's sign), ``fcs/elevator-cmd-norm`` > 0 pitches the nose down (q < 0; trailing
edge down) and ``fcs/rudder-cmd-norm`` > 0 yaws the nose left (r < 0), so PX4 roll =
aileron, pitch = -elevator, yaw = -rudder. JSBSim's trim (``do_trim``) sets the pitch through
``fcs/pitch-trim-cmd-norm`` and leaves ``fcs/elevator-cmd-norm`` at 0 on most aircraft, and the
aircraft's FCS adds the two (and clips the sum to [-1, 1]), so each reported surface is the
clipped sum of command and trim (``fcs/{roll,pitch,yaw}-trim-cmd-norm``). Throttle is
``fcs/throttle-cmd-norm[0]`` (the guidance law drives every engine with the same value),
flaps ``fcs/flap-cmd-norm`` (0 = retracted, never moved by the guidance law). Propeller speed is
``propulsion/engine[i]/propeller-rpm`` of each engine that has a propeller (piston aircraft
and the DHC6, Boeing314, Short_S23 of the verified list); jets and the turboprops that the
wheel models with direct thrust (OV10, t6texan2) have none and report no rpm.

The flight's configuration (start state, wind profiles, turbulence, who flies) is
:mod:`sim.flight_config`; the aircraft offered and their I/O-free loading, :mod:`sim.aircraft`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from types import TracebackType
from typing import Any

import jsbsim
import numpy as np

from physconst import WGS84_A_M
from sim.aircraft import available_aircraft, jsbsim_log_discarded, load_without_io, suggested_start
from sim.flight_config import FlightConfig, StartState
from sim.guidance import Controls, Guidance, GuidanceInput, TrimPoint
from sim.plans import FlightPlan, Leg
from sim.samples import Truth
from sim.vehicle_state import CONTROL_INDEX, N_CONTROLS, VehicleState, control_range

# --- unit conversions (exact definitions) ---------------------------------------------------
FT_M = 0.3048
LBF_N = 4.4482216152605
SLUG_KG = LBF_N / FT_M  # 1 lbf / (1 ft/s^2)
PSF_PA = LBF_N / FT_M**2
RANKINE_K = 5.0 / 9.0
KT_MPS = 1852.0 / 3600.0

# WGS-84 ellipsoid, for the local north/east offsets the guidance law uses. e² is the
# published rounded value (NIMA TR8350.2, table 3.3), 2e-13 from physconst's exact F(2 - F);
# the guidance law steers by these offsets, so a seed's trajectory depends on this value.
_A_M = WGS84_A_M
_E2 = 6.69437999014e-3

__all__ = [
    "FT_M",
    "KT_MPS",
    "LBF_N",
    "PSF_PA",
    "RANKINE_K",
    "SLUG_KG",
    "Flight",
    "FlightConfig",
    "FlightEnded",
    "StartState",
    "available_aircraft",
    "suggested_start",
]


_STALL_PERSIST_S = 0.5

GROUND_SETTLE_S = 10.0
"""Seconds a ground start stands braked before time 0 (engine to idle, struts settled)."""
_GROUND_IC_AGL_FT = 5.0  # a first guess above the runway; the ground trim sets the height
_BRAKES = ("fcs/left-brake-cmd-norm", "fcs/right-brake-cmd-norm", "fcs/center-brake-cmd-norm")

# Properties read after every step, in this order (JSBSim units).
_READ = (
    "position/lat-geod-rad",
    "position/long-gc-rad",
    "position/h-sl-meters",
    "position/h-agl-ft",
    "velocities/v-north-fps",
    "velocities/v-east-fps",
    "velocities/v-down-fps",
    "attitude/phi-rad",
    "attitude/theta-rad",
    "attitude/psi-rad",
    "velocities/pi-rad_sec",
    "velocities/qi-rad_sec",
    "velocities/ri-rad_sec",
    "velocities/p-rad_sec",
    "velocities/q-rad_sec",
    "velocities/r-rad_sec",
    "forces/fbx-total-lbs",
    "forces/fby-total-lbs",
    "forces/fbz-total-lbs",
    "inertia/mass-slugs",
    "atmosphere/P-psf",
    "atmosphere/T-R",
    "velocities/vtrue-fps",
    "velocities/vc-fps",
    "aero/alpha-rad",
    "aero/beta-rad",
    "aero/qbar-psf",
    "gear/wow",
    "atmosphere/total-wind-north-fps",
    "atmosphere/total-wind-east-fps",
    "atmosphere/total-wind-down-fps",
)
(
    _ILAT, _ILON, _IH, _IHAGL, _IVN, _IVE, _IVD, _IPHI, _ITHETA, _IPSI,
    _IPI, _IQI, _IRI, _IP, _IQ, _IR, _IFX, _IFY, _IFZ, _IMASS,
    _IPS, _ITR, _IVT, _IVC, _IALPHA, _IBETA, _IQBAR, _IWOW, _IWN, _IWE, _IWD,
) = range(len(_READ))  # fmt: skip


class FlightEnded(RuntimeError):
    """The aircraft stalled, hit the ground or departed controlled flight.

    Attributes
    ----------
    reason : what happened, one line.
    time_s : simulated time at which it happened.
    """

    def __init__(self, reason: str, time_s: float) -> None:
        super().__init__(f"flight ended at t = {time_s:.2f} s: {reason}")
        self.reason = reason
        self.time_s = time_s


def _radii_at(lat_rad: float) -> tuple[float, float, float]:
    """Prime-vertical and meridian radii of curvature (m) and the cosine at ``lat_rad``: the
    constants of the guidance law's local north/east offsets (computed once per flight)."""
    sin_lat = math.sin(lat_rad)
    den = 1.0 - _E2 * sin_lat * sin_lat
    r_n = _A_M / math.sqrt(den)
    r_m = r_n * (1.0 - _E2) / den
    return r_n, r_m, math.cos(lat_rad)


def _clip1(x: float) -> float:
    """``x`` clipped to [-1, 1] (what an FCS summer with ``clipto -1 1`` does)."""
    return -1.0 if x < -1.0 else 1.0 if x > 1.0 else x


def _euler_to_quat(phi: float, theta: float, psi: float) -> np.ndarray:
    """3-2-1 Euler angles (rad) -> Hamilton scalar-first quaternion body -> NED, w >= 0."""
    cr, sr = math.cos(0.5 * phi), math.sin(0.5 * phi)
    cp, sp = math.cos(0.5 * theta), math.sin(0.5 * theta)
    cy, sy = math.cos(0.5 * psi), math.sin(0.5 * psi)
    w = cr * cp * cy + sr * sp * sy
    x = sr * cp * cy - cr * sp * sy
    y = cr * sp * cy + sr * cp * sy
    z = cr * cp * sy - sr * sp * cy
    if w < 0.0:
        return np.array((-w, -x, -y, -z))
    return np.array((w, x, y, z))


class _Props:
    """Cached JSBSim property nodes (name lookups once, then direct reads)."""

    def __init__(self, fdm: Any) -> None:
        self._pm = fdm.get_property_manager()

    def node(self, name: str) -> Any:
        node = self._pm.get_node(name)
        if node is None:
            raise KeyError(f"JSBSim property {name!r} does not exist")
        return node


class Flight:
    """One JSBSim flight of ``plan`` under ``config``; steps at ``config.rate_hz``.

    Construction loads the aircraft, sets the start state, starts the engines, trims and
    engages the guidance law. Use as a context manager or call :meth:`close`.

    Raises
    ------
    ValueError
        Unknown aircraft (the message lists the valid ones) or a start state the aircraft
        cannot be trimmed at.
    """

    def __init__(self, config: FlightConfig, plan: FlightPlan) -> None:
        valid = available_aircraft()
        if config.aircraft not in valid:
            raise ValueError(
                f"unknown aircraft {config.aircraft!r}: valid aircraft are {', '.join(valid)}"
            )
        if config.start.on_ground and config.control == "guidance":
            raise ValueError(
                "a ground start needs an autopilot to take off: hilnav's guidance law flies "
                "from an in-air trim only (start kind 'air')"
            )
        self.config = config
        self._on_ground_start = config.start.on_ground
        self.plan = plan
        self._wind_profile = config.wind_varies_with_altitude
        self._dt = 1.0 / config.rate_hz
        self._step = 0
        self._ended: FlightEnded | None = None
        self._stall_s = 0.0
        self._guided = config.control == "guidance"
        # JSBSim prints a banner from the FGFDMExec constructor unless the (process-wide)
        # debug level is 0 before construction.
        jsbsim.FGJSBBase().debug_lvl = 0
        self._fdm: Any = jsbsim.FGFDMExec(None)
        self._fdm.set_debug_level(0)
        load_without_io(self._fdm, config.aircraft)
        self._fdm.set_dt(self._dt)
        self._fdm["simulation/randomseed"] = config.seed
        self._bind()
        self._origin = (math.radians(config.start.lat_deg), math.radians(config.start.lon_deg))
        self._origin_radii = _radii_at(self._origin[0])
        try:
            trim = self._start()
        except jsbsim.BaseError as error:
            where = "on the ground" if self._on_ground_start else "in the air"
            raise ValueError(
                f"JSBSim could not initialise {config.aircraft!r} {where}: {error}"
            ) from None
        # turbulence after the trim: random gusts would upset the trim's equilibrium search
        self._set_wind()
        self._set_turbulence()
        start = config.start
        self._guidance = Guidance(
            plan,
            start_heading_rad=math.radians(start.heading_deg),
            start_alt_m=start.alt_msl_m,
            start_airspeed_mps=start.airspeed_mps,
            trim=trim,
            gains=config.guidance,
        )
        self._truth = self._read_truth()

    # -- setup -----------------------------------------------------------------------------

    def _bind(self) -> None:
        p = _Props(self._fdm)
        n = p.node
        self._getters = [n(name).get_double_value for name in _READ]
        self._raw: list[float] = self._sample()
        self._n_ail = n("fcs/aileron-cmd-norm")
        self._n_ele = n("fcs/elevator-cmd-norm")
        self._n_rud = n("fcs/rudder-cmd-norm")
        self._n_steer = n("fcs/steer-cmd-norm")
        pm = self._fdm.get_property_manager()
        count = 0
        while pm.hasNode(f"propulsion/engine[{count}]"):
            count += 1
        self._n_thr = [n(f"fcs/throttle-cmd-norm[{i}]") for i in range(count)]
        self._n_mix = [n(f"fcs/mixture-cmd-norm[{i}]") for i in range(count)]
        # vehicle state (see the module docstring): trims, flaps, propeller speeds
        trims = ("fcs/roll-trim-cmd-norm", "fcs/pitch-trim-cmd-norm", "fcs/yaw-trim-cmd-norm")
        self._n_trim = [n(name) for name in trims]
        self._n_flap = n("fcs/flap-cmd-norm") if pm.hasNode("fcs/flap-cmd-norm") else None
        self._n_rpm = [
            n(f"propulsion/engine[{i}]/propeller-rpm")
            for i in range(count)
            if pm.hasNode(f"propulsion/engine[{i}]/propeller-rpm")
        ]
        self._n_wind = [n(f"atmosphere/wind-{axis}-fps") for axis in ("north", "east", "down")]

    def _sample(self) -> list[float]:
        """Read every property the adapter uses, once (indices: the _I* constants)."""
        return [get() for get in self._getters]

    def _start_wind(self) -> tuple[float, float, float]:
        """The steady wind at the start altitude (in the air JSBSim's terrain is at sea level:
        AGL = MSL at the start; on the ground the start is 0 m above it)."""
        start = self.config.start
        alt = start.alt_msl_m
        return self.config.wind_at(alt, alt - start.terrain_alt_msl_m)

    def _set_wind_ic(self, wind_ne_mps: tuple[float, float]) -> None:
        # run_ic() and the trim re-initialise the atmosphere's wind from the initial condition
        # (a wind set on atmosphere/ before them silently vanished), so the horizontal wind
        # goes into the IC: JSBSim's ic/vw-dir-deg is the direction the wind comes FROM. The
        # trim then finds the equilibrium in the moving air mass.
        wn, we = wind_ne_mps
        fdm = self._fdm
        fdm["ic/vw-mag-fps"] = math.hypot(wn, we) / FT_M
        fdm["ic/vw-dir-deg"] = math.degrees(math.atan2(-we, -wn)) % 360.0

    def _set_wind(self) -> None:
        # the whole vector once the trim is done (the IC has no settable vertical wind)
        self._write_wind(self._start_wind())

    def _write_wind(self, wind_ned_mps: tuple[float, float, float]) -> None:
        for node, w in zip(self._n_wind, wind_ned_mps, strict=True):
            node.set_double_value(w / FT_M)

    def _set_turbulence(self) -> None:
        fdm = self._fdm
        t = self.config.turbulence
        if t > 0.0:
            fdm["atmosphere/turb-type"] = 3  # MIL-F-8785C (Dryden)
            fdm["atmosphere/turbulence/milspec/severity"] = min(7, math.ceil(7.0 * t))
            fdm["atmosphere/turbulence/milspec/windspeed_at_20ft_AGL-fps"] = (
                52.5 * t * KT_MPS / FT_M
            )
        else:
            fdm["atmosphere/turb-type"] = 0

    def _apply_ic(
        self, alpha_rad: float | None = None, wind_ne_mps: tuple[float, float] = (0.0, 0.0)
    ) -> None:
        fdm = self._fdm
        s = self.config.start
        fdm["ic/lat-geod-deg"] = s.lat_deg
        fdm["ic/long-gc-deg"] = s.lon_deg
        fdm["ic/h-sl-ft"] = s.alt_msl_m / FT_M
        fdm["ic/psi-true-deg"] = s.heading_deg % 360.0
        fdm["ic/phi-deg"] = 0.0
        fdm["ic/gamma-deg"] = 0.0
        fdm["ic/vt-fps"] = s.airspeed_mps / FT_M
        if alpha_rad is not None:
            fdm["ic/alpha-rad"] = alpha_rad
        fdm["gear/gear-cmd-norm"] = 0.0  # airborne start: gear up where it retracts
        self._set_wind_ic(wind_ne_mps)
        with jsbsim_log_discarded():
            fdm.run_ic()

    def _start(self) -> TrimPoint:
        """Trim at the start; return the trim point the guidance law flies from.

        The guidance law's trim point is the equilibrium in the air mass without sideslip.
        A steady wind moves the air mass uniformly and does not change that equilibrium, but
        JSBSim's full trim in a crosswind is a different one: its ``hmgt`` axis makes the
        heading equal the ground track, so the aircraft is trimmed in a wing-low sideslip
        (c172x at 1000 m, 50 m/s, wind 5,-3,0: 2.8 deg of sideslip, 2.0 deg of bank). The
        law's sideslip loop removes that sideslip within seconds (the aircraft crabs), so
        that bank is not "wings level" in flight; taken as such, it biased every bank command
        by 1.8 deg, which the proportional course loop balanced with a standing course error
        of 1.4 deg, and a 180-degree turn never came within its 1-degree completion tolerance.
        So in a horizontal wind the aircraft is first trimmed without wind (the trim point
        returned), then, for the start state, in the wind. Without wind: one trim, as always.
        A ground start stands on the runway instead (:meth:`_start_on_ground`).
        """
        if self._on_ground_start:
            return self._start_on_ground()
        wn, we, _ = self._start_wind()
        if (wn, we) == (0.0, 0.0):
            return self._trim_in((0.0, 0.0))
        air_mass_trim = self._trim_in((0.0, 0.0))
        self._carry_into_wind(wn, we)
        return air_mass_trim

    def _carry_into_wind(self, wn_mps: float, we_mps: float) -> None:
        """Re-initialise the trimmed (windless) state moving with a horizontal wind: same
        attitude and air-relative velocity, ground velocity plus the wind.

        The wind itself is written to JSBSim's atmosphere afterwards (``_set_wind``, before
        the first step): the IC carries none, because JSBSim 1.3.3's ``FGFDMExec::Initialize``
        sets the atmosphere's wind to ``GetWindNEDFpsIC()``, which is ``v_air - v_ground``,
        the negative of the wind the IC's kinematics encode (measured: an IC wind "from" 270
        deg gave an atmosphere wind towards the west before the first step).
        """
        raw = self._raw
        fdm = self._fdm
        fdm["ic/vw-mag-fps"] = 0.0
        fdm["ic/phi-rad"] = raw[_IPHI]
        fdm["ic/theta-rad"] = raw[_ITHETA]
        fdm["ic/psi-true-rad"] = raw[_IPSI]
        fdm["ic/vn-fps"] = raw[_IVN] + wn_mps / FT_M
        fdm["ic/ve-fps"] = raw[_IVE] + we_mps / FT_M
        fdm["ic/vd-fps"] = raw[_IVD]
        with jsbsim_log_discarded():
            fdm.run_ic()
        self._start_engines()
        self._raw = self._sample()

    def _trim_in(self, wind_ne_mps: tuple[float, float]) -> TrimPoint:
        """Set the start state in this horizontal wind, start the engines and trim."""
        self._apply_ic(wind_ne_mps=wind_ne_mps)
        self._start_engines()
        if not self._try_trim():
            # JSBSim issue #1440: settle the engines and controls in flight, then retrim.
            # A failed trim re-initialises JSBSim with the engines off: start them again.
            self._start_engines()
            alpha = self._settle()
            self._apply_ic(alpha_rad=alpha, wind_ne_mps=wind_ne_mps)
            if not self._try_trim():
                s = self.config.start
                raise ValueError(
                    f"JSBSim cannot trim {self.config.aircraft} in level flight at "
                    f"{s.alt_msl_m:.0f} m, {s.airspeed_mps:.1f} m/s true airspeed; "
                    "try another start.airspeed_mps or start.alt_msl_m"
                )
        raw = self._raw = self._sample()
        return TrimPoint(
            controls=self._controls_now(),
            theta_rad=raw[_ITHETA],
            qbar_pa=raw[_IQBAR] * PSF_PA,
            phi_rad=raw[_IPHI],
        )

    def _start_on_ground(self) -> TrimPoint:
        """At rest on the runway, engines idling, brakes released (see the module docstring);
        the returned point holds the idle controls and the attitude on the gear."""
        fdm = self._fdm
        s = self.config.start
        fdm["ic/lat-geod-deg"] = s.lat_deg
        fdm["ic/long-gc-deg"] = s.lon_deg
        fdm["ic/terrain-elevation-ft"] = s.alt_msl_m / FT_M
        fdm["ic/h-agl-ft"] = _GROUND_IC_AGL_FT
        fdm["ic/psi-true-deg"] = s.heading_deg % 360.0
        fdm["ic/phi-deg"] = 0.0
        fdm["ic/theta-deg"] = 0.0
        for axis in ("u", "v", "w"):
            fdm[f"ic/{axis}-fps"] = 0.0
        fdm["ic/vw-mag-fps"] = 0.0
        fdm["gear/gear-cmd-norm"] = 1.0
        with jsbsim_log_discarded():
            fdm.run_ic()
        self._start_engines()
        for node in self._n_thr:
            node.set_double_value(0.0)
        try:
            with jsbsim_log_discarded():
                fdm.do_trim(2)  # JSBSim's ground trim: height, pitch and roll on the gear
        except jsbsim.TrimFailureError:
            raise ValueError(
                f"JSBSim cannot set {self.config.aircraft} on its gear at {s.alt_msl_m:.0f} m"
            ) from None
        for name in _BRAKES:
            fdm[name] = 1.0
        for _ in range(round(GROUND_SETTLE_S / self._dt)):
            fdm.run()
        for name in _BRAKES:
            fdm[name] = 0.0
        raw = self._raw = self._sample()
        if not all(math.isfinite(x) for x in raw):
            raise ValueError(f"JSBSim diverged with {self.config.aircraft} on the runway")
        return TrimPoint(
            controls=self._controls_now(),
            theta_rad=raw[_ITHETA],
            qbar_pa=raw[_IQBAR] * PSF_PA,
            phi_rad=raw[_IPHI],
        )

    def _start_engines(self) -> None:
        for node in self._n_mix:
            node.set_double_value(1.0)
        self._fdm["propulsion/set-running"] = -1

    def _try_trim(self) -> bool:
        try:
            with jsbsim_log_discarded():
                self._fdm.do_trim(1)
        except jsbsim.TrimFailureError:
            return False
        return all(math.isfinite(x) for x in self._sample())

    def _controls_now(self) -> Controls:
        return Controls(
            aileron=self._n_ail.get_double_value(),
            elevator=self._n_ele.get_double_value(),
            rudder=self._n_rud.get_double_value(),
            throttle=self._n_thr[0].get_double_value() if self._n_thr else 0.0,
        )

    def _settle(self, max_s: float = 120.0) -> float:
        """Fly the start condition untrimmed for ``max_s``; return the final angle of attack."""
        s = self.config.start
        hold = FlightPlan(
            name="settle", legs=(Leg(kind="heading", heading_deg=0.0, duration_s=max_s),)
        )
        guess = Controls(aileron=0.0, elevator=0.0, rudder=0.0, throttle=0.6)
        self._write_controls(guess)
        raw = self._raw = self._sample()
        trim = TrimPoint(controls=guess, theta_rad=raw[_ITHETA], qbar_pa=raw[_IQBAR] * PSF_PA)
        law = Guidance(
            hold,
            math.radians(s.heading_deg),
            s.alt_msl_m,
            s.airspeed_mps,
            trim,
            self.config.guidance,
        )
        for k in range(int(max_s / self._dt)):
            self._write_controls(law.update(self._guidance_input(k * self._dt)))
            self._fdm.run()
            self._raw = self._sample()
            if not math.isfinite(self._raw[_IH]):
                break
        return self._raw[_IALPHA]

    # -- stepping --------------------------------------------------------------------------

    @property
    def dt_s(self) -> float:
        """Step length, s."""
        return self._dt

    @property
    def time_us(self) -> int:
        """Simulated time of the current truth, microseconds since the start."""
        return round(self._step * 1e6 / self.config.rate_hz)

    @property
    def time_s(self) -> float:
        """Simulated time of the current truth, s."""
        return self._step * self._dt

    @property
    def guidance(self) -> Guidance:
        """The guidance law flying the plan (leg index, lap, current targets)."""
        return self._guidance

    def truth(self) -> Truth:
        """Truth of the current state."""
        return self._truth

    def vehicle_state(self) -> VehicleState:
        """The controls JSBSim flies with now, in PX4 HIL_ACTUATOR_CONTROLS order and signs,
        and the propeller speeds (see the module docstring for the properties and signs)."""
        roll_trim, pitch_trim, yaw_trim = (node.get_double_value() for node in self._n_trim)
        controls = [0.0] * N_CONTROLS
        controls[0] = _clip1(self._n_ail.get_double_value() + roll_trim)
        controls[1] = -_clip1(self._n_ele.get_double_value() + pitch_trim)
        controls[2] = -_clip1(self._n_rud.get_double_value() + yaw_trim)
        controls[3] = self._n_thr[0].get_double_value() if self._n_thr else 0.0
        controls[4] = self._n_flap.get_double_value() if self._n_flap is not None else 0.0
        return VehicleState(
            controls=tuple(controls),
            propeller_rpm=tuple(node.get_double_value() for node in self._n_rpm),
        )

    def command(self, controls: Sequence[float]) -> int:
        """Fly with ``controls`` from the next step on (``control="external"`` only).

        ``controls`` is a control vector in PX4's HIL_ACTUATOR_CONTROLS order and signs, the
        inverse of :meth:`vehicle_state` (0 roll, + = right wing down; 1 pitch, + = nose up;
        2 yaw, + = nose right; 3 throttle 0..1, every engine; 4 flaps 0..1); up to
        :data:`~sim.vehicle_state.N_CONTROLS` values, missing ones hold. Each surface command
        is written so that command + the trim JSBSim set equals the given value. A value
        outside its range (:func:`~sim.vehicle_state.control_range`) is clipped; a non-finite
        value leaves that control as it was. Returns how many values were clipped or
        ignored (the caller counts them).

        Raises
        ------
        RuntimeError
            The flight is guided by its own law (``control="guidance"``).
        """
        if self._guided:
            raise RuntimeError("Flight.command needs FlightConfig.control = 'external'")
        if len(controls) > N_CONTROLS:
            raise ValueError(f"at most {N_CONTROLS} controls, got {len(controls)}")
        bad = 0
        values: list[float | None] = [None] * N_CONTROLS
        for i, value in enumerate(controls):
            x = float(value)
            if not math.isfinite(x):
                bad += 1
                continue
            low, high = control_range(i)
            if x < low or x > high:
                bad += 1
                x = min(max(x, low), high)
            values[i] = x
        roll_trim, pitch_trim, yaw_trim = (node.get_double_value() for node in self._n_trim)
        roll, pitch, yaw = (values[CONTROL_INDEX[k]] for k in ("roll", "pitch", "yaw"))
        if roll is not None:
            self._n_ail.set_double_value(roll - roll_trim)
        if pitch is not None:
            self._n_ele.set_double_value(-pitch - pitch_trim)
        if yaw is not None:
            self._n_rud.set_double_value(-yaw - yaw_trim)
            self._n_steer.set_double_value(_clip1(yaw))  # the nose wheel follows the pedals
        throttle = values[CONTROL_INDEX["throttle"]]
        if throttle is not None:
            for node in self._n_thr:
                node.set_double_value(throttle)
        flaps = values[CONTROL_INDEX["flaps"]]
        if flaps is not None and self._n_flap is not None:
            self._n_flap.set_double_value(max(flaps, 0.0))
        return bad

    def step(self) -> Truth:
        """Advance one step of ``1 / rate_hz`` and return the new truth.

        Raises
        ------
        FlightEnded
            The aircraft stalled, hit the ground, departed controlled flight or the
            simulation diverged (also on every later call).
        """
        self._advance()
        self._truth = self._read_truth()
        return self._truth

    def run_for(self, duration_s: float) -> Truth:
        """Step for ``duration_s`` of simulated time (whole steps) and return the last truth.

        Faster than calling :meth:`step` in a loop: intermediate truth is not assembled.
        Raises :class:`FlightEnded` like :meth:`step`.
        """
        for _ in range(round(duration_s * self.config.rate_hz)):
            self._advance()
        self._truth = self._read_truth()
        return self._truth

    def _advance(self) -> None:
        if self._ended is not None:
            raise self._ended
        if self._fdm is None:
            raise RuntimeError("the flight is closed")
        if self._guided:
            self._write_controls(self._guidance.update(self._guidance_input(self.time_s)))
        self._fdm.run()
        self._step += 1
        raw = self._raw = self._sample()
        self._check()
        if self._wind_profile:
            self._write_wind(self.config.wind_at(raw[_IH], raw[_IHAGL] * FT_M))

    def close(self) -> None:
        """Release the JSBSim instance."""
        self._fdm = None

    def __enter__(self) -> Flight:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()

    # -- internals -------------------------------------------------------------------------

    def _write_controls(self, c: Controls) -> None:
        self._n_ail.set_double_value(c.aileron)
        self._n_ele.set_double_value(c.elevator)
        self._n_rud.set_double_value(c.rudder)
        for node in self._n_thr:
            node.set_double_value(c.throttle)

    def _guidance_input(self, time_s: float) -> GuidanceInput:
        raw = self._raw
        lat, h = raw[_ILAT], raw[_IH]
        lat0, lon0 = self._origin
        r_n, r_m, cos_lat0 = self._origin_radii
        dlon = (raw[_ILON] - lon0 + math.pi) % (2.0 * math.pi) - math.pi
        # positional, in GuidanceInput's field order (keywords cost ~1 us at every step)
        return GuidanceInput(
            time_s,
            self._dt,
            (lat - lat0) * (r_m + h),  # north_m
            dlon * (r_n + h) * cos_lat0,  # east_m
            h,
            raw[_IVN] * FT_M,
            raw[_IVE] * FT_M,
            raw[_IVD] * FT_M,
            raw[_IVT] * FT_M,  # airspeed_mps
            raw[_IPHI],
            raw[_ITHETA],
            raw[_IPSI],
            raw[_IP],
            raw[_IQ],
            raw[_IR],
            raw[_IALPHA],
            raw[_IBETA],
            raw[_IQBAR] * PSF_PA,
        )

    def _read_truth(self) -> Truth:
        raw = self._raw
        f_scale = FT_M / raw[_IMASS]  # lbf / slug = ft/s^2
        # positional, in Truth's field order (keywords cost ~0.5 us at every step)
        return Truth(
            self.time_us,
            raw[_ILAT],  # lat_rad
            raw[_ILON],  # lon_rad
            raw[_IH],  # alt_msl_m
            np.array((raw[_IVN] * FT_M, raw[_IVE] * FT_M, raw[_IVD] * FT_M)),  # v_ned_mps
            _euler_to_quat(raw[_IPHI], raw[_ITHETA], raw[_IPSI]),  # q_nb
            np.array((raw[_IPI], raw[_IQI], raw[_IRI])),  # omega_b_rps
            np.array((raw[_IFX] * f_scale, raw[_IFY] * f_scale, raw[_IFZ] * f_scale)),
            raw[_IPS] * PSF_PA,  # static_pressure_pa
            raw[_ITR] * RANKINE_K,  # temperature_k
            raw[_IVT] * FT_M,  # airspeed_mps
            raw[_IVC] * FT_M,  # indicated_airspeed_mps
            raw[_IALPHA],
            raw[_IBETA],
            np.array((raw[_IWN] * FT_M, raw[_IWE] * FT_M, raw[_IWD] * FT_M)),  # wind_ned_mps
        )

    def _check(self) -> None:
        raw = self._raw
        t = self.time_s
        if not math.isfinite(math.fsum(raw)):  # any inf or nan makes the sum non-finite
            self._end("the simulation diverged (non-finite state)", t)
        on_ground_start = self._on_ground_start
        if not on_ground_start and (raw[_IHAGL] * FT_M < 1.0 or raw[_IWOW] > 0.5):
            self._end(f"hit the ground at {raw[_IH]:.1f} m", t)
        alpha_deg = math.degrees(raw[_IALPHA])
        if on_ground_start and raw[_IWOW] > 0.5:
            alpha_deg = 0.0  # rolling on the gear: no stall, whatever the air does
        if alpha_deg > self.config.stall_alpha_deg:
            self._stall_s += self._dt
            if self._stall_s >= _STALL_PERSIST_S - 1e-9:
                self._end(
                    f"stall: angle of attack {alpha_deg:.1f} deg above "
                    f"{self.config.stall_alpha_deg:.1f} deg at {raw[_IVT] * FT_M:.1f} m/s",
                    t,
                )
        else:
            self._stall_s = 0.0
        phi, theta = math.degrees(raw[_IPHI]), math.degrees(raw[_ITHETA])
        if abs(phi) > 100.0 or abs(theta) > 70.0:
            self._end(f"loss of control: bank {phi:.0f} deg, pitch {theta:.0f} deg", t)
        if raw[_IVT] * FT_M < 5.0 and not on_ground_start:
            self._end(f"airspeed lost ({raw[_IVT] * FT_M:.1f} m/s)", t)

    def _end(self, reason: str, time_s: float) -> None:
        self._ended = FlightEnded(reason, time_s)
        raise self._ended
