"""The bridging interface: what NavFilter and a GNSS-outage bridging strategy hand each other.

:class:`fusion.filter.NavFilter` calls a :class:`Bridge`:

- ``on_gnss(epoch, error)`` once per fused (or attempted) GNSS fix, with INS-side features at
  the fix's epoch (:class:`BridgeEpoch`) and the GNSS-derived INS error (:class:`InsError`:
  INS minus GNSS, lever-arm corrected, before the update) — the training pairs of P0's GMDH
  and P1/P2's networks. When the strategy asks for virtual outages
  (``virtual_outage_s > 0``) the error also carries one :class:`VirtualOutage` per running
  virtual-outage INS copy (:mod:`fusion.bridging.virtual_outages`);
- ``on_outage(epoch)`` at ``BridgeConfig.rate_hz`` while GNSS is out; the strategy may return
  a :class:`PseudoGnss` (P3: a pseudo-fix the filter fuses like GNSS, keeping its update step)
  or an :class:`OutputCorrection` (P0/P2: subtracted from the output estimate only, the INS
  and the filter are left alone), or ``None``;
- ``on_gnss_restored(epoch)`` when the filter leaves the outage.

:class:`NoBridge` (name ``"none"``) does nothing: plain free-inertial coasting.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol

from fusion.airspeed_model import OnlineAirspeedModel
from fusion.pitot_model import OnlinePitotErrorModel
from fusion.strapdown import InsState
from fusion.wind_model import OnlineWindModel

if TYPE_CHECKING:  # the model imports the bridging gate, which imports this module
    from fusion.thermal.bias_model import ThermalBiasModel

Vec3 = tuple[float, float, float]
Vec6 = tuple[float, float, float, float, float, float]
_ZERO3: Vec3 = (0.0, 0.0, 0.0)

COMPONENTS: tuple[str, ...] = ("pn", "pe", "pd", "vn", "ve", "vd")
"""The six corrected components: N/E/D position error (m), N/E/D velocity error (m/s)."""

BRIDGE_STATES: tuple[str, ...] = (
    "off", "no inputs", "untrained", "training", "trained", "stale"
)
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
    accel_bias_b_mps2: tuple[float, float, float] = _ZERO3
    """The filter's accelerometer bias estimate, m/s^2."""
    gyro_bias_b_rps: tuple[float, float, float] = _ZERO3
    """The filter's gyro bias estimate, rad/s."""
    free_state: InsState | None = None
    """During a real outage, when the strategy runs virtual outages: the free-running INS
    since the outage was detected (never corrected by pseudo-fixes); ``None`` otherwise."""


@dataclass(frozen=True, slots=True)
class VirtualOutage:
    """One virtual-outage INS copy's error against a GNSS fix: a drift sample from an outage
    that did not happen.

    Attributes
    ----------
    index : int
        Index of the INS copy in the bank.
    elapsed_s : float
        Time from the copy's re-seed to the fix's time of validity, s.
    start : BridgeEpoch
        The filter's INS features at the re-seed (the virtual outage's start).
    epoch : BridgeEpoch
        The copy's own features at the fix (its position, velocity and attitude; specific
        force, body rate and biases as the filter's).
    pos_ned_m : 3 floats
        Copy minus GNSS, metres N/E/D (lever-arm corrected as the filter's innovation).
    vel_ned_mps : 3 floats
        Copy minus GNSS velocity, m/s.
    """

    index: int
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
    """The virtual-outage INS errors at this fix (empty unless the strategy asked for them)."""


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
        outage or after long GNSS rejection; the last models are still used); ``"no inputs"``
        (``gmdh-airspeed`` on a stream without the controls or rpm it learns from).
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
    model : str
        A learned model's selected polynomial (``gmdh-airspeed``, ``gmdh-pitot``; ``gmdh-wind``:
        one per wind axis), readable; empty for the other strategies.
    model_rmse : float
        That model's RMS error on the most recent, held-out part of its training window, in
        its target's units (m/s of true airspeed, of wind or of airspeed error); NaN before its
        first fit.
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
    model: str = ""
    model_rmse: float = math.nan


class Bridge(Protocol):
    """A bridging strategy (see the module docstring for when each hook is called).

    :class:`~fusion.filter.NavFilter` reads ``virtual_outage_s`` and ``virtual_outage_count``
    once (at construction and :meth:`~fusion.filter.NavFilter.reset`):
    ``virtual_outage_s > 0`` makes it run a
    :class:`~fusion.bridging.virtual_outages.VirtualOutageBank` of ``virtual_outage_count`` INS
    copies; otherwise the copies cost nothing. ``status`` goes
    into every estimate. :class:`NoBridge` has the defaults (no virtual outages, status
    ``off``): a strategy that needs neither can subclass it and override the hooks.
    """

    @property
    def name(self) -> str:
        """Method name."""
        ...

    @property
    def virtual_outage_s(self) -> float:
        """Length of a virtual outage asked of the filter, s (0: none)."""
        ...

    @property
    def virtual_outage_count(self) -> int:
        """Number of staggered virtual-outage INS copies asked of the filter (>= 1 when
        ``virtual_outage_s > 0``)."""
        ...

    @property
    def status(self) -> BridgeStatus:
        """The strategy's current health."""
        ...

    @property
    def airspeed_model(self) -> OnlineAirspeedModel | None:
        """A learned vehicle model for the filter's air-data aiding (``gmdh-airspeed``), read
        once at construction; None for the other strategies."""
        ...

    @property
    def wind_model(self) -> OnlineWindModel | None:
        """A learned wind profile for the filter's air-data aiding (``gmdh-wind``), read once
        at construction; None for the other strategies."""
        ...

    @property
    def pitot_model(self) -> OnlinePitotErrorModel | None:
        """A learned pitot position error for the filter's air-data aiding (``gmdh-pitot``),
        read once at construction; None for the other strategies."""
        ...

    @property
    def thermal_model(self) -> ThermalBiasModel | None:
        """A learned bias-versus-temperature model (``gmdh-thermal``), read once at
        construction; None for the other strategies."""
        ...

    def on_gnss(self, epoch: BridgeEpoch, error: InsError) -> None:
        """One fused (or attempted) GNSS fix: the training pair."""
        ...

    def on_outage(self, epoch: BridgeEpoch) -> BridgeAction | None:
        """One consultation during an outage: a pseudo-fix, an output correction or nothing."""
        ...

    def on_gnss_restored(self, epoch: BridgeEpoch) -> None:
        """The filter left the outage."""
        ...


_NONE_STATUS = BridgeStatus("none", "off")


class NoBridge:
    """The ``"none"`` strategy: observes nothing, corrects nothing."""

    name = "none"
    virtual_outage_s = 0.0
    virtual_outage_count = 0
    airspeed_model: OnlineAirspeedModel | None = None
    wind_model: OnlineWindModel | None = None
    pitot_model: OnlinePitotErrorModel | None = None
    thermal_model: ThermalBiasModel | None = None

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
