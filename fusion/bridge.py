"""Hooks for GNSS-outage bridging strategies (papers P0-P3: learn the INS error while GNSS is
good, correct the INS while it is not), and the shadow INS bank that feeds them.

:class:`fusion.filter.NavFilter` calls a :class:`Bridge`:

- ``on_gnss(epoch, error)`` once per fused (or attempted) GNSS fix, with INS-side features at
  the fix's epoch and the GNSS-derived INS error (INS minus GNSS, lever-arm corrected, before
  the update) — the training pairs of P0's GMDH and P1/P2's networks. When the strategy asks
  for virtual outages (:class:`LearningBridge`, ``virtual_outage_s > 0``) the error also
  carries one :class:`VirtualOutage` per running shadow INS (see below);
- ``on_outage(epoch)`` at ``BridgeConfig.rate_hz`` while GNSS is out; the strategy may return
  a :class:`PseudoGnss` (P3: a pseudo-fix the filter fuses like GNSS, keeping its update step)
  or an :class:`OutputCorrection` (P0/P2: subtracted from the output estimate only, the INS
  and the filter are left alone), or ``None``;
- ``on_gnss_restored(epoch)`` when the filter leaves the outage.

:class:`NoBridge` (name ``"none"``) does nothing: plain free-inertial coasting.

Why virtual outages
-------------------
NavFilter is a closed-loop error-state filter: every fix is fed back into the INS, so the
INS-minus-GNSS error at the next fix is only the prediction error over one GNSS interval
(a few centimetres plus GNSS noise). A network trained on those pairs learns "about zero",
which is what the INS error is *not* once GNSS is gone. What an outage needs is how the INS
drifts when left alone. :class:`ShadowBank` runs ``count`` shadow copies of the strapdown INS,
mechanised with the main INS's increments but with the bias estimates frozen at their
re-seed (as they are in a real outage), each re-seeded from the filter's INS every
``period_s`` (staggered by ``period_s / count``). At each fix the filter hands the strategy
each shadow's error against the fix and the time since its re-seed: drift-versus-time pairs
from outages that did not happen. The shadows' vertical channel is slaved to the main INS,
because in a real outage the barometer keeps aiding the filter's height; their horizontal
channel and attitude are free. During a real outage shadow 0 is re-seeded at the outage's
detection and runs free (``BridgeEpoch.free_state``), which a pseudo-GNSS strategy needs to
predict the true position independently of the corrections its own pseudo-fixes cause.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Protocol

from fusion import earth, strapdown
from fusion.strapdown import InsState

Vec3 = tuple[float, float, float]
Vec6 = tuple[float, float, float, float, float, float]
_ZERO3: Vec3 = (0.0, 0.0, 0.0)

COMPONENTS: tuple[str, ...] = ("pn", "pe", "pd", "vn", "ve", "vd")
"""The six corrected components: N/E/D position error (m), N/E/D velocity error (m/s)."""

BRIDGE_STATES: tuple[str, ...] = ("off", "untrained", "training", "trained", "stale")
"""Values of :attr:`BridgeStatus.state`."""


@dataclass(frozen=True, slots=True)
class BridgeEpoch:
    """INS-side features at one epoch (all SI, NED)."""

    time_us: int
    lat_rad: float
    lon_rad: float
    alt_msl_m: float
    v_ned_mps: tuple[float, float, float]
    euler_rad: tuple[float, float, float]
    """Roll, pitch, yaw."""
    f_n_mps2: tuple[float, float, float]
    """Specific force in NED, mean over the last covariance-propagation interval."""
    omega_ib_b_rps: tuple[float, float, float]
    """Bias-corrected body rate of the last IMU sample."""
    time_since_gnss_s: float
    """Seconds since the last fused fix (0 at a GNSS epoch)."""
    accel_bias_b: tuple[float, float, float] = _ZERO3
    """The filter's accelerometer bias estimate, m/s^2."""
    gyro_bias_b: tuple[float, float, float] = _ZERO3
    """The filter's gyro bias estimate, rad/s."""
    free_state: InsState | None = None
    """During a real outage, when the strategy runs virtual outages: the free-running INS
    since the outage was detected (never corrected by pseudo-fixes); ``None`` otherwise."""


@dataclass(frozen=True, slots=True)
class VirtualOutage:
    """One shadow INS's error against a GNSS fix: a drift sample from an outage that did not
    happen.

    Attributes
    ----------
    shadow : int
        Index of the shadow INS.
    elapsed_s : float
        Time from the shadow's re-seed to the fix's time of validity, s.
    start : BridgeEpoch
        The filter's INS features at the re-seed (the virtual outage's start).
    epoch : BridgeEpoch
        The shadow's own features at the fix (its position, velocity and attitude; specific
        force, body rate and biases as the filter's).
    pos_ned_m : 3 floats
        Shadow minus GNSS, metres N/E/D (lever-arm corrected as the filter's innovation).
    vel_ned_mps : 3 floats
        Shadow minus GNSS velocity, m/s.
    """

    shadow: int
    elapsed_s: float
    start: BridgeEpoch
    epoch: BridgeEpoch
    pos_ned_m: Vec3
    vel_ned_mps: Vec3


@dataclass(frozen=True, slots=True)
class InsError:
    """GNSS-derived INS error at a fix's time of validity: INS minus GNSS, before the update."""

    pos_ned_m: tuple[float, float, float]
    vel_ned_mps: tuple[float, float, float]
    pos_accepted: bool
    vel_accepted: bool
    virtual: tuple[VirtualOutage, ...] = ()
    """The shadow INS errors at this fix (empty unless the strategy asked for them)."""


@dataclass(frozen=True, slots=True)
class PseudoGnss:
    """A pseudo-fix for the filter to fuse (antenna position and velocity, 1-sigma per axis)."""

    lat_rad: float
    lon_rad: float
    alt_msl_m: float
    v_ned_mps: tuple[float, float, float]
    sigma_pos_m: float
    sigma_vel_mps: float


@dataclass(frozen=True, slots=True)
class OutputCorrection:
    """Predicted INS error to subtract from the *output* (estimate = INS - correction)."""

    pos_ned_m: tuple[float, float, float]
    vel_ned_mps: tuple[float, float, float]


BridgeAction = PseudoGnss | OutputCorrection


@dataclass(frozen=True, slots=True)
class BridgeStatus:
    """Health of a bridging strategy, for the filter's estimate and the status topic.

    Attributes
    ----------
    method : str
        Strategy name.
    state : str
        ``"off"`` (plain filter), ``"untrained"`` (too little data: behaves as ``none``),
        ``"training"`` (first fits under way, some components not fitted yet), ``"trained"``,
        ``"stale"`` (no refit for longer than ``BridgeConfig.stale_after_s``, e.g. in a long
        outage or after long GNSS rejection; the last models are still used).
    samples : int
        Training pairs in the sliding window.
    refits : int
        Component fits completed since construction.
    validation_rmse : 6 floats
        Per component (:data:`COMPONENTS`), RMS error left by the correction on the outages
        the fallback gate judged (held-out virtual outages, replayed through the models in
        use at their start, and the ends of real outages); NaN before the first.
    zero_rmse : 6 floats
        RMS error of no correction on the same outages.
    fallback : 6 bools
        Component not corrected (the gate has not seen it win clearly and consistently, or
        it is not fitted yet).
    last_fit_samples : int
        Training pairs used by the last component fit (after thinning to the budget).
    horizon_s : float
        Longest time into a (virtual) outage covered by the training pairs; inputs beyond the
        training range are clipped to it, so predictions stop growing past it, s.
    active : bool
        A correction or pseudo-fix is being applied now.
    """

    method: str
    state: str
    samples: int = 0
    refits: int = 0
    validation_rmse: Vec6 = (math.nan,) * 6
    zero_rmse: Vec6 = (math.nan,) * 6
    fallback: tuple[bool, bool, bool, bool, bool, bool] = (True,) * 6
    last_fit_samples: int = 0
    horizon_s: float = 0.0
    active: bool = False


class Bridge(Protocol):
    """A bridging strategy (see module docstring)."""

    @property
    def name(self) -> str: ...

    def on_gnss(self, epoch: BridgeEpoch, error: InsError) -> None: ...

    def on_outage(self, epoch: BridgeEpoch) -> BridgeAction | None: ...

    def on_gnss_restored(self, epoch: BridgeEpoch) -> None: ...


class LearningBridge(Bridge, Protocol):
    """A strategy that asks the filter for virtual outages and reports its health.

    NavFilter reads ``virtual_outage_s`` and ``virtual_outage_count`` once (at construction and
    :meth:`~fusion.filter.NavFilter.reset`): ``virtual_outage_s > 0`` makes it run the
    :class:`ShadowBank`; otherwise the shadows cost nothing.
    """

    @property
    def virtual_outage_s(self) -> float: ...

    @property
    def virtual_outage_count(self) -> int: ...

    @property
    def status(self) -> BridgeStatus: ...


_NONE_STATUS = BridgeStatus("none", "off")


class NoBridge:
    """The ``"none"`` strategy: observes nothing, corrects nothing."""

    name = "none"
    virtual_outage_s = 0.0
    virtual_outage_count = 0

    @property
    def status(self) -> BridgeStatus:
        """Always ``"off"``."""
        return _NONE_STATUS

    def on_gnss(self, epoch: BridgeEpoch, error: InsError) -> None:
        """Ignore the training pair."""

    def on_outage(self, epoch: BridgeEpoch) -> BridgeAction | None:
        """No correction."""
        return None

    def on_gnss_restored(self, epoch: BridgeEpoch) -> None:
        """Nothing to reset."""


# ---------------------------------------------------------------------------------------------
# Shadow INS bank (virtual outages)
# ---------------------------------------------------------------------------------------------


class _Shadow:
    __slots__ = ("ba", "bg", "prev_dth", "prev_dv", "seed_us", "start", "state")

    def __init__(self) -> None:
        self.state: InsState | None = None
        self.seed_us = 0
        self.start: BridgeEpoch | None = None
        self.ba: Vec3 = _ZERO3
        self.bg: Vec3 = _ZERO3
        self.prev_dth: Sequence[float] = _ZERO3
        self.prev_dv: Sequence[float] = _ZERO3


class ShadowBank:
    """``count`` staggered shadow strapdown INS copies (virtual outages, module docstring).

    Parameters
    ----------
    period_s : float
        Each shadow is re-seeded from the filter's INS this often, s (> 0).
    count : int
        Number of shadows (>= 1); shadow ``i`` is first seeded ``i * period_s / count`` after
        the first step.
    epoch_fn : callable ``(time_us, InsState) -> BridgeEpoch``
        Builds the filter's features for a state (the filter's ``_epoch``).

    Notes
    -----
    Cost per IMU sample: one :func:`fusion.strapdown.update` per running shadow (about 10 µs
    each in CPython) plus a few float operations; nothing when the bank is not created.
    """

    def __init__(
        self, period_s: float, count: int, epoch_fn: Callable[[int, InsState], BridgeEpoch]
    ) -> None:
        if not (math.isfinite(period_s) and period_s > 0.0):
            raise ValueError(f"ShadowBank: period_s must be > 0, got {period_s!r}")
        if count < 1:
            raise ValueError(f"ShadowBank: count must be >= 1, got {count!r}")
        self._period_us = max(1, round(period_s * 1e6))
        self._count = int(count)
        self._epoch_fn = epoch_fn
        self._shadows = [_Shadow() for _ in range(self._count)]
        self._next_us: list[int | None] = [None] * self._count
        self._hold = False

    @property
    def shadows(self) -> list[InsState | None]:
        """Current shadow states (``None``: not seeded yet)."""
        return [s.state for s in self._shadows]

    @property
    def in_outage(self) -> bool:
        """A real outage is under way (only shadow 0 runs, free)."""
        return self._hold

    @property
    def free_state(self) -> InsState | None:
        """The free-running INS during a real outage (``None`` otherwise)."""
        return self._shadows[0].state if self._hold else None

    def _seed(
        self, i: int, t_us: int, main: InsState, ba: Sequence[float], bg: Sequence[float],
        dth: Sequence[float], dv: Sequence[float],
    ) -> None:  # fmt: skip
        s = self._shadows[i]
        s.state = main
        s.seed_us = t_us
        s.start = self._epoch_fn(t_us, main)
        s.ba = (ba[0], ba[1], ba[2])
        s.bg = (bg[0], bg[1], bg[2])
        s.prev_dth = dth
        s.prev_dv = dv

    def step(
        self, t_us: int, main: InsState, dth: Sequence[float], dv: Sequence[float],
        dt: float, ba: Sequence[float], bg: Sequence[float],
    ) -> None:  # fmt: skip
        """Advance every running shadow over one IMU interval; re-seed those that are due.

        Parameters
        ----------
        t_us : int
            Time at the end of the interval.
        main : InsState
            The filter's INS after its own update over the same interval.
        dth, dv : 3 floats
            The filter's bias-corrected gyro / accelerometer increments of the interval.
        dt : float
            Interval, s.
        ba, bg : 3 floats
            The filter's current bias estimates (the shadows undo their changes since the
            re-seed: a shadow's biases stay frozen, as in a real outage).
        """
        nxt = self._next_us
        hold = self._hold
        for i, s in enumerate(self._shadows):
            st = s.state
            if st is not None and (not hold or i == 0):
                sb, sa = s.bg, s.ba
                th = (
                    dth[0] + (bg[0] - sb[0]) * dt,
                    dth[1] + (bg[1] - sb[1]) * dt,
                    dth[2] + (bg[2] - sb[2]) * dt,
                )
                v = (
                    dv[0] + (ba[0] - sa[0]) * dt,
                    dv[1] + (ba[1] - sa[1]) * dt,
                    dv[2] + (ba[2] - sa[2]) * dt,
                )
                new = strapdown.update(st, th, v, s.prev_dth, s.prev_dv, dt)
                # vertical channel slaved to the (baro-aided) filter, horizontal free
                vn, ve, _ = new.v_ned_mps
                s.state = InsState(
                    new.lat_rad, new.lon_rad, main.alt_msl_m, (vn, ve, main.v_ned_mps[2]),
                    new.q_nb,
                )  # fmt: skip
                s.prev_dth = th
                s.prev_dv = v
            if hold:
                continue
            due = nxt[i]
            if due is None:
                nxt[i] = due = t_us + (i * self._period_us) // self._count
            if t_us >= due:
                self._seed(i, t_us, main, ba, bg, dth, dv)
                nxt[i] = max(due + self._period_us, t_us + 1)

    def begin_outage(
        self, t_us: int, main: InsState, ba: Sequence[float], bg: Sequence[float],
        dth: Sequence[float], dv: Sequence[float],
    ) -> None:  # fmt: skip
        """A real outage was detected: shadow 0 becomes the free INS (seeded now), the other
        shadows stop (their virtual outages would straddle the real one)."""
        self._seed(0, t_us, main, ba, bg, dth, dv)
        self._hold = True
        for s in self._shadows[1:]:
            s.state = None

    def end_outage(self, t_us: int) -> None:
        """GNSS is back: restart the staggered re-seeding from ``t_us``."""
        self._hold = False
        self._shadows[0].state = None
        self._next_us = [t_us + (i * self._period_us) // self._count for i in range(self._count)]

    def restart(self, t_us: int) -> None:
        """Drop every shadow (e.g. over an IMU gap the INS did not mechanise) and restart the
        staggered re-seeding from ``t_us``; in a real outage the free INS is lost too."""
        for s in self._shadows:
            s.state = None
        self._next_us = [t_us + (i * self._period_us) // self._count for i in range(self._count)]

    def samples(
        self,
        t_fix_us: int,
        main_pos: InsState,
        main_vel: InsState,
        z_pos: Sequence[float],
        z_vel: Sequence[float],
    ) -> tuple[VirtualOutage, ...]:
        """Every running shadow's error against one fix.

        The shadow is compared with the fix through the filter:
        ``shadow - gnss = (shadow - main) + (main - gnss)``, with ``main - gnss`` the filter's
        innovation (at the fix's time of validity, lever-arm corrected) and ``shadow - main``
        taken now (the drift difference changes negligibly over the fix's latency).

        Parameters
        ----------
        t_fix_us : int
            The fix's time of validity.
        main_pos, main_vel : InsState
            The filter's current INS before the position update / before the velocity update.
        z_pos, z_vel : 3 floats
            The filter's position and velocity innovations (INS minus GNSS, NED).

        Returns
        -------
        tuple of VirtualOutage
        """
        if self._hold:
            return ()
        out: list[VirtualOutage] = []
        lt = earth.local_terms(main_pos.lat_rad, main_pos.alt_msl_m)
        kn, ke = lt.rho_n_m, lt.rho_e_m * lt.cos_lat
        mv = main_vel.v_ned_mps
        for i, s in enumerate(self._shadows):
            st, start = s.state, s.start
            if st is None or start is None or t_fix_us < s.seed_us:
                continue
            dn = (st.lat_rad - main_pos.lat_rad) * kn
            de = (st.lon_rad - main_pos.lon_rad) * ke
            dd = main_pos.alt_msl_m - st.alt_msl_m
            v = st.v_ned_mps
            out.append(
                VirtualOutage(
                    i,
                    (t_fix_us - s.seed_us) * 1e-6,
                    start,
                    self._epoch_fn(t_fix_us, st),
                    (dn + z_pos[0], de + z_pos[1], dd + z_pos[2]),
                    (v[0] - mv[0] + z_vel[0], v[1] - mv[1] + z_vel[1], v[2] - mv[2] + z_vel[2]),
                )
            )
        return tuple(out)
