"""Virtual outages: free-running INS copies that give drift samples from outages that did not
happen.

NavFilter is a closed-loop error-state filter: every fix is fed back into the INS, so the
INS-minus-GNSS error at the next fix is only the prediction error over one GNSS interval
(a few centimetres plus GNSS noise). A network trained on those pairs learns "about zero",
which is what the INS error is *not* once GNSS is gone. What an outage needs is how the INS
drifts when left alone. :class:`VirtualOutageBank` runs ``count`` copies of the strapdown INS,
mechanised with the main INS's increments but with the bias estimates frozen at their
re-seed (as they are in a real outage), each re-seeded from the filter's INS every
``period_s`` (staggered by ``period_s / count``). At each fix the filter hands the strategy
each copy's error against the fix and the time since its re-seed: drift-versus-time pairs
from outages that did not happen. The copies' vertical channel is slaved to the main INS,
because in a real outage the barometer keeps aiding the filter's height; their horizontal
channel and attitude are free. During a real outage copy 0 is re-seeded at the outage's
detection and runs free (``BridgeEpoch.free_state``), which a pseudo-GNSS strategy needs to
predict the true position independently of the corrections its own pseudo-fixes cause.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

from fusion import earth, strapdown
from fusion.bridging.interface import BridgeEpoch, VirtualOutage
from fusion.strapdown import InsState

Vec3 = tuple[float, float, float]
_ZERO3: Vec3 = (0.0, 0.0, 0.0)

class _OutageIns:
    __slots__ = ("ba", "bg", "prev_dth", "prev_dv", "seed_us", "start", "state")

    def __init__(self) -> None:
        self.state: InsState | None = None
        self.seed_us = 0
        self.start: BridgeEpoch | None = None
        self.ba: Vec3 = _ZERO3
        self.bg: Vec3 = _ZERO3
        self.prev_dth: Sequence[float] = _ZERO3
        self.prev_dv: Sequence[float] = _ZERO3


class VirtualOutageBank:
    """``count`` staggered virtual-outage INS copies (module docstring).

    Parameters
    ----------
    period_s : float
        Each copy is re-seeded from the filter's INS this often, s (> 0).
    count : int
        Number of copies (>= 1); copy ``i`` is first seeded ``i * period_s / count`` after
        the first step.
    epoch_fn : callable ``(time_us, InsState) -> BridgeEpoch``
        Builds the filter's features for a state (the filter's ``_epoch``).

    Notes
    -----
    Cost per IMU sample: one :func:`fusion.strapdown.update` per running copy (about 10 µs
    each in CPython) plus a few float operations; nothing when the bank is not created.
    """

    def __init__(
        self, period_s: float, count: int, epoch_fn: Callable[[int, InsState], BridgeEpoch]
    ) -> None:
        if not (math.isfinite(period_s) and period_s > 0.0):
            raise ValueError(f"VirtualOutageBank: period_s must be > 0, got {period_s!r}")
        if count < 1:
            raise ValueError(f"VirtualOutageBank: count must be >= 1, got {count!r}")
        self._period_us = max(1, round(period_s * 1e6))
        self._count = int(count)
        self._epoch_fn = epoch_fn
        self._copies = [_OutageIns() for _ in range(self._count)]
        self._next_us: list[int | None] = [None] * self._count
        self._hold = False

    @property
    def states(self) -> list[InsState | None]:
        """Current states of the copies (``None``: not seeded yet)."""
        return [s.state for s in self._copies]

    @property
    def in_outage(self) -> bool:
        """A real outage is under way (only copy 0 runs, free)."""
        return self._hold

    @property
    def free_state(self) -> InsState | None:
        """The free-running INS during a real outage (``None`` otherwise)."""
        return self._copies[0].state if self._hold else None

    def _seed(
        self, i: int, t_us: int, main: InsState, ba: Sequence[float], bg: Sequence[float],
        dth: Sequence[float], dv: Sequence[float],
    ) -> None:  # fmt: skip
        s = self._copies[i]
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
        """Advance every running copy over one IMU interval; re-seed those that are due.

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
            The filter's current bias estimates (the copies undo their changes since the
            re-seed: a copy's biases stay frozen, as in a real outage).
        """
        nxt = self._next_us
        hold = self._hold
        for i, s in enumerate(self._copies):
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
        """A real outage was detected: copy 0 becomes the free INS (seeded now), the other
        copies stop (their virtual outages would straddle the real one)."""
        self._seed(0, t_us, main, ba, bg, dth, dv)
        self._hold = True
        for s in self._copies[1:]:
            s.state = None

    def end_outage(self, t_us: int) -> None:
        """GNSS is back: restart the staggered re-seeding from ``t_us``."""
        self._hold = False
        self._copies[0].state = None
        self._next_us = [t_us + (i * self._period_us) // self._count for i in range(self._count)]

    def restart(self, t_us: int) -> None:
        """Drop every copy (e.g. over an IMU gap the INS did not mechanise) and restart the
        staggered re-seeding from ``t_us``; in a real outage the free INS is lost too."""
        for s in self._copies:
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
        """Every running copy's error against one fix.

        The copy is compared with the fix through the filter:
        ``copy - gnss = (copy - main) + (main - gnss)``, with ``main - gnss`` the filter's
        innovation (at the fix's time of validity, lever-arm corrected) and ``copy - main``
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
        for i, s in enumerate(self._copies):
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
