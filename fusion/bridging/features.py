"""Bridging features: the base quantities of one training pair or prediction epoch, and the
network inputs computed from them.

Inputs (``BridgeConfig.features``; a pair is (elapsed ``t``, the INS features at the outage's
start, the INS features now)):

``t``, ``t2``, ``t3``
    time since the (virtual) outage start and its powers, s, s^2, s^3;
``fn``, ``fe``, ``fd``
    specific force in NED, m/s^2; ``sinpsi``, ``cospsi``: heading now; ``sinpsi0``,
    ``cospsi0``: heading at the start; ``roll``, ``pitch``, rad;
``vn``, ``ve``, ``vd``
    velocity, m/s; ``wx``, ``wy``, ``wz``: body rate, rad/s;
``dn``, ``de``, ``dvn``, ``dve``
    horizontal displacement (m) and velocity change (m/s) since the start;
``bax`` … ``bgz``
    the filter's accelerometer (m/s^2) and gyro (rad/s) bias estimates;
``own``, ``own_rel``, ``own_rate``
    the corrected component's own INS value (P0's input: position N/E/D from a fixed origin,
    or velocity), the same relative to the start, and its rate (velocity for a position
    component, specific force plus gravity for a velocity component; P2's epoch-to-epoch
    difference per second).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from fusion import earth
from fusion.bridging.interface import BridgeEpoch
from fusion.config import BRIDGE_FEATURES
from physconst import G0_MPS2

FloatArray = NDArray[np.float64]

# Every training pair and prediction epoch is first reduced to one row of these quantities;
# features are columns of it (or sin / cos / powers of a column).
(COL_T, _FN, _FE, _FD, _PSI, _PSI0, _ROLL, _PITCH, _VN, _VE, _VD, _WX, _WY, _WZ,
 _DN, _DE, _DVN, _DVE) = range(18)  # fmt: skip
_BA = 18
_BG = 21
_OWN = 24  # 6 columns: position N/E/D from the origin, velocity N/E/D
_OWN_REL = 30  # 6: position change N/E/D since the start, velocity change
_OWN_RATE = 36  # 6: velocity N/E/D, specific force + gravity N/E/D
BASE_COLUMNS = 42

_SIMPLE: dict[str, tuple[str, int]] = {
    "t": ("id", COL_T), "t2": ("sq", COL_T), "t3": ("cube", COL_T),
    "fn": ("id", _FN), "fe": ("id", _FE), "fd": ("id", _FD),
    "sinpsi": ("sin", _PSI), "cospsi": ("cos", _PSI),
    "sinpsi0": ("sin", _PSI0), "cospsi0": ("cos", _PSI0),
    "roll": ("id", _ROLL), "pitch": ("id", _PITCH),
    "vn": ("id", _VN), "ve": ("id", _VE), "vd": ("id", _VD),
    "wx": ("id", _WX), "wy": ("id", _WY), "wz": ("id", _WZ),
    "dn": ("id", _DN), "de": ("id", _DE), "dvn": ("id", _DVN), "dve": ("id", _DVE),
    "bax": ("id", _BA), "bay": ("id", _BA + 1), "baz": ("id", _BA + 2),
    "bgx": ("id", _BG), "bgy": ("id", _BG + 1), "bgz": ("id", _BG + 2),
}  # fmt: skip
_PER_COMPONENT = {"own": _OWN, "own_rel": _OWN_REL, "own_rate": _OWN_RATE}
assert set(_SIMPLE) | set(_PER_COMPONENT) == set(BRIDGE_FEATURES)

Spec = tuple[tuple[str, int], ...]


def feature_spec(names: tuple[str, ...], component: int) -> Spec:
    """``(operation, base column)`` per feature for one component (0..5, :data:`COMPONENTS`).

    Raises
    ------
    ValueError
        For a name not in :data:`fusion.config.BRIDGE_FEATURES` or a bad component.
    """
    if not 0 <= component < 6:
        raise ValueError(f"component must be 0..5, got {component}")
    out: list[tuple[str, int]] = []
    for n in names:
        if n in _SIMPLE:
            out.append(_SIMPLE[n])
        elif n in _PER_COMPONENT:
            out.append(("id", _PER_COMPONENT[n] + component))
        else:
            raise ValueError(f"unknown feature {n!r}; valid: {', '.join(BRIDGE_FEATURES)}")
    return tuple(out)


def features_row(base: list[float], spec: Spec) -> list[float]:
    """Features of one base row (plain floats: the prediction path runs per outage epoch)."""
    out = []
    for op, col in spec:
        x = base[col]
        if op == "id":
            out.append(x)
        elif op == "sin":
            out.append(math.sin(x))
        elif op == "cos":
            out.append(math.cos(x))
        elif op == "sq":
            out.append(x * x)
        else:
            out.append(x * x * x)
    return out


_SCALAR_OPS: dict[str, Callable[[float], float]] = {
    "id": lambda x: x,
    "sin": math.sin,
    "cos": math.cos,
    "sq": lambda x: x * x,
    "cube": lambda x: x * x * x,
}


def compile_features(
    spec: Spec, lo: list[float], hi: list[float]
) -> Callable[[list[float]], list[float]]:
    """:func:`features_row` followed by clipping to ``[lo, hi]``, as one function of a base
    row (the prediction path of a fitted candidate; same operations as :func:`features_row`).

    Parameters
    ----------
    spec : Spec
        ``(operation, base column)`` per feature (:func:`feature_spec`).
    lo, hi : list of float
        Per-feature bounds (the training range).

    Returns
    -------
    callable ``(base row) -> list of float``
    """
    terms = tuple(
        (_SCALAR_OPS[op], int(col), float(a), float(b))
        for (op, col), a, b in zip(spec, lo, hi, strict=True)
    )

    def features(base: list[float]) -> list[float]:
        return [min(max(op(base[col]), a), b) for op, col, a, b in terms]

    return features


def features_matrix(B: FloatArray, spec: Spec) -> FloatArray:
    """Features of many base rows ``B`` (n, 42) -> (n, len(spec)); same values as
    :func:`features_row` row by row."""
    cols = []
    for op, col in spec:
        x = B[:, col]
        if op == "id":
            cols.append(x)
        elif op == "sin":
            cols.append(np.sin(x))
        elif op == "cos":
            cols.append(np.cos(x))
        elif op == "sq":
            cols.append(x * x)
        else:
            cols.append(x * x * x)
    return np.column_stack(cols)


class Origin:
    """Local tangent origin for the ``own`` features (the first epoch a strategy sees)."""

    __slots__ = ("alt", "ke", "kn", "lat", "lon")

    def __init__(self, epoch: BridgeEpoch) -> None:
        lt = earth.local_terms(epoch.lat_rad, epoch.alt_msl_m)
        self.lat, self.lon, self.alt = epoch.lat_rad, epoch.lon_rad, epoch.alt_msl_m
        self.kn, self.ke = lt.rho_n_m, lt.rho_e_m * lt.cos_lat


def base_row(t: float, start: BridgeEpoch, ep: BridgeEpoch, origin: Origin) -> list[float]:
    """The 42 base quantities of one pair (see the module docstring for the features)."""
    kn, ke = origin.kn, origin.ke
    v, v0, f = ep.v_ned_mps, start.v_ned_mps, ep.f_n_mps2
    dn = (ep.lat_rad - start.lat_rad) * kn
    de = (ep.lon_rad - start.lon_rad) * ke
    dd = start.alt_msl_m - ep.alt_msl_m
    roll, pitch, yaw = ep.euler_rad
    w, ba, bg = ep.omega_ib_b_rps, ep.accel_bias_b_mps2, ep.gyro_bias_b_rps
    return [
        t, f[0], f[1], f[2], yaw, start.euler_rad[2], roll, pitch,
        v[0], v[1], v[2], w[0], w[1], w[2],
        dn, de, v[0] - v0[0], v[1] - v0[1],
        ba[0], ba[1], ba[2], bg[0], bg[1], bg[2],
        (ep.lat_rad - origin.lat) * kn, (ep.lon_rad - origin.lon) * ke,
        origin.alt - ep.alt_msl_m, v[0], v[1], v[2],
        dn, de, dd, v[0] - v0[0], v[1] - v0[1], v[2] - v0[2],
        v[0], v[1], v[2], f[0], f[1], f[2] + G0_MPS2,
    ]  # fmt: skip
