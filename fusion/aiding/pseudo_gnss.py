"""Pseudo-GNSS aiding: a bridging strategy's pseudo-fix (paper P3) fused like a GNSS fix.

*How* — the GNSS models (:func:`fusion.aiding.gnss.position_model`,
:func:`~fusion.aiding.gnss.velocity_model`) at the current INS state, with the strategy's
sigmas and no receiver bias. *When* — at each bridging consultation that returns a
:class:`~fusion.bridging.interface.PseudoGnss` (:mod:`fusion.outage`). The updates are
labelled ``bridge_pos`` / ``bridge_vel``.
"""

from __future__ import annotations

import numpy as np

from fusion import kalman
from fusion.aiding import Update
from fusion.aiding.gnss import position_model, velocity_model
from fusion.bridging.interface import PseudoGnss
from fusion.config import GnssTuning
from fusion.estimate import AidSource
from fusion.state_layout import StateLayout
from fusion.strapdown import InsState


class PseudoGnssAiding:
    """Fuses a bridging strategy's pseudo-fixes (position, then velocity).

    Parameters
    ----------
    cfg : GnssTuning
        The antenna lever arm and the gate probability (those of the GNSS updates).
    layout : StateLayout
    update : Update
        The filter's shared measurement update.
    """

    def __init__(self, cfg: GnssTuning, layout: StateLayout, update: Update) -> None:
        self.layout = layout
        self._lever_arm_b_m = cfg.lever_arm_b_m
        self.gate = kalman.chi2_gate(3, cfg.gate_probability)
        self._update = update

    def fuse_position(self, fix: PseudoGnss, ins: InsState, step_us: int) -> None:
        """The pseudo-fix's position, against the current INS ``ins``."""
        obs = position_model(
            self.layout, ins, fix.lat_rad, fix.lon_rad, fix.alt_msl_m,
            fix.sigma_pos_m, fix.sigma_pos_m, self._lever_arm_b_m,
        )  # fmt: skip
        if obs is not None:
            self._update(obs, self.gate, AidSource.BRIDGE_POS, step_us)

    def fuse_velocity(
        self, fix: PseudoGnss, ins: InsState, omega_ib_b_rps: tuple[float, float, float],
        step_us: int,
    ) -> None:  # fmt: skip
        """The pseudo-fix's velocity, against the current INS ``ins`` (after the position
        update) with the bias-corrected body rate ``omega_ib_b_rps``."""
        obs = velocity_model(
            self.layout, ins, omega_ib_b_rps, np.asarray(fix.v_ned_mps, dtype=float),
            fix.sigma_vel_mps, self._lever_arm_b_m,
        )  # fmt: skip
        if obs is not None:
            self._update(obs, self.gate, AidSource.BRIDGE_VEL, step_us)
