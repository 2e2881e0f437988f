"""NavFilter's GNSS-outage bookkeeping: the outage state, the bridging strategy's
consultations and output correction, and the life cycle of the virtual-outage INS copies it
asks for.

An outage begins when no fix was fused for ``GnssTuning.outage_timeout_s`` and ends when GNSS
aiding is active again. Meanwhile the strategy (:class:`fusion.bridging.interface.Bridge`) is
consulted every ``1 / BridgeConfig.rate_hz``; an
:class:`~fusion.bridging.interface.OutputCorrection` it returns is subtracted from the output
estimate until the outage ends, a :class:`~fusion.bridging.interface.PseudoGnss` is fused by
the filter (:mod:`fusion.aiding.pseudo_gnss`). While GNSS is good every fix goes to the
strategy with the INS error it revealed and, when the strategy asks for virtual outages
(``virtual_outage_s > 0``), the errors of the virtual-outage INS copies
(:class:`~fusion.bridging.virtual_outages.VirtualOutageBank`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

from fusion.bridging.interface import (
    Bridge,
    BridgeAction,
    BridgeEpoch,
    InsError,
    OutputCorrection,
)
from fusion.bridging.virtual_outages import VirtualOutageBank
from fusion.strapdown import InsState


class OutageBridging:
    """The outage state and the bridging strategy's hooks (see the module docstring).

    Parameters
    ----------
    bridge : Bridge
        The strategy.
    rate_hz : float
        Consultations per second during an outage.
    epoch : callable ``(time_us, InsState) -> BridgeEpoch``
        Builds the filter's features for a state (also given to the virtual-outage bank).

    Attributes
    ----------
    in_outage : bool
        An outage is under way.
    active : bool
        The strategy applied a correction or a pseudo-fix in this outage (mode ``bridging``).
    next_us : int
        Time of the next consultation.
    correction : OutputCorrection or None
        The output correction in force.
    virtual_outages : VirtualOutageBank or None
        The virtual-outage INS copies, when the strategy asks for virtual outages.
    """

    def __init__(
        self, bridge: Bridge, rate_hz: float, epoch: Callable[[int, InsState], BridgeEpoch]
    ) -> None:
        self.bridge = bridge
        self._epoch = epoch
        self._period_us = round(1e6 / rate_hz)
        self.in_outage = False
        self.active = False
        self.next_us = 0
        self.correction: OutputCorrection | None = None
        # Virtual outages only when the strategy asks for them: otherwise None, and the IMU
        # loop pays one attribute test.
        period_s = bridge.virtual_outage_s
        self.virtual_outages: VirtualOutageBank | None = (
            VirtualOutageBank(period_s, bridge.virtual_outage_count, epoch)
            if period_s > 0.0 else None
        )

    def restart(self) -> None:
        """The filter (re)started from a known state: no outage."""
        self.in_outage = False

    def begin(
        self, time_us: int, ins: InsState | None, ba: Sequence[float], bg: Sequence[float],
        dtheta_b: Sequence[float], dv_b: Sequence[float],
    ) -> None:  # fmt: skip
        """An outage was detected at ``time_us``: consult the strategy from now on, and let
        copy 0 run free from the current INS (its biases and last increments)."""
        self.in_outage = True
        self.next_us = time_us
        if self.virtual_outages is not None and ins is not None:
            self.virtual_outages.begin_outage(time_us, ins, ba, bg, dtheta_b, dv_b)

    def consult(self, time_us: int, epoch: BridgeEpoch) -> BridgeAction | None:
        """Ask the strategy at a consultation epoch; schedule the next one."""
        self.next_us = max(self.next_us + self._period_us, time_us + 1)
        return self.bridge.on_outage(epoch)

    def on_fix(
        self, time_us: int, past: InsState, ins_pre_pos: InsState | None,
        ins_pre_vel: InsState | None, pos_accepted: bool, vel_accepted: bool,
        pos_ned_m: list[float], vel_ned_mps: list[float],
    ) -> None:  # fmt: skip
        """Hand one fix to the strategy: the INS error it revealed and the virtual-outage INS
        errors.

        Parameters
        ----------
        time_us : int
            The fix's time of validity.
        past : InsState
            The INS at that time (after the updates).
        ins_pre_pos, ins_pre_vel : InsState or None
            The current INS before the position / the velocity update.
        pos_accepted, vel_accepted : bool
            The gate's verdicts.
        pos_ned_m, vel_ned_mps : 3 floats
            INS minus the fix as received (position without the bias estimate).
        """
        zp, zv = pos_ned_m, vel_ned_mps
        copies = self.virtual_outages
        virtual = (
            copies.samples(time_us, ins_pre_pos, ins_pre_vel, zp, zv)
            if copies is not None and pos_accepted and vel_accepted
            and ins_pre_pos is not None and ins_pre_vel is not None
            else ()
        )  # fmt: skip
        self.bridge.on_gnss(
            self._epoch(time_us, past),
            InsError((zp[0], zp[1], zp[2]), (zv[0], zv[1], zv[2]), pos_accepted, vel_accepted,
                     virtual),
        )  # fmt: skip

    def end(self, time_us: int, epoch: BridgeEpoch) -> None:
        """GNSS is back at ``time_us`` (``epoch``: the filter's features then)."""
        self.in_outage = False
        self.active = False
        self.correction = None
        self.bridge.on_gnss_restored(epoch)
        if self.virtual_outages is not None:
            self.virtual_outages.end_outage(time_us)
