"""The error states of the NED strapdown INS and their named layouts.

Error definitions (every error is *estimated minus true*):

- ``dr`` (POS): position error in metres North / East / Down,
  ``dr = [(L^ - L)(R_M + h), (l^ - l)(R_N + h) cos L, -(h^ - h)]``;
- ``dv`` (VEL): ``v^_n - v_n``, m/s;
- ``phi`` (ATT): attitude error in the n frame, ``C^_nb = (I + [phi×]) C_nb`` (the small rotation
  that takes the true attitude to the estimate), rad;
- ``dba`` (BA), ``dbg`` (BG): accelerometer / gyro bias errors in the body frame, m/s^2, rad/s;
- ``dbb`` (BARO): barometric height bias error, m (see :mod:`fusion.aiding.baro`);
- optional ``dsa`` (SA) / ``dsg`` (SG): accelerometer / gyro scale-factor errors (dimensionless);
- optional ``dma`` (MA) / ``dmg`` (MG): accelerometer / gyro misalignment (cross-axis
  coupling, non-orthogonality) errors, the six off-diagonal entries ``m_ij`` (output axis
  ``i``, input axis ``j``) in the order :data:`OFF_DIAGONAL` (dimensionless, rad);
- optional ``dbs`` (BS): barometric scale-factor error (dimensionless): a non-standard
  atmosphere makes the ISA pressure height change by ``(1 + s)`` times the true height change
  (paper P4's scale; about 7 % for a day 20 K off ISA), ``h_baro = h + b + s (h - h_ref)``
  (:mod:`fusion.aiding.baro`); it does not enter the INS dynamics;
- optional ``db_gnss`` (GNSS): error of the estimated time-correlated GNSS position error
  (receiver "bias": atmosphere, orbit, multipath), North / East / Down, m; it does not enter the
  INS dynamics, only the GNSS position measurement (see :mod:`fusion.aiding.gnss`);
- optional ``dw`` (WIND), ``dk`` (ASPD_SCALE) and ``dg`` (GUST), the ``+air`` block:
  horizontal mean-wind error North / East, m/s, the airspeed scale-factor error
  (dimensionless, ``TAS_measured = (1 + k) |v - w - g|``, :mod:`fusion.aiding.airspeed`) and
  the horizontal gust error North / East, m/s; they do not enter the INS dynamics.
  The mean wind is a random walk whose driving noise grows with the climb rate (PX4 EKF2:
  ``EKF2_WIND_NSD`` = 0.05 m/s^2/sqrt(Hz) times ``1 + 0.5 |dh/dt|``: wind changes with
  height), the scale a random constant plus a small random walk (PX4's wind estimator,
  ``WEST_SC_P_NOISE`` = 1e-4). The gust is turbulence: a first-order Gauss-Markov process
  per axis with sigma ``gust_sigma_mps`` and correlation time ``L / V`` (the Dryden
  longitudinal scale length over the airspeed, MIL-F-8785C; ``L`` = 1000 ft at 1000 ft
  above ground). Without it a random-walk wind cannot follow a gust, and the scale state
  absorbs what the wind cannot: the ground speed varies with every along-track gust while the
  autopilot holds the airspeed, so fitting ``TAS = (1 + k) |v - w|`` regresses the airspeed on
  a noisy ground speed and drives ``k`` down (measured on a JSBSim cruise in turbulence 0.36:
  ``k`` = -0.19 and the along-track wind 10 m/s off after four minutes of GNSS; with the gust
  states it stays near zero: ``tests/integration/test_air_data_turbulence.py``). PX4 and
  ArduPilot do not estimate the scale in their EKFs (it is calibrated apart), so they do not
  meet this. The block is *dormant* until air data
  starts it: zero
  covariance rows and columns and no process noise (:meth:`ErrorModel.air_process_noise` is
  added by :class:`fusion.propagation.CovariancePropagator` only once the filter activated
  it), so a stream without air data navigates as the same layout without the block.

- optional ``dka`` (KA) / ``dkg`` (KG), the ``+therm`` block: error of the linear temperature
  coefficient of each accelerometer / gyro bias axis, m/s^2/K and rad/s/K (``--thermal
  states``): the bias is ``b0 + k (T - T_ref)``, so it moves by ``k dT`` when the die
  temperature changes by ``dT``; the filter moves its bias estimate by ``k^ dT`` and the
  transition couples the blocks, ``dbg <- dbg + dT dkg`` (:mod:`fusion.propagation`). The
  coefficients are random walks.

The dynamics of these errors (F, Phi, Q) are in :mod:`fusion.error_model`.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import Literal, cast

LayoutName = Literal[
    "ins16", "ins16+gnss", "ins22", "ins22+gnss", "ins35", "ins35+gnss",
    "ins16+air", "ins16+gnss+air", "ins22+air", "ins22+gnss+air", "ins35+air", "ins35+gnss+air",
]  # fmt: skip
"""Names of the error-state layouts (:func:`layout_for`)."""

OFF_DIAGONAL: tuple[tuple[int, int], ...] = ((0, 1), (0, 2), (1, 0), (1, 2), (2, 0), (2, 1))
"""Order of the six misalignment entries ``m_ij`` (output axis ``i``, input axis ``j``) in the
MA / MG blocks: ``f~_i += m_ij f_j``."""


@dataclass(frozen=True)
class StateLayout:
    """Named offsets of the error-state blocks (the only place that knows them).

    Use the slices (``layout.pos``, ``layout.att`` ...) instead of bare numbers; ``None`` means
    the block is not in this layout (:attr:`has_scale_factors`, :attr:`has_misalignment`,
    :attr:`has_gnss_bias` say which optional blocks are present). Six layouts exist:
    :data:`INS16`, :data:`INS22`, :data:`INS35` and the same three with the GNSS
    position-bias block appended (:data:`INS16_GNSS`, :data:`INS22_GNSS`, :data:`INS35_GNSS`);
    :func:`layout_for` picks one by name, and the name always says which blocks are present.
    The offsets and ``has_*`` flags are computed once per layout (``cached_property``: the
    filter reads them at every update).
    """

    name: LayoutName
    n: int
    pos: slice
    vel: slice
    att: slice
    ba: slice
    bg: slice
    baro: slice
    sa: slice | None
    sg: slice | None
    labels: tuple[str, ...]
    gnss: slice | None = None
    ma: slice | None = None
    mg: slice | None = None
    bs: slice | None = None
    air: slice | None = None
    """Wind North, wind East, airspeed scale (``+air`` layouts)."""
    therm: slice | None = None
    """Accelerometer then gyro temperature coefficients (``+therm`` layouts)."""

    def _optional_offset(self, block: slice | None, what: str) -> int:
        if block is None:
            raise ValueError(f"layout {self.name!r} has no {what}")
        return int(block.start)

    @cached_property
    def POS(self) -> int:
        """Offset of the position block."""
        return int(self.pos.start)

    @cached_property
    def VEL(self) -> int:
        """Offset of the velocity block."""
        return int(self.vel.start)

    @cached_property
    def ATT(self) -> int:
        """Offset of the attitude block."""
        return int(self.att.start)

    @cached_property
    def BA(self) -> int:
        """Offset of the accelerometer-bias block."""
        return int(self.ba.start)

    @cached_property
    def BG(self) -> int:
        """Offset of the gyro-bias block."""
        return int(self.bg.start)

    @cached_property
    def BARO(self) -> int:
        """Offset of the baro-bias state."""
        return int(self.baro.start)

    @cached_property
    def GNSS(self) -> int:
        """Offset of the GNSS position-bias block (ValueError if the layout has none)."""
        return self._optional_offset(self.gnss, "GNSS position-bias states")

    @cached_property
    def SA(self) -> int:
        """Offset of the accelerometer scale-factor block (ValueError if the layout has none)."""
        return self._optional_offset(self.sa, "scale-factor states")

    @cached_property
    def SG(self) -> int:
        """Offset of the gyro scale-factor block (ValueError if the layout has none)."""
        return self._optional_offset(self.sg, "scale-factor states")

    @cached_property
    def MA(self) -> int:
        """Offset of the accelerometer misalignment block (ValueError if the layout has none)."""
        return self._optional_offset(self.ma, "misalignment states")

    @cached_property
    def MG(self) -> int:
        """Offset of the gyro misalignment block (ValueError if the layout has none)."""
        return self._optional_offset(self.mg, "misalignment states")

    @cached_property
    def BS(self) -> int:
        """Offset of the baro scale-factor state (ValueError if the layout has none)."""
        return self._optional_offset(self.bs, "baro scale-factor state")

    @cached_property
    def WIND(self) -> int:
        """Offset of the wind block (North, East; ValueError if the layout has none)."""
        return self._optional_offset(self.air, "air-data states")

    @cached_property
    def ASPD_SCALE(self) -> int:
        """Offset of the airspeed scale-factor state (ValueError if the layout has none)."""
        return self._optional_offset(self.air, "air-data states") + 2

    @cached_property
    def GUST(self) -> int:
        """Offset of the gust block (North, East; ValueError if the layout has none)."""
        return self._optional_offset(self.air, "air-data states") + 3

    @cached_property
    def KA(self) -> int:
        """Offset of the accelerometer temperature-coefficient block (ValueError if none)."""
        return self._optional_offset(self.therm, "temperature-coefficient states")

    @cached_property
    def KG(self) -> int:
        """Offset of the gyro temperature-coefficient block (ValueError if none)."""
        return self._optional_offset(self.therm, "temperature-coefficient states") + 3

    @cached_property
    def has_thermal(self) -> bool:
        """The layout carries the temperature-coefficient states (``+therm``)."""
        return self.therm is not None

    @cached_property
    def has_air(self) -> bool:
        """The layout carries the wind and airspeed-scale states (``+air``)."""
        return self.air is not None

    @cached_property
    def has_baro_scale(self) -> bool:
        """The layout carries the baro scale-factor state (``ins35``)."""
        return self.bs is not None

    @cached_property
    def has_misalignment(self) -> bool:
        """The layout carries the accelerometer and gyro misalignment blocks (``ins35``)."""
        return self.ma is not None

    @cached_property
    def has_scale_factors(self) -> bool:
        """The layout carries the accelerometer and gyro scale-factor blocks (``ins22``,
        ``ins35``)."""
        return self.sa is not None

    @cached_property
    def has_gnss_bias(self) -> bool:
        """The layout carries the GNSS position-bias block (``+gnss``)."""
        return self.gnss is not None


_LABELS16 = (
    "pos_n_m", "pos_e_m", "pos_d_m",
    "vel_n_mps", "vel_e_mps", "vel_d_mps",
    "att_n_rad", "att_e_rad", "att_d_rad",
    "accel_bias_x_mps2", "accel_bias_y_mps2", "accel_bias_z_mps2",
    "gyro_bias_x_rps", "gyro_bias_y_rps", "gyro_bias_z_rps",
    "baro_bias_m",
)  # fmt: skip

#: 16 states: position, velocity, attitude, accelerometer bias, gyro bias, baro bias.
_BASE = dict(
    pos=slice(0, 3), vel=slice(3, 6), att=slice(6, 9), ba=slice(9, 12), bg=slice(12, 15),
    baro=slice(15, 16),
)  # fmt: skip
INS16 = StateLayout(name="ins16", n=16, **_BASE, sa=None, sg=None, labels=_LABELS16)
#: 22 states: :data:`INS16` plus accelerometer and gyro scale factors.
INS22 = StateLayout(
    name="ins22",
    n=22,
    **_BASE,
    sa=slice(16, 19),
    sg=slice(19, 22),
    labels=(
        *_LABELS16,
        "accel_scale_x", "accel_scale_y", "accel_scale_z",
        "gyro_scale_x", "gyro_scale_y", "gyro_scale_z",
    ),
)  # fmt: skip

#: 35 states: :data:`INS22` plus accelerometer and gyro misalignments (six each) and the
#: baro scale factor: every error a datasheet or paper P4's atmosphere names.
INS35 = StateLayout(
    name="ins35",
    n=35,
    **_BASE,
    sa=INS22.sa,
    sg=INS22.sg,
    labels=(
        *INS22.labels,
        *(f"accel_misalignment_{i}{j}" for i, j in OFF_DIAGONAL),
        *(f"gyro_misalignment_{i}{j}" for i, j in OFF_DIAGONAL),
        "baro_scale",
    ),
    ma=slice(22, 28),
    mg=slice(28, 34),
    bs=slice(34, 35),
)

_GNSS_LABELS = ("gnss_bias_n_m", "gnss_bias_e_m", "gnss_bias_d_m")


def _with_gnss_bias(base: StateLayout, name: LayoutName) -> StateLayout:
    n = base.n
    return StateLayout(
        name=name, n=n + 3, pos=base.pos, vel=base.vel, att=base.att, ba=base.ba,
        bg=base.bg, baro=base.baro, sa=base.sa, sg=base.sg,
        labels=(*base.labels, *_GNSS_LABELS), gnss=slice(n, n + 3), ma=base.ma, mg=base.mg,
        bs=base.bs,
    )  # fmt: skip


#: :data:`INS16` plus the GNSS position bias (19 states).
INS16_GNSS = _with_gnss_bias(INS16, "ins16+gnss")
#: :data:`INS22` plus the GNSS position bias (25 states).
INS22_GNSS = _with_gnss_bias(INS22, "ins22+gnss")
#: :data:`INS35` plus the GNSS position bias (38 states).
INS35_GNSS = _with_gnss_bias(INS35, "ins35+gnss")

_AIR_LABELS = ("wind_n_mps", "wind_e_mps", "airspeed_scale", "gust_n_mps", "gust_e_mps")


def _with_air(base: StateLayout) -> StateLayout:
    n = base.n
    return StateLayout(
        name=cast(LayoutName, f"{base.name}+air"), n=n + 5, pos=base.pos, vel=base.vel,
        att=base.att, ba=base.ba, bg=base.bg, baro=base.baro, sa=base.sa, sg=base.sg,
        labels=(*base.labels, *_AIR_LABELS), gnss=base.gnss, ma=base.ma, mg=base.mg,
        bs=base.bs, air=slice(n, n + 5),
    )  # fmt: skip


_BASE_LAYOUTS = (INS16, INS16_GNSS, INS22, INS22_GNSS, INS35, INS35_GNSS)
#: Every layout plus the air-data block (wind N/E, airspeed scale, gust N/E): ``ins16+air``
#: (21), ``ins16+gnss+air`` (24), ``ins22+air`` (27), ``ins22+gnss+air`` (30), ``ins35+air``
#: (40), ``ins35+gnss+air`` (43 states, the commands' default).
AIR_LAYOUTS = tuple(_with_air(lay) for lay in _BASE_LAYOUTS)

_THERM_LABELS = (
    "accel_tempco_x_mps2pk", "accel_tempco_y_mps2pk", "accel_tempco_z_mps2pk",
    "gyro_tempco_x_rpspk", "gyro_tempco_y_rpspk", "gyro_tempco_z_rpspk",
)  # fmt: skip


def with_thermal(base: StateLayout) -> StateLayout:
    """``base`` plus the temperature-coefficient block (six states appended), named
    ``<base>+therm`` (``--thermal states``)."""
    if base.therm is not None:
        return base
    n = base.n
    return StateLayout(
        name=cast(LayoutName, f"{base.name}+therm"), n=n + 6, pos=base.pos, vel=base.vel,
        att=base.att, ba=base.ba, bg=base.bg, baro=base.baro, sa=base.sa, sg=base.sg,
        labels=(*base.labels, *_THERM_LABELS), gnss=base.gnss, ma=base.ma, mg=base.mg,
        bs=base.bs, air=base.air, therm=slice(n, n + 6),
    )  # fmt: skip


#: Every layout with the temperature-coefficient block appended (``+therm``).
THERMAL_LAYOUTS = tuple(with_thermal(lay) for lay in (*_BASE_LAYOUTS, *AIR_LAYOUTS))

LAYOUTS: dict[str, StateLayout] = {
    lay.name: lay for lay in (*_BASE_LAYOUTS, *AIR_LAYOUTS, *THERMAL_LAYOUTS)
}


def layout_for(name: str) -> StateLayout:
    """The layout called ``name`` (one of :data:`LayoutName`).

    Raises
    ------
    ValueError
        Unknown ``name`` (the message lists the valid ones).
    """
    layout = LAYOUTS.get(name)
    if layout is None:
        raise ValueError(f"unknown state layout {name!r}; valid: {', '.join(LAYOUTS)}")
    return layout
