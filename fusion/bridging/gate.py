"""The bridging fallback gate: whether each fitted component's correction is applied.

A fitted network is only a *candidate*. Whether its correction is applied is decided by what
it would have done on data it never saw: every virtual outage, once over, is replayed through
the candidates that were in use when it *started* (the virtual outages give exactly that: the error
left after the correction against the INS left uncorrected, over the first
``gate_horizon_s``), and the first fix after each real outage scores the candidates' last
prediction against the drift GNSS then reveals (output corrections only). A component is on
only while, over its last ``gate_outages`` scored outages (at least ``gate_min_outages``),
the RMS error left is at most ``gate_margin`` times that of no correction (over the summed
squares *and* as the geometric mean of the per-outage ratios), it won in at least
``gate_min_wins`` of them, and it won the most recent one: it turns off at the first loss.
The last real outage is the judge that counts: virtual outages (INS copies without the
filter's mag/baro aiding) can drift unlike real ones, so a component whose prediction lost
the last real outage stays off until it wins one again.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable, Iterator, Sequence

import numpy as np
from numpy.typing import NDArray

from fusion.bridging.features import COL_T, Spec
from fusion.bridging.interface import InsError
from fusion.bridging.models import Candidate, Snapshot
from fusion.config import BridgeConfig

FloatArray = NDArray[np.float64]


def _log_ratio(left: float, uncorrected: float) -> float:
    """``log(left / uncorrected)`` of one scored outage (+inf when the correction added error
    to a zero one or is not finite, 0 when both are zero)."""
    if not math.isfinite(left):
        return math.inf
    if uncorrected <= 0.0:
        return 0.0 if left <= 0.0 else math.inf
    return math.log(max(left, 1e-300) / uncorrected)


class Tracked:
    """A virtual outage under way: the candidates in use at its start, its longest elapsed."""

    __slots__ = ("elapsed", "snapshot")

    def __init__(self, snapshot: Snapshot) -> None:
        self.snapshot = snapshot
        self.elapsed = 0.0


class FallbackGate:
    """The per-component on/off decision of a learned strategy (see the module docstring).

    Parameters
    ----------
    config : BridgeConfig
        The ``gate_*`` settings and ``min_horizon_s``.
    components : tuple of int
        The corrected components (indices into :data:`~fusion.bridging.interface.COMPONENTS`).

    Attributes
    ----------
    fallback : list of 6 bool
        Component not corrected (not fitted, or the gate has not seen it win).
    val_rmse, zero_rmse : list of 6 float
        RMS error left by the correction / of no correction on the scored outages (NaN
        before the first).
    scores : list of 6 deque
        Per component, ``(mean square left, mean square uncorrected)`` of each scored outage.
    """

    def __init__(self, config: BridgeConfig, components: tuple[int, ...]) -> None:
        self.config = config
        self._components = components
        self.fallback = [True] * 6
        self.val_rmse = [math.nan] * 6
        self.zero_rmse = [math.nan] * 6
        self.scores: list[deque[tuple[float, float]]] = [
            deque(maxlen=config.gate_outages) for _ in range(6)
        ]
        self._real_lost = [False] * 6
        self._real_scored = False
        self._judged: set[int] = set()  # virtual outages already scored (keys)
        self._judged_order: deque[int] = deque()
        self._tracked: dict[int, Tracked] = {}

    # -- virtual outages ----------------------------------------------------------------------
    def track(self, key: int, elapsed_s: float, candidates: Sequence[Candidate | None]) -> None:
        """A training pair of the virtual outage ``key`` arrived ``elapsed_s`` into it; an
        outage seen for the first time remembers the candidates in use now (they have seen
        nothing of it)."""
        tr = self._tracked.get(key)
        if tr is None:
            if key in self._judged:
                # scored already: a copy runs on past the gate horizon, and tracking it again
                # would score the same outage once per fix, with models that have trained on it
                return
            tr = self._tracked[key] = Tracked(tuple(candidates))
        tr.elapsed = max(tr.elapsed, elapsed_s)

    def finished(self, seen: set[int]) -> Iterator[tuple[int, Tracked]]:
        """Stop tracking, and yield, the virtual outages that ended (no pair at this fix) or
        ran past ``gate_horizon_s``."""
        for key in list(self._tracked):
            tr = self._tracked[key]
            if key not in seen or tr.elapsed >= self.config.gate_horizon_s:
                yield key, self._tracked.pop(key)

    def score_virtual(
        self,
        key: int,
        tracked: Tracked,
        rows: Callable[[int], tuple[FloatArray, FloatArray]],
        specs: Sequence[Spec],
        candidates: Sequence[Candidate | None],
    ) -> None:
        """Replay a finished virtual outage through the candidates of its start.

        Parameters
        ----------
        key : int
            The outage.
        tracked : Tracked
            What :meth:`finished` yielded for it.
        rows : callable ``key -> (B, Y)``
            The outage's training pairs in time order: base rows (n, 42) and targets (n, 6).
        specs : sequence of Spec
            Feature spec per component.
        candidates : sequence of Candidate or None
            The candidates in use now (for :meth:`judge`).
        """
        self._judged.add(key)
        self._judged_order.append(key)
        if len(self._judged_order) > 256:
            self._judged.discard(self._judged_order.popleft())
        if tracked.elapsed < self.config.min_horizon_s or not any(tracked.snapshot):
            return  # too short to say anything (or nothing was fitted at its start)
        B_all, Y_all = rows(key)
        keep = B_all[:, COL_T] <= self.config.gate_horizon_s
        if np.count_nonzero(keep) < 2:
            return
        B = B_all[keep]
        Y = Y_all[keep]
        groups = np.zeros(len(B), dtype=np.int64)
        for k in self._components:
            cand = tracked.snapshot[k]
            if cand is None:
                continue
            y = Y[:, k]
            pred = cand.predict_rows(B, specs[k], groups)
            left = float(np.mean((y - pred) ** 2))
            self.scores[k].append((left if math.isfinite(left) else math.inf,
                                   float(np.mean(y * y))))  # fmt: skip
        self.judge(candidates)

    # -- real outages -------------------------------------------------------------------------
    def score_real(
        self, prediction: list[float], error: InsError, candidates: Sequence[Candidate | None]
    ) -> None:
        """The first fix after a real outage measures the INS error at its end: what the
        candidates' last prediction would have left of it (output corrections only: a
        pseudo-GNSS strategy has moved the INS, so the fix no longer sees the drift).

        Once per outage, at its first fix, whether or not the filter's gate took it: after a
        long outage the gate may refuse good fixes for seconds (until its reset), and those
        are exactly the outages where a bad correction must be caught.
        """
        if self._real_scored:
            return
        self._real_scored = True
        err = [*error.pos_ned_m, *error.vel_ned_mps]
        for k in self._components:
            if math.isfinite(prediction[k]) and math.isfinite(err[k]):
                self.scores[k].append(((err[k] - prediction[k]) ** 2, err[k] ** 2))
                self._real_lost[k] = (err[k] - prediction[k]) ** 2 >= err[k] ** 2
        self.judge(candidates)

    def outage_ended(self) -> None:
        """GNSS is back: the next real outage will be scored at its first fix."""
        self._real_scored = False

    # -- decision -----------------------------------------------------------------------------
    def judge(self, candidates: Sequence[Candidate | None]) -> None:
        """Turn each component on or off from its record (``BridgeConfig.gate_*``)."""
        cfg = self.config
        for k in self._components:
            sc = self.scores[k]
            if sc:
                self.val_rmse[k] = math.sqrt(sum(s[0] for s in sc) / len(sc))
                self.zero_rmse[k] = math.sqrt(sum(s[1] for s in sc) / len(sc))
            on = False
            if candidates[k] is not None and len(sc) >= cfg.gate_min_outages:
                left = sum(s[0] for s in sc)
                unc = sum(s[1] for s in sc)
                wins = sum(1 for s in sc if s[0] < s[1])
                # per outage too (geometric mean of the ratios): the sums alone are ruled by
                # the largest drifts, and a correction that wins the big outages can still
                # multiply the error of the small ones
                log_ratio = sum(_log_ratio(a, b) for a, b in sc) / len(sc)
                on = (
                    left <= cfg.gate_margin**2 * unc
                    and log_ratio <= 2.0 * math.log(cfg.gate_margin)
                    and wins >= cfg.gate_min_wins * len(sc)
                    and sc[-1][0] < sc[-1][1]
                    and not self._real_lost[k]
                )
            self.fallback[k] = not on
