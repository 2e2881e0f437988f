"""Error-state model of the NED strapdown INS: F, Phi and Q of a layout.

The error states and their layouts are defined in :mod:`fusion.state_layout` (re-exported
here, where most code imports them).

Sensor model: ``f~ = (I + diag(s_a) + M_a) f + b_a + w_a``,
``omega~ = (I + diag(s_g) + M_g) omega + b_g + w_g`` (``M`` zero on the diagonal; layouts
without the blocks hold ``s`` or ``M`` at zero).

The IMU's biases, scale factors and misalignments are a *random constant plus a random walk*,
``b' = w`` (F = 0 on their diagonal): a turn-on value the datasheet bounds (the initial
covariance, :mod:`fusion.alignment`) that stays until it is observed, plus the in-run
variation, whose driving noise is that of the datasheet's Gauss-Markov process
(``q = sigma^2 (1 - exp(-2 T / tau))``, :meth:`ErrorModel.process_noise`; a random walk with the
Gauss-Markov's driving noise matches it over times short against ``tau`` and is conservative
beyond). Modelling the whole bias as a Gauss-Markov process instead makes its covariance decay
from the turn-on sigma to the in-run one within ``tau`` (100 s for MEMS datasheets) whether or
not anything observed it: the filter then believes in a heading-gyro bias it never learned
(``docs/results.md``, "Consistency"). The baro bias and the GNSS position bias are zero-mean
processes, first-order Gauss-Markov, ``b' = -b / tau + w``.

Continuous error dynamics ``dx' = F dx + G w`` (Titterton & Weston ch. 12, Groves ch. 14.2,
same structure as KF-GINS ``gi_engine.cpp`` with our sign of ``phi``)::

    dr'   = F_rr dr + dv
    dv'   = F_vr dr + F_vv dv - [f_n×] phi - C_nb dba - C_nb diag(f_b) dsa - C_nb dM_a f_b
            + C_nb w_a
    phi'  = -(N_ie + N_en) dr - N_env dv - [omega_in_n×] phi - C_nb dbg - C_nb diag(omega_b) dsg
            - C_nb dM_g omega_b + C_nb w_g
    dba'  = w_ba                      (likewise dbg, dsa, dsg, dma, dmg, dbs)
    dbb'  = -dbb / tau_b + w_bb       (likewise db_gnss)
    dka'  = w_ka, dkg' = w_kg         (+therm; over a propagation interval in which the die
                                      temperature changed by dT: dba += dT dka, dbg += dT dkg,
                                      written into Phi by fusion.propagation)

with ``N_ie``, ``N_en`` the derivatives of ``omega_ie_n``, ``omega_en_n`` w.r.t. position error
and ``N_env`` that of ``omega_en_n`` w.r.t. velocity error; ``F_vr = [v×](2 N_ie + N_en) + dg``,
``F_vv = [v×] N_env - [(2 omega_ie + omega_en)×]``. Radius-of-curvature derivatives are
neglected (e^2-small). Every block is checked against a numerically propagated, perturbed INS in
``tests/test_error_model.py``.

After each measurement update the error estimate is moved into the INS and reset to zero
(:mod:`fusion.feedback`).
"""


from __future__ import annotations

import math
import os
import struct
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from fusion import earth
from fusion.state_layout import (
    AIR_LAYOUTS,
    INS16,
    INS16_GNSS,
    INS22,
    INS22_GNSS,
    INS35,
    INS35_GNSS,
    LAYOUTS,
    OFF_DIAGONAL,
    LayoutName,
    StateLayout,
    layout_for,
)

__all__ = [
    "AIR_LAYOUTS", "INS16", "INS16_GNSS", "INS22", "INS22_GNSS", "INS35", "INS35_GNSS", "KERNEL",
    "LAYOUTS", "OFF_DIAGONAL", "ErrorModel", "LayoutName", "ProcessNoise", "StateLayout",
    "layout_for",
]  # fmt: skip
from physconst.kernel import python_forced

FloatArray = NDArray[np.float64]

@dataclass(frozen=True)
class ProcessNoise:
    """Continuous-time noise and correlation times of the sensor error model, SI.

    ``gyro_noise`` / ``accel_noise`` are white-noise densities (rad/s/sqrt(Hz), m/s^2/sqrt(Hz)),
    the same on the three axes; ``*_sigma`` and ``*_tau_s`` are the steady-state standard
    deviations and correlation times of the Gauss-Markov processes: the baro and GNSS bias
    states follow them, the IMU error states are random walks with their driving noise.
    """

    gyro_noise: float
    accel_noise: float
    gyro_bias_sigma: float
    gyro_bias_tau_s: float
    accel_bias_sigma: float
    accel_bias_tau_s: float
    baro_bias_sigma: float
    baro_bias_tau_s: float
    gyro_scale_sigma: float = 0.0
    gyro_scale_tau_s: float = 3600.0
    accel_scale_sigma: float = 0.0
    accel_scale_tau_s: float = 3600.0
    gnss_bias_sigma_h_m: float = 0.0
    """GNSS position bias per horizontal axis, m (only layouts with the GNSS block)."""
    gnss_bias_sigma_v_m: float = 0.0
    gnss_bias_tau_h_s: float = 120.0
    gnss_bias_tau_v_s: float = 120.0
    gyro_misalignment_sigma: float = 0.0
    """Per off-diagonal entry, rad (only layouts with misalignment states); the correlation
    times are the scale factors'."""
    accel_misalignment_sigma: float = 0.0
    baro_scale_sigma: float = 0.0
    """Random-walk driving of the baro scale factor: its sigma over ``baro_scale_tau_s``
    (only layouts with the state)."""
    baro_scale_tau_s: float = 3600.0
    wind_noise_mps2_rthz: float = 0.05
    """Wind random-walk driving noise in level flight, m/s^2/sqrt(Hz) (PX4 EKF2_WIND_NSD)."""
    wind_climb_scaler_spm: float = 0.5
    """The wind noise is multiplied by ``1 + scaler |climb rate|`` (s/m; EKF2's
    ``wind_vel_nsd_scaler``): a climbing aircraft flies through the wind profile."""
    gyro_tempco_walk: float = 0.0
    """Random-walk density of the gyro temperature coefficients, (rad/s/K)^2/s (``+therm``
    layouts)."""
    accel_tempco_walk: float = 0.0
    """Random-walk density of the accelerometer temperature coefficients, (m/s^2/K)^2/s."""
    airspeed_scale_noise_rthz: float = 1e-4
    """Airspeed scale random-walk driving noise, 1/sqrt(s) (PX4 WEST_SC_P_NOISE)."""
    gust_sigma_mps: float = 1.5
    """Steady-state sigma of the horizontal gust per axis, m/s."""
    gust_length_m: float = 300.0
    """Gust correlation length, m: correlation time ``gust_length_m / airspeed``."""


class ErrorModel:
    """F, Phi and Q for one layout and one noise model.

    The variable entries of F are written into a preallocated matrix through one fancy-index
    assignment (about 60 floats computed in plain Python), which is what keeps the covariance
    propagation cheap enough for 100 Hz in pure Python.

    Parameters
    ----------
    layout : StateLayout
    noise : ProcessNoise
    """

    def __init__(self, layout: StateLayout, noise: ProcessNoise) -> None:
        self.layout = layout
        self.noise = noise
        n = layout.n
        self._eye = np.eye(n)
        f0 = np.zeros((n, n))
        p, v = layout.POS, layout.VEL
        for i in range(3):
            f0[p + i, v + i] = 1.0
        self._taus = self._gm_taus()
        for idx, tau in self._taus:
            f0[idx, idx] = -1.0 / tau
        self._f0 = f0
        self._var_idx = self._variable_indices()
        n_var = len(self._var_idx)
        self._var_buf = np.empty(n_var)
        self._var_raw: Any = self._var_buf  # the same array, as the writable buffer pack_into takes
        self._pack_var = struct.Struct(f"{n_var}d").pack_into
        self._q_cache: dict[float, FloatArray] = {}
        self._phi_base: dict[float, FloatArray] = {}

    # --- layout-dependent index bookkeeping -------------------------------------------------
    def _gm_taus(self) -> list[tuple[int, float]]:
        """The Gauss-Markov states and their correlation times (the IMU error states are
        random constants plus random walks: not listed, F = 0 on their diagonal)."""
        lay, nz = self.layout, self.noise
        out = [(lay.BARO, nz.baro_bias_tau_s)]
        if lay.has_gnss_bias:
            g = lay.GNSS
            out += [(g, nz.gnss_bias_tau_h_s), (g + 1, nz.gnss_bias_tau_h_s),
                    (g + 2, nz.gnss_bias_tau_v_s)]  # fmt: skip
        return out

    def _variable_indices(self) -> NDArray[np.intp]:
        lay = self.layout
        p, v, a, ba, bg = lay.POS, lay.VEL, lay.ATT, lay.BA, lay.BG
        rows: list[int] = []
        cols: list[int] = []

        def block(r0: int, c0: int, entries: list[tuple[int, int]]) -> None:
            for i, j in entries:
                rows.append(r0 + i)
                cols.append(c0 + j)

        full = [(i, j) for i in range(3) for j in range(3)]
        off = [(0, 1), (0, 2), (1, 0), (1, 2), (2, 0), (2, 1)]
        cols02 = [(i, j) for i in range(3) for j in (0, 2)]
        block(p, p, [(0, 0), (0, 2), (1, 0), (1, 1), (1, 2)])  # F_rr
        block(v, p, cols02)  # F_vr
        block(v, v, full)  # F_vv
        block(v, a, off)  # F_vphi
        block(v, ba, full)  # F_v,ba
        block(a, p, cols02)  # F_phi,r
        block(a, v, [(0, 1), (1, 0), (2, 1)])  # F_phi,v
        block(a, a, off)  # F_phi,phi
        block(a, bg, full)  # F_phi,bg
        if lay.has_scale_factors:
            block(v, lay.SA, full)  # C_nb diag(f_b)
            block(a, lay.SG, full)  # C_nb diag(omega_b)
        if lay.has_misalignment:
            rows6 = [(i, j) for i in range(3) for j in range(6)]
            block(v, lay.MA, rows6)  # C_nb dM_a f_b
            block(a, lay.MG, rows6)  # C_nb dM_g omega_b
        return np.ravel_multi_index((np.array(rows), np.array(cols)), (lay.n, lay.n))

    # --- F -----------------------------------------------------------------------------------
    def _fill(
        self,
        lat_rad: float,
        alt_m: float,
        v_ned_mps: tuple[float, float, float],
        c_nb: tuple[float, ...],
        f_n_mps2: tuple[float, float, float],
        f_b_mps2: tuple[float, float, float],
        omega_ib_b_rps: tuple[float, float, float],
        k: float,
        one: float,
        terms: earth.LocalTerms | None = None,
    ) -> list[float]:
        """The variable entries of ``k F + one I`` in the order of ``self._var_idx`` (``k = 1``,
        ``one = 0``: F itself; ``k = dt``, ``one = 1``: the first-order transition, scaled here
        on a few base quantities rather than by a loop over 60 entries).

        Parameters
        ----------
        lat_rad, alt_m : float
            Position of the INS.
        v_ned_mps : 3 floats
            INS velocity, m/s.
        c_nb : 9 floats
            ``C_nb`` row-major.
        f_n_mps2 : 3 floats
            Specific force in NED (mean over the propagation interval), m/s^2.
        f_b_mps2, omega_ib_b_rps : 3 floats
            Mean body specific force and angular rate; used only by the scale-factor and
            misalignment blocks.
        k, one : float
            Scale of F and the value added on its diagonal.
        terms : LocalTerms, optional
            ``earth.local_terms(lat_rad, alt_m)`` if the caller has it already.
        """
        t = terms if terms is not None else earth.local_terms(lat_rad, alt_m)
        rn, re = t.rho_n_m, t.rho_e_m
        s, c = t.sin_lat, t.cos_lat
        tan = s / c
        sec2 = 1.0 / (c * c)
        vn, ve, vd = v_ned_mps
        fn, fe, fd = f_n_mps2
        om = earth.RATE
        dg_dlat, dg_dh = earth.gravity_gradient(lat_rad, alt_m)
        # Earth / transport rates and their derivatives w.r.t. dr_N (col 0) and dr_D (col 2)
        wie_n, wie_d = om * c, -om * s
        wen_n, wen_e, wen_d = ve / re, -vn / rn, -ve * tan / re
        # d omega_ie / d dr_N ; d omega_en / d dr_N ; d omega_en / d dr_D
        die_n0, die_d0 = -om * s / rn, -om * c / rn
        den_d0 = -ve * sec2 / (re * rn)
        den_n2, den_e2, den_d2 = ve / (re * re), -vn / (rn * rn), -ve * tan / (re * re)
        # W = 2 N_ie + N_en (columns 0 and 2), rows n, e, d
        w_n0, w_e0, w_d0 = 2.0 * die_n0, 0.0, 2.0 * die_d0 + den_d0
        w_n2, w_e2, w_d2 = den_n2, den_e2, den_d2
        # [v×] W : row i = (v × W_col)_i
        fvr_00 = ve * w_d0 - vd * w_e0
        fvr_10 = vd * w_n0 - vn * w_d0
        fvr_20 = vn * w_e0 - ve * w_n0 + dg_dlat / rn
        fvr_02 = ve * w_d2 - vd * w_e2
        fvr_12 = vd * w_n2 - vn * w_d2
        fvr_22 = vn * w_e2 - ve * w_n2 - dg_dh
        # F_vv = [v×] N_env - [c×], c = 2 omega_ie + omega_en,
        # N_env = [[0, a01, 0], [a10, 0, 0], [0, a21, 0]] (d omega_en / d dv)
        cx, cy, cz = 2.0 * wie_n + wen_n, wen_e, 2.0 * wie_d + wen_d
        a01, a10, a21 = 1.0 / re, -1.0 / rn, -tan / re
        fvv_00, fvv_01, fvv_02 = -vd * a10, ve * a21 + cz, -cy
        fvv_10, fvv_11, fvv_12 = -cz, vd * a01 - vn * a21, cx
        fvv_20, fvv_21, fvv_22 = vn * a10 + cy, -ve * a01 - cx, 0.0
        # -C_nb, f_n, omega_in and N_env pre-scaled by k
        m = -k
        c00, c01, c02 = m * c_nb[0], m * c_nb[1], m * c_nb[2]
        c10, c11, c12 = m * c_nb[3], m * c_nb[4], m * c_nb[5]
        c20, c21, c22 = m * c_nb[6], m * c_nb[7], m * c_nb[8]
        fn, fe, fd = k * fn, k * fe, k * fd
        win_n, win_e, win_d = k * (wie_n + wen_n), k * wen_e, k * (wie_d + wen_d)
        a01, a10, a21 = k * a01, k * a10, k * a21
        vals = [
            # F_rr
            -vd / rn * k + one, vn / rn * k,
            ve * tan / rn * k, -(vd / re + vn * tan / rn) * k + one, ve / re * k,
            # F_vr (cols 0, 2)
            fvr_00 * k, fvr_02 * k, fvr_10 * k, fvr_12 * k, fvr_20 * k, fvr_22 * k,
            # F_vv
            fvv_00 * k + one, fvv_01 * k, fvv_02 * k,
            fvv_10 * k, fvv_11 * k + one, fvv_12 * k,
            fvv_20 * k, fvv_21 * k, fvv_22 * k + one,
            # F_vphi = -[f_n×] (off-diagonal: (0,1), (0,2), (1,0), (1,2), (2,0), (2,1))
            fd, -fe, -fd, fn, fe, -fn,
            # F_v,ba = -C_nb
            c00, c01, c02, c10, c11, c12, c20, c21, c22,
            # F_phi,r = -(N_ie + N_en) (cols 0, 2)
            -die_n0 * k, -den_n2 * k, 0.0, -den_e2 * k, -(die_d0 + den_d0) * k, -den_d2 * k,
            # F_phi,v = -N_env
            -a01, -a10, -a21,
            # F_phi,phi = -[omega_in×]
            win_d, -win_e, -win_d, win_n, win_e, -win_n,
            # F_phi,bg = -C_nb
            c00, c01, c02, c10, c11, c12, c20, c21, c22,
        ]  # fmt: skip
        if self.layout.has_scale_factors:
            # -C_nb diag(f_b)
            fx, fy, fz = f_b_mps2
            vals += [
                c00 * fx, c01 * fy, c02 * fz,
                c10 * fx, c11 * fy, c12 * fz,
                c20 * fx, c21 * fy, c22 * fz,
            ]  # fmt: skip
            # -C_nb diag(omega_b)
            wx, wy, wz = omega_ib_b_rps
            vals += [
                c00 * wx, c01 * wy, c02 * wz,
                c10 * wx, c11 * wy, c12 * wz,
                c20 * wx, c21 * wy, c22 * wz,
            ]  # fmt: skip
        if self.layout.has_misalignment:
            # -C_nb dM f: d(row r)/d m_ij = -C_nb[r, i] * f_j, entries in OFF_DIAGONAL order
            for x, y, z in (f_b_mps2, omega_ib_b_rps):
                vals += [
                    c00 * y, c00 * z, c01 * x, c01 * z, c02 * x, c02 * y,
                    c10 * y, c10 * z, c11 * x, c11 * z, c12 * x, c12 * y,
                    c20 * y, c20 * z, c21 * x, c21 * z, c22 * x, c22 * y,
                ]  # fmt: skip
        return vals

    def continuous_matrix(
        self,
        lat_rad: float,
        alt_m: float,
        v_ned_mps: tuple[float, float, float],
        c_nb: tuple[float, ...],
        f_n_mps2: tuple[float, float, float],
        f_b_mps2: tuple[float, float, float] = (0.0, 0.0, 0.0),
        omega_ib_b_rps: tuple[float, float, float] = (0.0, 0.0, 0.0),
    ) -> FloatArray:
        """Continuous error-dynamics matrix ``F`` (n, n) at one operating point.

        Parameters
        ----------
        lat_rad, alt_m : float
            Position of the INS.
        v_ned_mps : 3 floats
            INS velocity, m/s.
        c_nb : 9 floats
            ``C_nb`` row-major.
        f_n_mps2 : 3 floats
            Specific force in NED (mean over the propagation interval), m/s^2.
        f_b_mps2, omega_ib_b_rps : 3 floats
            Mean body specific force and angular rate; used only by the scale-factor and
            misalignment blocks.

        Returns
        -------
        ndarray, shape (n, n)
        """
        f = self._f0.copy()
        f.put(
            self._var_idx,
            self._fill(
                lat_rad, alt_m, v_ned_mps, c_nb, f_n_mps2, f_b_mps2, omega_ib_b_rps, 1.0, 0.0
            ),
        )
        return f

    def first_order_transition(
        self,
        lat_rad: float,
        alt_m: float,
        v_ned_mps: tuple[float, float, float],
        c_nb: tuple[float, ...],
        f_n_mps2: tuple[float, float, float],
        dt_s: float,
        f_b_mps2: tuple[float, float, float] = (0.0, 0.0, 0.0),
        omega_ib_b_rps: tuple[float, float, float] = (0.0, 0.0, 0.0),
        terms: earth.LocalTerms | None = None,
        *,
        scratch: bool = False,
    ) -> FloatArray:
        """``Phi = I + F T`` built in place (the filter's per-propagation path, P0's
        ``Phi ≈ I + F Ts``); same arguments as :meth:`continuous_matrix` plus ``dt_s``.
        The neglected ``(F T)^2 / 2`` is ~1e-3 of the first-order terms at 100 Hz.

        With ``scratch`` the returned matrix is this model's cached one for ``dt_s`` (no
        copy), overwritten by the next call with the same ``dt_s``: for a caller that uses it
        at once and drops it (:meth:`fusion.propagation.CovariancePropagator.propagate`).
        Every call writes all the variable entries, so the values never depend on an earlier
        call."""
        base = self._phi_base.get(dt_s)
        if base is None:
            base = self._eye + self._f0 * dt_s
            if len(self._phi_base) < 64:
                self._phi_base[dt_s] = base
        phi = base if scratch else base.copy()
        if terms is None:
            terms = earth.local_terms(lat_rad, alt_m)  # as the reference's first line does
        if _kernel is not None:
            # the compiled _fill (fusion/_update.c), written straight into phi; it declines
            # (False, phi untouched) where the reference would raise or meets non-float input
            try:
                dg = earth.gravity_gradient(lat_rad, alt_m)
            except Exception:  # the reference below raises it again, at its own place
                dg = None
            lay = self.layout
            if dg is not None and _kernel.transition_fill(
                phi, self._var_idx, terms, dg, v_ned_mps, c_nb, f_n_mps2, f_b_mps2,
                omega_ib_b_rps, dt_s, 1.0, lay.has_scale_factors, lay.has_misalignment,
            ):  # fmt: skip
                return phi
        vals = self._fill(
            lat_rad, alt_m, v_ned_mps, c_nb, f_n_mps2, f_b_mps2, omega_ib_b_rps, dt_s, 1.0, terms
        )
        # put() replaces the identity on the diagonal entries of F: _fill adds it back
        # (the floats packed as C doubles into a preallocated buffer: the same float64 values,
        # half the instructions of np.fromiter over the list)
        self._pack_var(self._var_raw, 0, *vals)
        phi.put(self._var_idx, self._var_buf)
        return phi

    def air_process_noise(
        self, dt_s: float, climb_rate_mps: float, level: float = 1.0, climb: float = 1.0,
        scale: float = 1.0,
    ) -> tuple[float, float]:  # fmt: skip
        """Discrete process noise of the air-data block over ``dt_s`` (layouts with it, once
        active): ``(q_wind per axis, q_scale)``, m^2/s^2 and dimensionless.

        ``q_wind = (nsd (level + climb scaler |climb rate|))^2 T`` (PX4 EKF2's wind random
        walk), ``q_scale = scale^2 nsd_k^2 T``; ``level``, ``climb`` and ``scale`` are factors
        on the level-flight and the climb-driven wind noise and on the scale noise (1 in
        turbulence; still air and the outage hold of :class:`fusion.config.AirspeedTuning`
        lower them, :meth:`fusion.aiding.airspeed.AirspeedAiding.noise_factors`).
        """
        nz = self.noise
        w = nz.wind_noise_mps2_rthz * (
            level + climb * nz.wind_climb_scaler_spm * abs(climb_rate_mps))
        k = scale * nz.airspeed_scale_noise_rthz
        return w * w * dt_s, k * k * dt_s

    def gust_transition(
        self, dt_s: float, airspeed_mps: float, sigma_mps: float | None = None
    ) -> tuple[float, float]:
        """The gust block over ``dt_s`` at ``airspeed_mps``: ``(phi, q)``, the Gauss-Markov
        decay ``exp(-T V / L)`` and the discrete driving variance ``sigma^2 (1 - phi^2)``
        per axis (m^2/s^2); the airspeed is floored at 1 m/s. ``sigma_mps``: the gust sigma
        (default the noise model's ``gust_sigma_mps``; the filter's turbulence estimate)."""
        nz = self.noise
        phi = math.exp(-dt_s * max(airspeed_mps, 1.0) / nz.gust_length_m)
        s = nz.gust_sigma_mps if sigma_mps is None else sigma_mps
        return phi, s * s * (1.0 - phi * phi)

    def add_process_noise(
        self, P: FloatArray, dt_s: float, air_offset: int | None = None, q_wind: float = 0.0,
        q_scale: float = 0.0, gust_phi: float = 1.0, q_gust: float = 0.0,
    ) -> None:  # fmt: skip
        """``P += Q_d`` in place (:meth:`process_noise`), and with the air-data block active
        (``air_offset``) its process noise (:meth:`air_process_noise`: ``q_wind`` on the three
        wind entries, ``q_scale`` on the scale) and the gust block's
        Gauss-Markov step (:meth:`gust_transition`: its rows and columns times ``gust_phi``, then
        ``q_gust`` on its diagonal).

        Parameters
        ----------
        P : ndarray, shape (n, n)
            Covariance after ``Phi P Phi^T``, modified in place.
        dt_s : float
            Propagation interval, s.
        air_offset : int, optional
            Offset of the active air-data block; ``None``: dormant or absent.
        q_wind, q_scale, gust_phi, q_gust : float
            The air block's increments over ``dt_s`` (unused without ``air_offset``).
        """
        Q = self.process_noise(dt_s)
        if _kernel is not None and _kernel.add_process_noise(
            P, Q, -1 if air_offset is None else air_offset, q_wind, q_scale, gust_phi, q_gust
        ):
            return  # the compiled loop below, element by element (fusion/_update.c)
        # P = P + Q  (Q diagonal: white sensor noise and Gauss-Markov driving noise)
        P += Q
        a = air_offset
        if a is not None:
            # wind random walk, airspeed scale random walk
            P[a, a] += q_wind
            P[a + 1, a + 1] += q_wind
            P[a + 2, a + 2] += q_scale
            # gusts: first-order Gauss-Markov, P_gg <- phi P_gg phi + q
            g = a + 3
            P[g : g + 2, :] *= gust_phi
            P[:, g : g + 2] *= gust_phi
            P[g, g] += q_gust
            P[g + 1, g + 1] += q_gust

    def transition_matrix(self, f: FloatArray, dt_s: float) -> FloatArray:
        """Discrete transition ``Phi = I + F T + (F T)^2 / 2`` (second-order Taylor series)."""
        ft = f * dt_s
        return self._eye + ft + 0.5 * (ft @ ft)

    def process_noise(self, dt_s: float) -> FloatArray:
        """Discrete process noise ``Q_d`` (n, n), diagonal, for an interval ``dt_s``.

        White sensor noise enters velocity and attitude as ``C_nb w``; with the same density on
        the three axes ``C_nb (q I) C_nb^T = q I``, so ``Q_d`` does not depend on the attitude:
        ``q_vel = accel_noise^2 T``, ``q_att = gyro_noise^2 T``; Gauss-Markov states get their
        exact discrete variance ``sigma^2 (1 - exp(-2 T / tau))``, and the IMU's random-walk
        states the same increment (the driving noise of the datasheet's Gauss-Markov
        process). Cached per ``dt`` (treat the
        returned array as read-only).
        """
        cached = self._q_cache.get(dt_s)
        if cached is not None:
            return cached
        lay, nz = self.layout, self.noise
        q = np.zeros(lay.n)
        q[lay.vel] = nz.accel_noise**2 * dt_s
        q[lay.att] = nz.gyro_noise**2 * dt_s

        def gm(sigma: float, tau: float) -> float:
            return sigma * sigma * (1.0 - math.exp(-2.0 * dt_s / tau))

        q[lay.ba] = gm(nz.accel_bias_sigma, nz.accel_bias_tau_s)
        q[lay.bg] = gm(nz.gyro_bias_sigma, nz.gyro_bias_tau_s)
        q[lay.baro] = gm(nz.baro_bias_sigma, nz.baro_bias_tau_s)
        if lay.has_scale_factors:
            q[lay.sa] = gm(nz.accel_scale_sigma, nz.accel_scale_tau_s)
            q[lay.sg] = gm(nz.gyro_scale_sigma, nz.gyro_scale_tau_s)
        if lay.has_misalignment:
            q[lay.ma] = gm(nz.accel_misalignment_sigma, nz.accel_scale_tau_s)
            q[lay.mg] = gm(nz.gyro_misalignment_sigma, nz.gyro_scale_tau_s)
        if lay.has_baro_scale:
            q[lay.bs] = gm(nz.baro_scale_sigma, nz.baro_scale_tau_s)
        if lay.has_thermal:
            q[lay.KA : lay.KA + 3] = nz.accel_tempco_walk * dt_s
            q[lay.KG : lay.KG + 3] = nz.gyro_tempco_walk * dt_s
        if lay.has_gnss_bias:
            g = lay.GNSS
            q[g] = q[g + 1] = gm(nz.gnss_bias_sigma_h_m, nz.gnss_bias_tau_h_s)
            q[g + 2] = gm(nz.gnss_bias_sigma_v_m, nz.gnss_bias_tau_v_s)
        qd = np.diag(q)
        if len(self._q_cache) < 64:
            self._q_cache[dt_s] = qd
        return qd


# ---- compiled kernel -----------------------------------------------------------------------
# fusion/_update.c is ErrorModel._fill (writing Phi's variable entries in place) and the
# element loops of ErrorModel.add_process_noise in C, operation for operation (built by
# `pip install` when a C compiler is there; docs/development.md, "Compiled kernels"). Its
# results are bit
# for bit the reference's (tests/fusion/test_update_kernel.py). One difference off the numbers:
# numpy's in-place lines warn on an overflow or NaN they produce, the loop does not.
def _load_kernel() -> Any:
    try:
        from fusion import _update
    except ImportError:  # built without a C compiler: the Python reference, same numbers
        return None
    _update.bind(earth.LocalTerms, earth.RATE)
    return _update


_compiled = _load_kernel()  # bound even when not used (tests compare it with the reference)
_kernel = None if python_forced(os.environ) else _compiled
#: Which implementation fills the first-order transition and adds the process noise: ``"c"``
#: (fusion/_update.c) or ``"python"`` (:meth:`ErrorModel._fill`, :meth:`ErrorModel.
#: add_process_noise`'s numpy lines; no compiler at install time, or
#: ``HILNAV_KERNEL=python``).
KERNEL = "python" if _kernel is None else "c"
