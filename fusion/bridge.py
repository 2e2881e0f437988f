"""Hooks for GNSS-outage bridging strategies (papers P0-P3: learn the INS error while GNSS is
good, correct the INS while it is not).

:class:`fusion.filter.NavFilter` calls a :class:`Bridge`:

- ``on_gnss(epoch, error)`` once per fused (or attempted) GNSS fix, with INS-side features at
  the fix's epoch and the GNSS-derived INS error (INS minus GNSS, lever-arm corrected, before
  the update) — the training pairs of P0's GMDH and P1/P2's networks;
- ``on_outage(epoch)`` at ``BridgeConfig.rate_hz`` while GNSS is out; the strategy may return
  a :class:`PseudoGnss` (P3: a pseudo-fix the filter fuses like GNSS, keeping its update step)
  or an :class:`OutputCorrection` (P0/P2: subtracted from the output estimate only, the INS
  and the filter are left alone), or ``None``;
- ``on_gnss_restored(epoch)`` when the filter leaves the outage.

:class:`NoBridge` (name ``"none"``) does nothing: plain free-inertial coasting.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol


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


@dataclass(frozen=True, slots=True)
class InsError:
    """GNSS-derived INS error at a fix's time of validity: INS minus GNSS, before the update."""

    pos_ned_m: tuple[float, float, float]
    vel_ned_mps: tuple[float, float, float]
    pos_accepted: bool
    vel_accepted: bool


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


class Bridge(Protocol):
    """A bridging strategy (see module docstring)."""

    @property
    def name(self) -> str: ...

    def on_gnss(self, epoch: BridgeEpoch, error: InsError) -> None: ...

    def on_outage(self, epoch: BridgeEpoch) -> BridgeAction | None: ...

    def on_gnss_restored(self, epoch: BridgeEpoch) -> None: ...


class NoBridge:
    """The ``"none"`` strategy: observes nothing, corrects nothing."""

    name = "none"

    def on_gnss(self, epoch: BridgeEpoch, error: InsError) -> None:
        """Ignore the training pair."""

    def on_outage(self, epoch: BridgeEpoch) -> BridgeAction | None:
        """No correction."""
        return None

    def on_gnss_restored(self, epoch: BridgeEpoch) -> None:
        """Nothing to reset."""
