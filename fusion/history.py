"""Short buffer of past INS states, for fusing delayed measurements (GNSS latency).

Each IMU epoch stores the INS state (an immutable tuple: storing it costs one list slot) and the
running sum of the feedback corrections applied so far. A past state read back later is
corrected by every feedback applied *after* it was stored — ``x_past - (sum_now - sum_then)`` —
so a measurement at its time of validity is compared with an INS history consistent with the
current, corrected INS (corrections are small and are carried unchanged over the fraction of a
second the buffer spans).
"""

from __future__ import annotations

import math
from collections import deque

from fusion import earth
from fusion.rotations import quat_product, rotvec_quat
from fusion.strapdown import InsState

Correction9 = tuple[float, float, float, float, float, float, float, float, float]
_ZERO9: Correction9 = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)


class InsHistory:
    """Ring buffer of ``(time_us, InsState, cumulative correction)``.

    Parameters
    ----------
    capacity : int
        Number of epochs kept (e.g. 0.5 s at 400 Hz -> 200).
    """

    def __init__(self, capacity: int) -> None:
        if capacity < 2:
            raise ValueError(f"capacity must be >= 2, got {capacity}")
        self._cap = capacity
        # one bounded deque of entry tuples: push (every IMU epoch) is a single C-level append
        self._d: deque[tuple[int, InsState, Correction9]] = deque(maxlen=capacity)
        self._cum: Correction9 = _ZERO9

    def clear(self) -> None:
        """Forget every stored state (the running correction sum restarts too)."""
        self._d.clear()
        self._cum = _ZERO9

    def push(self, time_us: int, state: InsState) -> None:
        """Store the INS state of epoch ``time_us`` (times must increase)."""
        self._d.append((time_us, state, self._cum))

    def add_correction(self, dx9: list[float]) -> None:
        """Record a feedback ``[dr_ned m, dv_ned m/s, phi rad]`` just subtracted from the INS."""
        c, d = self._cum, dx9
        self._cum = (
            c[0] + d[0], c[1] + d[1], c[2] + d[2], c[3] + d[3], c[4] + d[4], c[5] + d[5],
            c[6] + d[6], c[7] + d[7], c[8] + d[8],
        )  # fmt: skip

    @property
    def oldest_us(self) -> int | None:
        """Time of the oldest stored epoch."""
        return self._d[0][0] if self._d else None

    def _corrected(self, entry: tuple[int, InsState, Correction9]) -> InsState:
        _, s, c0 = entry
        c1 = self._cum
        if c0 is c1:
            return s
        d = [b - a for a, b in zip(c0, c1, strict=True)]
        t = earth.local_terms(s.lat_rad, s.alt_msl_m)
        vn, ve, vd = s.v_ned_mps
        # q <- q(-phi) ⊗ q
        q = quat_product(rotvec_quat(-d[6], -d[7], -d[8]), s.q_nb)
        return InsState(
            s.lat_rad - d[0] / t.rho_n_m,
            s.lon_rad - d[1] / (t.rho_e_m * t.cos_lat),
            s.alt_msl_m + d[2],
            (vn - d[3], ve - d[4], vd - d[5]),
            q,
        )

    def at(self, time_us: int) -> InsState | None:
        """Corrected INS state at ``time_us`` (linear interpolation of position and velocity,
        nearest attitude), or ``None`` when outside the stored span."""
        buf = self._d
        if not buf or time_us > buf[-1][0]:
            return None
        newer = buf[-1]
        for entry in reversed(buf):  # newest first: GNSS delays are short
            ti = entry[0]
            if ti <= time_us:
                if ti == time_us:
                    return self._corrected(entry)
                a = self._corrected(entry)
                b = self._corrected(newer)
                w = (time_us - ti) / (newer[0] - ti)
                va, vb = a.v_ned_mps, b.v_ned_mps
                return InsState(
                    a.lat_rad + w * (b.lat_rad - a.lat_rad),
                    a.lon_rad + w * (b.lon_rad - a.lon_rad),
                    a.alt_msl_m + w * (b.alt_msl_m - a.alt_msl_m),
                    (
                        va[0] + w * (vb[0] - va[0]),
                        va[1] + w * (vb[1] - va[1]),
                        va[2] + w * (vb[2] - va[2]),
                    ),
                    a.q_nb if w < 0.5 else b.q_nb,
                )
            newer = entry
        return None


def span_capacity(max_delay_s: float, max_rate_hz: float = 400.0) -> int:
    """Buffer size that covers ``max_delay_s`` at ``max_rate_hz`` with a margin."""
    return max(8, math.ceil(max_delay_s * max_rate_hz * 1.25) + 4)
