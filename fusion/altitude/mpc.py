"""P4's Laguerre-MPC compensator: drives the vertical error model so that ``δh`` tracks
``h − h_GNSS``.

The corrected height is ``h_T = h − δh``. During GNSS outages the compensator has no reference
and keeps its last model (``outage_mode``). P4's horizons are short: with ``Np = 10`` the
receding-horizon loop on this (double-integrator) model is *unstable* for ``R_L ≳ 100``
(finite horizon, no terminal cost); :class:`MpcCompensator` checks the closed-loop spectral
radius and refuses such a design. A slower compensator needs a longer ``period_s`` (or
``np_horizon``).

What an MPC learned while GNSS was valid can do in an outage: only extrapolate its own state.
With ``hold`` it keeps the offset ``h − h_GNSS`` it saw last (which contains the GNSS error of
that moment); with ``coast``/``extrapolate`` it also continues the learned trend. It cannot see
a weather front that starts or changes during the outage.
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from numpy.typing import NDArray
from pydantic import Field, PositiveFloat, PositiveInt

from fusion.altitude.common import OMEGA_S2, Frozen, check_finite
from fusion.altitude.vertical_model import VerticalErrorModel
from fusion.laguerre import LaguerreMPC

FloatArray = NDArray[np.float64]

OutageMode = Literal["hold", "coast", "extrapolate"]


class MpcConfig(Frozen):
    """P4's Laguerre-MPC compensator on the error model.

    ``outage_mode`` (no reference): ``hold`` keeps ``δh`` and the model frozen; ``coast`` runs
    the model on with the last control held (``Δu = 0``); ``extrapolate`` runs it with ``u = 0``
    (``δh`` continues along the learned ``δVz``).

    Defaults: P4's horizons ``Np = Nc = 10``; period 0.2 s, Laguerre pole 0.6 and ``R_L = 1``
    as chosen on the tuning seeds of ``bench/altitude_jsbsim.py`` (grid: period 0.2 / 1 / 5 s,
    pole 0 / 0.6, ``R_L`` 0.01 / 1 / 10). P4 gives no pole or ``N``; :meth:`p4` is the
    untuned design used before (pole 0.5).
    """

    period_s: PositiveFloat = 0.2
    pole: float = Field(default=0.6, ge=0.0, lt=1.0)
    n_terms: PositiveInt = 4
    np_horizon: PositiveInt = 10
    nc_horizon: PositiveInt | None = 10
    r_l: float = Field(default=1.0, ge=0.0)
    delta_u_max_mps2: PositiveFloat | None = None
    """Bound on each acceleration move, m/s² per step (real QP when set)."""
    u_max_mps2: PositiveFloat | None = None
    """Bound on the compensator's acceleration, m/s²."""
    baro_bias_tau_s: PositiveFloat = 600.0
    baro_bias_sigma_m: float = Field(default=1.0, ge=0.0)
    outage_mode: OutageMode = "hold"
    warm_start: bool = True
    """Start the model at ``δh = r`` with the first reference (no pull-in transient)."""

    @classmethod
    def p4(cls) -> MpcConfig:
        """The untuned design: ``Np = Nc = 10`` (P4), pole 0.5, 4 terms, ``R_L = 1``, 0.2 s,
        P4's Gauss–Markov baro bias (τ 600 s)."""
        return cls(pole=0.5)


class MpcCompensator:
    """Laguerre-MPC driving P4's error model so that ``δh`` tracks ``h − h_GNSS``.

    The third state ``b`` is neither driven by ``u`` nor seen in ``δh``; its MPC gain is zero
    and it only decays. Kept so the model is P4's.

    Parameters
    ----------
    config : MpcConfig
    omega_s2 : float
        ``ωs²``, 1/s².
    """

    def __init__(self, config: MpcConfig | None = None, omega_s2: float = OMEGA_S2) -> None:
        self.config = cfg = config or MpcConfig()
        model = VerticalErrorModel(cfg.baro_bias_tau_s, cfg.baro_bias_sigma_m, 0.0, omega_s2)
        phi, gam, _ = model.discretise(cfg.period_s)
        self.model = model
        self.mpc = LaguerreMPC(
            phi,
            gam,
            [0.0, 1.0, 0.0],
            pole=cfg.pole,
            n_terms=cfg.n_terms,
            np_horizon=cfg.np_horizon,
            nc_horizon=cfg.nc_horizon,
            r_l=cfg.r_l,
            delta_u_min=None if cfg.delta_u_max_mps2 is None else -cfg.delta_u_max_mps2,
            delta_u_max=cfg.delta_u_max_mps2,
            u_min=None if cfg.u_max_mps2 is None else -cfg.u_max_mps2,
            u_max=cfg.u_max_mps2,
        )
        rho = float(np.max(np.abs(self.mpc.closed_loop_poles())))
        if rho >= 1.0:
            # A finite horizon without terminal cost does not guarantee stability: with the
            # double integrator of the error model, a heavy r_l makes Np steps too short to
            # act in and the receding-horizon loop diverges (e.g. Np = 10, r_l ≥ 100).
            raise ValueError(
                f"MPC design unstable (closed-loop spectral radius {rho:.4f}): decrease r_l "
                f"({cfg.r_l}) or lengthen np_horizon ({cfg.np_horizon}) / period_s"
            )
        self._phi: list[list[float]] = phi.tolist()
        self._gam: list[float] = gam.tolist()
        self.x = [0.0, 0.0, 0.0]
        self._dx = [0.0, 0.0, 0.0]
        self.u = 0.0
        self.started = False
        self.qp_active = 0

    @property
    def delta_h_m(self) -> float:
        """The model's height error ``δh``, m."""
        return self.x[1]

    @property
    def delta_vz_mps(self) -> float:
        """The model's vertical-speed error ``δVz``, m/s."""
        return self.x[0]

    def delta_at(self, frac: float) -> tuple[float, float]:
        """``(δh, δVz)`` a fraction ``frac`` ∈ [0, 1] into the current period.

        After :meth:`step` at time ``k`` the model holds ``x(k+1)``; between steps the output is
        interpolated linearly from ``x(k)`` to ``x(k+1)`` (first-order hold), so the correction
        has the right timing and no staircase at long periods.
        """
        back = 1.0 - min(1.0, max(0.0, frac))
        return self.x[1] - back * self._dx[1], self.x[0] - back * self._dx[0]

    def snapshot(self) -> tuple[tuple[float, ...], tuple[float, ...], float, bool]:
        """The compensator's state (for :meth:`restore`)."""
        return (tuple(self.x), tuple(self._dx), self.u, self.started)

    def restore(self, state: tuple[tuple[float, ...], tuple[float, ...], float, bool]) -> None:
        """Go back to a state taken with :meth:`snapshot`."""
        x, dx, self.u, self.started = state
        self.x, self._dx = list(x), list(dx)

    def _propagate(self, u: float) -> None:
        p, g, x = self._phi, self._gam, self.x
        n0 = p[0][0] * x[0] + p[0][1] * x[1] + p[0][2] * x[2] + g[0] * u
        n1 = p[1][0] * x[0] + p[1][1] * x[1] + p[1][2] * x[2] + g[1] * u
        n2 = p[2][0] * x[0] + p[2][1] * x[1] + p[2][2] * x[2] + g[2] * u
        self._dx = [n0 - x[0], n1 - x[1], n2 - x[2]]
        self.x = [n0, n1, n2]

    def step(self, reference_m: float | None) -> float:
        """One compensator period.

        Parameters
        ----------
        reference_m : float or None
            ``δh_ref = h − h_GNSS`` (m) while GNSS is valid, ``None`` during outages.

        Returns
        -------
        float
            ``δh`` after the step, m.
        """
        if reference_m is None:
            if not self.started:
                return self.x[1]
            mode = self.config.outage_mode
            if mode == "coast":
                self._propagate(self.u)
            elif mode == "extrapolate":
                self.u = 0.0
                self._propagate(0.0)
            else:
                self._dx = [0.0, 0.0, 0.0]
            return self.x[1]
        check_finite("reference_m", reference_m)
        if not self.started:
            self.started = True
            if self.config.warm_start:
                self.x = [0.0, reference_m, 0.0]
                self._dx = [0.0, 0.0, 0.0]
        if self.mpc.constrained:
            eta, res = self.mpc.solve(self._dx, self.x[1], reference_m, self.u)
            du = float(self.mpc.laguerre[0] @ eta)
            self.qp_active += int(res.active)
        else:
            du = self.mpc.first_move_fast(self._dx, self.x[1] - reference_m)
        self.u += du
        self._propagate(self.u)
        return self.x[1]
