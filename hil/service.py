"""``hilnav fusion``: the live fusion service.

Input (``--mavlink URL``)
    Sensor messages from hilnav's simulator (HIL_SENSOR, HIL_GPS; truth as
    HIL_STATE_QUATERNION from :data:`hil.codec.TRUTH_COMPONENT_ID`; the vehicle state as
    HIL_ACTUATOR_CONTROLS and RAW_RPM from :data:`hil.codec.AUTOPILOT_COMPONENT_ID`) or from a
    real flight controller (HIGHRES_IMU, SCALED_IMU*, RAW_IMU, GPS_RAW_INT, SCALED_PRESSURE*,
    SERVO_OUTPUT_RAW, RAW_RPM), decoded by
    :class:`hil.codec.Decoder` and run through :class:`fusion.filter.NavFilter` in arrival
    order (the same order a ``hilnav replay`` of the same frames sees: same seed, same numbers).

Outputs (all optional; none of them can block the filter)
    * ``--gcs URL``: a *shadow vehicle* for ground stations (own system id, component 1):
      HEARTBEAT (the link; custom mode = the navigation mode), the fast group at
      ``telemetry_hz`` and the slow group at 1 Hz (wall-clock pacing, estimate-time stamps;
      :mod:`hil.shadow_vehicle`), a STATUSTEXT per navigation event; answers to
      PARAM_REQUEST_LIST / PARAM_REQUEST_READ (one parameter), COMMAND_LONG
      REQUEST_AUTOPILOT_CAPABILITIES, GET_HOME_POSITION, REQUEST_MESSAGE of AUTOPILOT_VERSION,
      HOME_POSITION, AVAILABLE_MODES and CURRENT_MODE, MISSION_REQUEST_LIST (zero items) and
      MAVLink FTP (an empty, read-only file system) so QGC / MAVProxy / MAVSDK connect without
      retries. The simulator's scenario events (STATUSTEXT ``SIM: ...`` from its truth
      component, :mod:`hil.live_sim`) are relayed as the shadow vehicle's STATUSTEXT.
      ``--gcs-tlog PATH`` records every frame the shadow vehicle sends (and its heartbeats) as
      a .tlog stamped with estimate time, for pymavlink's log tools.
    * ``fusion/events`` on Zenoh: every :class:`hil.nav_events.NavEvent` (mode changes and
      detected faults), with or without a ground station.
    * ``--companion URL --companion-kind gps_input|odometry``: GPS_INPUT (ArduPilot, 5 Hz)
      or ODOMETRY (PX4, 30 Hz) to a flight controller, on simulated time.
    * ``--zenoh EP`` (a router) and / or ``--zenoh-listen EP`` (peer-to-peer: subscribers
      connect to this process directly, one hop less; loopback only): estimate, status
      (mode, test ratios, health, link counters), error vs truth (estimate and truth of the
      same time), innovations (one message per aiding update, see below), a
      ``fusion/config`` queryable and a ``fusion/alive`` liveliness token
      (:class:`hil.bus.Bus`: bounded queue, never blocks).
    * ``--out DIR``: at exit, ``summary.json`` of everything received (estimate vs truth,
      GNSS outages from fix gaps), computed exactly as ``hilnav replay`` does, plus a
      ``live`` section with the link counters (sample loss). While running, what it will be
      scored from is kept compact and spilled to an anonymous file in ``DIR``
      (:class:`hil.tracks.Collector`), so memory stays flat however long the flight.

Innovations (``fusion/innovations``)
    Every gated Kalman update of the filter is published: ``source`` (``gnss_pos``,
    ``gnss_vel``, ``baro_hgt``, ``mag_hdg``; ``bridge_pos`` / ``bridge_vel`` for pseudo-GNSS
    updates of a bridging strategy), the innovation (INS-predicted minus measured, SI units of
    the observation: m, m/s, m, rad), ``sqrt(diag(S))``, the test ratio (NIS over the gate,
    > 1 = rejected) and whether it was fused. ``time_us`` is the time of the sample whose
    processing made the update. They are the filter's own records of each step
    (:attr:`fusion.filter.NavFilter.innovations`), which name the source where the update is
    made.

Lockstep acknowledgements (``hilnav sim --live URL --lockstep``)
    A simulator that asks for lockstep (HEARTBEAT with ``custom_mode`` =
    :data:`hil.link.LOCKSTEP_CUSTOM_MODE`) gets a TIMESYNC on the input link after every
    batch the filter has processed: ``ts1`` = ``tc1`` = simulated time in ns of the newest
    sample processed so far (never a stamp the filter's clock refused:
    :class:`hil.sample_clock.SampleClock`). The reader thread owns the link, so the
    filter thread wakes it through a socket pair to send the acknowledgement at once. Nothing
    is sent to other peers (a flight controller never sees a TIMESYNC from us).

Wire units of the outputs live in :mod:`hil.shadow` (codec-adjacent).
"""

from __future__ import annotations

import contextlib
import dataclasses
import selectors
import socket
import threading
import time
from collections import OrderedDict, deque
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Final, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from fusion.config import DEFAULT_AIRSPEED_MODE, DEFAULT_ALIGN_MODE
from fusion.estimate import Mode, NavEstimate
from fusion.thermal.tuning import ThermalTuning
from hil.bus import BusAccess, Topic
from hil.codec import TRUTH_COMPONENT_ID, mavlink2
from hil.codec.wire import STANDARD_MODES_DIALECT
from hil.link import (
    FAST_MSG_IDS,
    FC_SENSOR_MSG_IDS,
    HIL_MSG_IDS,
    LOCKSTEP_CUSTOM_MODE,
    LinkRole,
    MavlinkLink,
)
from hil.nav_events import MODE_LABELS, NavEvent, NavEventDetector
from hil.pipeline import FusionRun, filter_config
from hil.sample_clock import SampleClock
from hil.shadow import CUSTOM_MODES, CompanionEncoder, ShadowEncoder, heartbeat_state
from hil.shadow_vehicle import ShadowVehicle
from hil.signing import Signer
from hil.tlog import TlogWriter
from sim.presets import gnss_preset
from sim.samples import Truth

__all__ = [
    "FusionOptions", "FusionService", "GcsResponder", "input_role", "interpolate_truth",
    "parse_source",
]

_TRUTH_ID: Final = int(mavlink2.MAVLINK_MSG_ID_HIL_STATE_QUATERNION)
_HEARTBEAT_ID: Final = int(mavlink2.MAVLINK_MSG_ID_HEARTBEAT)
_STATUSTEXT_ID: Final = int(mavlink2.MAVLINK_MSG_ID_STATUSTEXT)
_GCS_MSG_IDS: Final = frozenset({
    int(mavlink2.MAVLINK_MSG_ID_PARAM_REQUEST_LIST),
    int(mavlink2.MAVLINK_MSG_ID_PARAM_REQUEST_READ),
    int(mavlink2.MAVLINK_MSG_ID_COMMAND_LONG),
    int(mavlink2.MAVLINK_MSG_ID_MISSION_REQUEST_LIST),
    int(mavlink2.MAVLINK_MSG_ID_MISSION_ACK),  # a ground station's ack of our empty list
    int(mavlink2.MAVLINK_MSG_ID_FILE_TRANSFER_PROTOCOL),
})
_HOME_ID: Final = int(mavlink2.MAVLINK_MSG_ID_HOME_POSITION)
_AVAILABLE_MODES_ID: Final = int(STANDARD_MODES_DIALECT.MAVLINK_MSG_ID_AVAILABLE_MODES)
_CURRENT_MODE_ID: Final = int(STANDARD_MODES_DIALECT.MAVLINK_MSG_ID_CURRENT_MODE)
_COMPANION_RATE_HZ: Final = {"gps_input": 5.0, "odometry": 30.0}
_ERROR_MATCH_KEEP: Final = 64  # recent estimates kept to pair with truth of the same time


class FusionOptions(BaseModel):
    """Validated options of the fusion service (see the module docstring)."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    mavlink: str
    source: str | None = None
    """Accept sensors only from ``SYSID[:COMPID]``; None: lock onto the first sensor source."""
    zenoh: str | None = None
    zenoh_listen: str | None = None
    """Peer-to-peer subscription mode: the bus is a Zenoh peer listening here (loopback) for
    subscribers that connect directly (``hilnav monitor --peer``), besides ``zenoh``'s router
    when given."""
    zenoh_low_latency: bool = False
    """Ask for Zenoh's low-latency unicast transport (:attr:`hil.bus.BusConfig.low_latency`):
    used on a link only when the other end (a direct subscriber, the router) asks too."""
    vehicle: str = "sim1"
    imu: str = "industrial-mems"
    gnss: str = "modern"
    bridge: str = "none"
    altitude: str = "ekf"
    airspeed: str = DEFAULT_AIRSPEED_MODE
    """Air data: ``on``, ``off`` or ``synthetic`` (:data:`fusion.config.AIRSPEED_MODES`)."""
    align: str = DEFAULT_ALIGN_MODE
    thermal: ThermalTuning | None = None
    """The IMU thermal strategy (``None``: the filter's default, ``off``)."""
    """Alignment: ``auto``, ``static`` or ``in-flight`` (:data:`fusion.config.ALIGN_MODES`)."""
    gcs: str | None = None
    gcs_tlog: Path | None = None
    """Record the shadow vehicle's stream here (.tlog, estimate-time stamps); needs ``gcs``."""
    shadow_system_id: int = Field(default=1, ge=1, le=255)
    companion: str | None = None
    companion_kind: Literal["gps_input", "odometry"] = "gps_input"
    companion_system_id: int = Field(default=1, ge=1, le=255)
    telemetry_hz: float = Field(default=10.0, gt=0.0, le=100.0)
    duration_s: float | None = Field(default=None, gt=0.0)
    idle_exit_s: float | None = Field(default=None, gt=0.0)
    out: Path | None = None
    settle_s: float = Field(default=60.0, ge=0.0)


def _text(value: str | bytes) -> str:
    """A MAVLink char[] field as text (pymavlink gives str or bytes), NULs stripped."""
    raw = value if isinstance(value, str) else value.decode("ascii", "replace")
    return raw.rstrip("\x00")


def parse_source(text: str) -> tuple[int, int | None]:
    """``"SYSID"`` or ``"SYSID:COMPID"`` -> ``(sysid, compid or None)`` (ValueError, one line)."""
    parts = text.split(":")
    try:
        if len(parts) > 2:
            raise ValueError
        sys_id = int(parts[0])
        comp_id = int(parts[1]) if len(parts) == 2 else None
    except ValueError:
        raise ValueError(f"--source {text!r} must be SYSID or SYSID:COMPID, e.g. 1 or 1:200"
                         ) from None
    if not 1 <= sys_id <= 255 or (comp_id is not None and not 0 <= comp_id <= 255):
        raise ValueError(f"--source {text!r}: system id 1-255, component id 0-255")
    return sys_id, comp_id


def input_role(source: tuple[int, int | None] | None = None) -> LinkRole:
    """The input link: an onboard computer (191) taking simulator and flight-controller
    sensor messages from one source: ``source`` (system id, component id or None for any
    component) when given, else the system of the first sensor frame (the link locks onto
    it; every other system is counted in ``wrong_source`` and ignored)."""
    return LinkRole(
        system_id=1,
        component_id=int(mavlink2.MAV_COMP_ID_ONBOARD_COMPUTER),
        mav_type=int(mavlink2.MAV_TYPE_ONBOARD_CONTROLLER),
        autopilot=int(mavlink2.MAV_AUTOPILOT_INVALID),
        accept_sources=None if source is None else frozenset({source}),
        accept_msg_ids=HIL_MSG_IDS | FC_SENSOR_MSG_IDS | {_STATUSTEXT_ID},
        lock_to_first_source=source is None,
    )


def shadow_role(system_id: int) -> LinkRole:
    """The shadow vehicle's role, accepting the few ground-station requests we answer."""
    base = LinkRole.shadow_vehicle(system_id=system_id)
    return base.model_copy(update={"accept_msg_ids": _GCS_MSG_IDS})


class GcsResponder:
    """Minimal answers to ground-station requests (returns frames to send).

    One parameter is published (``HILNAV_SYSID``); AUTOPILOT_VERSION is answered to
    MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES and REQUEST_MESSAGE(148); HOME_POSITION to
    MAV_CMD_GET_HOME_POSITION and REQUEST_MESSAGE(242) (TEMPORARILY_REJECTED before
    alignment); AVAILABLE_MODES to REQUEST_MESSAGE(435, index; index 0 = every mode) and
    CURRENT_MODE to REQUEST_MESSAGE(436); any other command gets MAV_RESULT_UNSUPPORTED;
    mission lists have zero items; MAVLink FTP requests get the answers of an empty, read-only
    file system (:meth:`hil.shadow.ShadowEncoder.ftp_reply`).

    Parameters
    ----------
    encoder : ShadowEncoder
    mode : callable, optional
        The current navigation mode (None: aligning).
    """

    def __init__(self, encoder: ShadowEncoder, mode: Any = None) -> None:
        self.enc = encoder
        self._mode = mode or (lambda: Mode.INITIALIZING)
        self.params: dict[str, float] = {"HILNAV_SYSID": float(encoder.system_id)}

    def _for_us(self, msg: Any) -> bool:
        target = int(getattr(msg, "target_system", 0))
        return target in (0, self.enc.system_id)

    def handle(self, msg: Any) -> list[bytes]:
        """Frames answering ``msg`` (a pymavlink message from the ground-station link)."""
        msg_id = msg.get_msgId()
        if not self._for_us(msg):
            return []
        names = list(self.params)
        if msg_id == mavlink2.MAVLINK_MSG_ID_PARAM_REQUEST_LIST:
            return [self.enc.param_value(n, self.params[n], i, len(names))
                    for i, n in enumerate(names)]
        if msg_id == mavlink2.MAVLINK_MSG_ID_PARAM_REQUEST_READ:
            pid = msg.param_id if isinstance(msg.param_id, str) else msg.param_id.decode()
            pid = pid.rstrip("\x00")
            if pid in self.params:
                return [self.enc.param_value(pid, self.params[pid], names.index(pid), len(names))]
            if 0 <= msg.param_index < len(names):
                n = names[msg.param_index]
                return [self.enc.param_value(n, self.params[n], msg.param_index, len(names))]
            return []
        if msg_id == mavlink2.MAVLINK_MSG_ID_MISSION_REQUEST_LIST:
            return [self.enc.mission_count(msg.get_srcSystem(), msg.get_srcComponent(),
                                           int(getattr(msg, "mission_type", 0)))]
        if msg_id == mavlink2.MAVLINK_MSG_ID_COMMAND_LONG:
            return self._command(msg)
        if msg_id == mavlink2.MAVLINK_MSG_ID_FILE_TRANSFER_PROTOCOL and int(
                msg.target_component) in (0, int(mavlink2.MAV_COMP_ID_AUTOPILOT1)):
            return [self.enc.ftp_reply(msg.get_srcSystem(), msg.get_srcComponent(),
                                       bytes(msg.payload))]
        return []

    def _command(self, msg: Any) -> list[bytes]:
        cmd = int(msg.command)
        src = (msg.get_srcSystem(), msg.get_srcComponent())
        wants_version = cmd == mavlink2.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES or (
            cmd == mavlink2.MAV_CMD_REQUEST_MESSAGE
            and int(msg.param1) == mavlink2.MAVLINK_MSG_ID_AUTOPILOT_VERSION
        )
        accepted = int(mavlink2.MAV_RESULT_ACCEPTED)
        if wants_version:
            return [self.enc.command_ack(cmd, accepted, *src), self.enc.autopilot_version()]
        requested = int(msg.param1) if cmd == mavlink2.MAV_CMD_REQUEST_MESSAGE else None
        if cmd == mavlink2.MAV_CMD_GET_HOME_POSITION or requested == _HOME_ID:
            home = self.enc.home_position()
            if home is None:
                return [self.enc.command_ack(
                    cmd, int(mavlink2.MAV_RESULT_TEMPORARILY_REJECTED), *src)]
            return [self.enc.command_ack(cmd, accepted, *src), home]
        if requested == _AVAILABLE_MODES_ID:
            n = len(CUSTOM_MODES)
            index = int(msg.param2)
            if not 0 <= index <= n:
                return [self.enc.command_ack(cmd, int(mavlink2.MAV_RESULT_DENIED), *src)]
            indices = range(1, n + 1) if index == 0 else [index]
            return [self.enc.command_ack(cmd, accepted, *src),
                    *(self.enc.available_modes(i) for i in indices)]
        if requested == _CURRENT_MODE_ID:
            mode = self._mode() or Mode.INITIALIZING
            return [self.enc.command_ack(cmd, accepted, *src), self.enc.current_mode(mode)]
        return [self.enc.command_ack(cmd, int(mavlink2.MAV_RESULT_UNSUPPORTED), *src)]


@dataclass
class _Stats:
    truth_other_component: int = 0
    errors_published: int = 0
    estimates: int = 0
    gcs_answers: int = 0
    innovations: int = 0
    events: int = 0
    statustexts: int = 0
    lockstep_acks: int = 0
    first_input_wall: float | None = None
    last_input_wall: float | None = None
    last_processed_wall: float | None = None
    extra: dict[str, int] = field(default_factory=dict)


class FusionService:
    """The filter and its outputs, driven by :meth:`run` (or by :meth:`handle_input` in tests).

    Parameters
    ----------
    options : FusionOptions
    signing_key : bytes, optional
        32-byte MAVLink 2 signing key for every MAVLink link of the service.
    bus_access : BusAccess, optional
        Zenoh login / TLS and the shared payload key (kept out of ``options``: the
        ``fusion/config`` queryable answers with the options).
    """

    def __init__(self, options: FusionOptions, *, signing_key: bytes | None = None,
                 bus_access: BusAccess | None = None) -> None:
        self.options = options
        self.bus_access = bus_access or BusAccess()
        self.config = filter_config(options.imu, gnss_preset(options.gnss), options.altitude,
                                    options.airspeed, options.align, options.thermal)
        self.fusion = FusionRun(self.config, options.bridge, collect=options.out is not None,
                                spill_dir=options.out)
        self.nav = self.fusion.nav
        self.decoder = self.fusion.decoder
        self.stats = _Stats()
        self._signing_key = signing_key
        self._recent: OrderedDict[int, NavEstimate] = OrderedDict()
        self.last_estimate: NavEstimate | None = None
        self._prev_truth: Truth | None = None
        self._links: dict[str, MavlinkLink] = {}
        self._bus: Any = None
        self.shadow: ShadowEncoder | None = None
        self.vehicle: ShadowVehicle | None = None
        self.responder: GcsResponder | None = None
        self.events = NavEventDetector()
        self._pending_text: deque[NavEvent] = deque(maxlen=64)
        self._gcs_heard = False  # a ground station has spoken on the GCS link
        self._relay_text: deque[tuple[int, str]] = deque(maxlen=64)  # the simulator's events
        self._gcs_tlog: TlogWriter | None = None
        self.companion: CompanionEncoder | None = None
        self._next_companion_us = 0
        self._wall0 = time.monotonic()
        self._queue: deque[Any] = deque()
        self._cond = threading.Condition()
        # lockstep: sources that asked for acknowledgements, newest processed sample time (us;
        # written by the filter thread, read by the reader thread), and the reader's wake-up
        self._lockstep_sources: set[tuple[int, int]] = set()
        self._processed_us = -1
        self._ack_clock = SampleClock(round(self.config.imu.time_jump_s * 1e6))
        self._wake_rx: socket.socket | None = None
        self._wake_tx: socket.socket | None = None

    # ---------------------------------------------------------------- links
    def _signer(self, link_id: int) -> Signer | None:
        return None if self._signing_key is None else Signer(self._signing_key, link_id=link_id)

    def open(self, stack: contextlib.ExitStack) -> None:
        """Open every configured link and the bus (closed by ``stack``)."""
        o = self.options
        self._links["mavlink"] = stack.enter_context(
            MavlinkLink(o.mavlink, input_role(None if o.source is None
                                              else parse_source(o.source)),
                        signer=self._signer(0), fast_msg_ids=FAST_MSG_IDS))
        if o.gcs is not None:
            self.shadow = ShadowEncoder(o.shadow_system_id)
            self.vehicle = ShadowVehicle(self.shadow, airspeed_enabled=o.airspeed != "off")
            vehicle = self.vehicle
            self.responder = GcsResponder(self.shadow, lambda: vehicle.mode)
            self._links["gcs"] = stack.enter_context(
                MavlinkLink(o.gcs, shadow_role(o.shadow_system_id), signer=self._signer(1)))
            if o.gcs_tlog is not None:
                self._gcs_tlog = stack.enter_context(TlogWriter(o.gcs_tlog))
        if o.companion is not None:
            role = LinkRole.companion(system_id=o.companion_system_id)
            self.companion = CompanionEncoder(role.system_id, role.component_id)
            self._links["companion"] = stack.enter_context(
                MavlinkLink(o.companion, role, signer=self._signer(2)))
        if o.zenoh is not None or o.zenoh_listen is not None:
            from hil.bus import Bus, BusConfig

            self._bus = stack.enter_context(Bus(
                o.zenoh, vehicle=o.vehicle, mode="client" if o.zenoh_listen is None else "peer",
                listen=o.zenoh_listen, config=BusConfig(low_latency=o.zenoh_low_latency),
                security=self.bus_access.security, auth_key=self.bus_access.auth_key))
            self._bus.declare_config_queryable(self.config_snapshot)
            self._bus.declare_liveliness()

    def config_snapshot(self) -> dict[str, Any]:
        """What the ``fusion/config`` queryable answers."""
        return {
            "options": self.options.model_dump(mode="json"),
            "filter": self.config.model_dump(mode="json"),
        }

    def link_counters(self) -> dict[str, dict[str, int]]:
        """Counters of every link plus the decoder's."""
        out = {name: link.counters() for name, link in self._links.items()}
        out["decoder"] = self.decoder.counters.as_dict()
        return out

    # ---------------------------------------------------------------- input
    def handle_input(self, msg: Any) -> list[NavEstimate]:
        """Decode one input message, run the filter, publish; returns the new estimates."""
        now = time.monotonic()
        if self.stats.first_input_wall is None:
            self.stats.first_input_wall = now
        self.stats.last_input_wall = now
        return self._handle(msg)

    def _handle(self, msg: Any) -> list[NavEstimate]:
        self.stats.last_processed_wall = time.monotonic()
        new: list[NavEstimate] = []
        if (msg.get_msgId() == _STATUSTEXT_ID and self.vehicle is not None
                and msg.get_srcComponent() == TRUTH_COMPONENT_ID):
            self._relay_text.append((int(msg.severity), _text(msg.text)))
        for d in self.decoder.decode_message(msg):
            item = d.sample
            if self.vehicle is not None:
                self.vehicle.on_sample(item)
            if isinstance(item, Truth):
                if d.component_id != TRUTH_COMPONENT_ID or d.msg_id != _TRUTH_ID:
                    self.stats.truth_other_component += 1
                    continue
                self.fusion.feed([item])
                self._advance_processed(item.time_us)
                self._on_truth(item)
                continue
            ests = self.fusion.feed([item])
            self._advance_processed(item.time_us)
            for est in ests:  # before the innovations: the estimate's latency counts most
                self._on_estimate(est)
            if self.nav.innovations:
                self._on_innovations()
            new.extend(ests)
        return new

    def _advance_processed(self, time_us: int) -> None:
        """Move the acknowledged time (lockstep) to a processed sample's time, unless the
        filter's clock did not take that stamp (:class:`hil.sample_clock.SampleClock`): the
        simulator keeps the largest acknowledgement it saw, so one stamp an hour ahead would
        end its pacing for good, and 2^64 - 1 us does not fit TIMESYNC's int64 ns."""
        if self._ack_clock.offer(time_us, self.nav.time_us):
            self._processed_us = time_us

    def _on_innovations(self) -> None:
        """Publish the updates the last filter step made on ``fusion/innovations``."""
        if self._bus is None:
            return
        for inn in self.nav.innovations:
            if self._bus.publish_innovation(inn.time_us, str(inn.source), inn.innovation,
                                            S=inn.S, test_ratio=float(inn.test_ratio),
                                            accepted=inn.fused):
                self.stats.innovations += 1

    def _on_estimate(self, est: NavEstimate) -> None:
        # published first, for live latency: everything else here waits, the subscribers do not
        if self._bus is not None and est.mode != "initializing":
            self._bus.publish_estimate(est)
        self.stats.estimates += 1
        self.last_estimate = est
        self._recent[est.time_us] = est
        if len(self._recent) > _ERROR_MATCH_KEEP:
            self._recent.popitem(last=False)
        events = self.events.update(est)
        for ev in events:
            self.stats.events += 1
            if self.vehicle is not None and ev.severity != "debug":
                self._pending_text.append(ev)
            if self._bus is not None:
                self._bus.publish_fusion_event(ev.time_us, ev.event, ev.severity, ev.message,
                                               ev.detail)
        if est.mode == "initializing":
            return
        if self._bus is not None and self._bus.due(Topic.STATUS, est.time_us):
            # counters only when it is sent
            self._bus.publish_status(est, links=self.link_counters(),
                                     thermal=self.nav.thermal_status)
        if self.companion is not None and est.time_us >= self._next_companion_us:
            kind = self.options.companion_kind
            frame = (self.companion.gps_input(est) if kind == "gps_input"
                     else self.companion.odometry(est))
            self._links["companion"].send(frame)
            self._next_companion_us = est.time_us + round(1e6 / _COMPANION_RATE_HZ[kind])

    def _on_truth(self, truth: Truth) -> None:
        prev, self._prev_truth = self._prev_truth, truth
        if self._bus is None or prev is None or not prev.time_us < truth.time_us:
            return
        # estimates between the two truth samples: error against the interpolated truth
        for t, est in self._recent.items():
            if prev.time_us < t <= truth.time_us and est.mode != "initializing" and (
                self._bus.due(Topic.ERROR, t)
            ):
                if self._bus.publish_error(est, interpolate_truth(prev, truth, t)):
                    self.stats.errors_published += 1

    # ---------------------------------------------------------------- outputs on wall time
    def _gcs_send(self, link: MavlinkLink, frame: bytes) -> None:
        link.send(frame)
        if self._gcs_tlog is not None and self.shadow is not None:
            self._gcs_tlog.write(frame, self.shadow.time_us)

    def _greet_gcs(self, est: NavEstimate | None) -> None:
        """A ground station that connects after the alignment missed its STATUSTEXT: tell it
        the navigation's state once (the mode events after this reach it as they happen)."""
        if est is None or est.mode == "initializing":
            return
        label = MODE_LABELS[Mode(est.mode)]
        self._pending_text.appendleft(NavEvent(int(est.time_us), "mode", "notice",
                                               f"Nav aligned: {label}", {"to": str(est.mode)}))

    def _gcs_step(self, now: float, schedule: dict[str, float]) -> None:
        link = self._links.get("gcs")
        vehicle, responder = self.vehicle, self.responder
        if link is None or self.shadow is None or vehicle is None or responder is None:
            return
        est = self.last_estimate
        mode = None if est is None else Mode(est.mode)
        base_mode, custom_mode, status = heartbeat_state(mode)
        link.set_heartbeat_state(base_mode=base_mode, custom_mode=custom_mode,
                                 system_status=status)
        for msg in link.recv(0.0):
            if not self._gcs_heard:
                self._gcs_heard = True
                self._greet_gcs(est)
            for frame in responder.handle(msg):
                self._gcs_send(link, frame)
                self.stats.gcs_answers += 1
        while self._pending_text:
            ev = self._pending_text.popleft()
            for frame in vehicle.statustexts([ev]):
                self._gcs_send(link, frame)
                self.stats.statustexts += 1
        while self._relay_text:
            severity, text = self._relay_text.popleft()
            self._gcs_send(link, self.shadow.statustext(severity, text))
            self.stats.statustexts += 1
        if est is not None and est.mode != "initializing" and now >= schedule["fast"]:
            for frame in vehicle.fast(est):
                self._gcs_send(link, frame)
            schedule["fast"] = now + 1.0 / self.options.telemetry_hz
        if now >= schedule["slow"]:
            if self._gcs_tlog is not None:  # the link sends its own; the log needs one too
                self._gcs_tlog.write(self.shadow.heartbeat(mode), self.shadow.time_us)
            for frame in vehicle.slow(est):
                self._gcs_send(link, frame)
            schedule["slow"] = now + 1.0

    def _reader(self, link: MavlinkLink, stop: threading.Event) -> None:
        """Own the input link: drain the socket into the queue as fast as frames arrive, so
        a filter that falls behind (CPU contention, first-call warm-up) builds a backlog in
        memory instead of overflowing the kernel's receive buffer (= losing frames). Also
        sends the lockstep acknowledgements (the link belongs to this thread)."""
        wake = self._wake_rx
        assert wake is not None
        acked_us = -1
        with selectors.DefaultSelector() as sel:
            sel.register(link.fileno(), selectors.EVENT_READ)
            sel.register(wake, selectors.EVENT_READ)
            while not stop.is_set():
                sel.select(0.05)
                with contextlib.suppress(BlockingIOError, InterruptedError):
                    while wake.recv(4096):
                        pass
                msgs = []
                for m in link.recv(0.0):
                    if m.get_msgId() == _HEARTBEAT_ID:
                        self._on_heartbeat(m)
                    else:
                        msgs.append(m)
                if msgs:
                    with self._cond:
                        self._queue.extend(msgs)
                        self.stats.last_input_wall = time.monotonic()
                        if self.stats.first_input_wall is None:
                            self.stats.first_input_wall = self.stats.last_input_wall
                        self._cond.notify()
                processed = self._processed_us
                if self._lockstep_sources and processed > acked_us:
                    t_ns = processed * 1000
                    if link.send_message(mavlink2.MAVLink_timesync_message(t_ns, t_ns)):
                        self.stats.lockstep_acks += 1
                    acked_us = processed

    def _on_heartbeat(self, msg: Any) -> None:
        """Follow which peers ask for lockstep acknowledgements (see the module docstring)."""
        source = (msg.get_srcSystem(), msg.get_srcComponent())
        if (int(msg.autopilot) == mavlink2.MAV_AUTOPILOT_INVALID
                and int(msg.custom_mode) == LOCKSTEP_CUSTOM_MODE):
            self._lockstep_sources.add(source)
        else:
            self._lockstep_sources.discard(source)

    def _wake_reader(self) -> None:
        if self._wake_tx is not None:
            with contextlib.suppress(BlockingIOError, InterruptedError):
                self._wake_tx.send(b"\0")  # full buffer: a wake-up is pending anyway

    def run(self, stop: threading.Event) -> None:
        """Serve until ``stop`` is set, ``duration_s`` passed, or input stayed idle for
        ``idle_exit_s`` after it had started (the backlog is processed first)."""
        o = self.options
        link = self._links["mavlink"]
        wall0 = self._wall0 = time.monotonic()
        schedule = {"fast": wall0, "slow": wall0, "housekeeping": wall0}
        reader_stop = threading.Event()
        self._wake_rx, self._wake_tx = socket.socketpair()
        self._wake_rx.setblocking(False)
        self._wake_tx.setblocking(False)
        reader = threading.Thread(target=self._reader, args=(link, reader_stop),
                                  name="mavlink-reader", daemon=True)
        reader.start()
        try:
            while not stop.is_set():
                with self._cond:
                    if not self._queue:
                        self._cond.wait(0.02)
                    batch = list(self._queue)
                    self._queue.clear()
                for msg in batch:
                    self._handle(msg)
                if batch and self._lockstep_sources:
                    self._wake_reader()
                now = time.monotonic()
                if now < schedule["housekeeping"]:
                    continue
                schedule["housekeeping"] = now + 0.02
                self._gcs_step(now, schedule)
                if "companion" in self._links:
                    self._links["companion"].recv(0.0)
                if batch:
                    continue
                if o.duration_s is not None and now - wall0 >= o.duration_s:
                    break
                last = self.stats.last_input_wall
                if o.idle_exit_s is not None and last is not None and now - last >= o.idle_exit_s:
                    break
        finally:
            reader_stop.set()
            self._wake_reader()
            reader.join(timeout=2.0)
            for s in (self._wake_rx, self._wake_tx):
                if s is not None:
                    s.close()
            self._wake_rx = self._wake_tx = None
        if self._bus is not None and self.last_estimate is not None:
            with contextlib.suppress(ValueError):
                self._bus.publish_status(self.last_estimate, links=self.link_counters(),
                                         force=True, thermal=self.nav.thermal_status)

    # ---------------------------------------------------------------- scorecard
    def live_section(self) -> dict[str, Any]:
        """The ``live`` section of the live scorecard: link counters and what was published."""
        counters = self.link_counters()
        col = self.fusion.collector
        link = self._links.get("mavlink")
        return {
            "source_system": self._source_system(link),
            "signed": link is not None and link.signed,
            "links": counters,
            "lost_frames": counters["mavlink"].get("lost_seq", 0),
            "fixes": 0 if col is None else col.n_fixes,
            "errors_published": self.stats.errors_published,
            "gcs_answers": self.stats.gcs_answers,
            "nav_events": self.stats.events,
            "statustexts_sent": self.stats.statustexts,
            "innovations_published": self.stats.innovations,
            "lockstep_acks": self.stats.lockstep_acks,
            "lockstep_acks_withheld": self._ack_clock.refused,
            "truth_from_other_components": self.stats.truth_other_component,
        }

    def _source_system(self, link: MavlinkLink | None) -> int | None:
        """The system the input is bound to: ``--source``, else the one the link locked onto
        (None: no sensor frame yet)."""
        if self.options.source is not None:
            return parse_source(self.options.source)[0]
        return None if link is None else link.locked_system

    def wall_s(self, fallback_s: float) -> float:
        """Wall time from the first frame in to the last frame fused (``fallback_s`` before
        any input)."""
        first, last = self.stats.first_input_wall, self.stats.last_processed_wall
        return last - first if first is not None and last is not None else fallback_s


def interpolate_truth(a: Truth, b: Truth, time_us: int) -> Truth:
    """Truth at ``time_us`` in ``[a.time_us, b.time_us]``: position, velocity and rates
    linear, attitude normalised linear (nlerp; < 1e-4 rad off a slerp at 50 Hz truth)."""
    if not a.time_us < b.time_us or not a.time_us <= time_us <= b.time_us:
        raise ValueError("time_us must lie within the two truth samples")
    w = (time_us - a.time_us) / (b.time_us - a.time_us)
    qa = np.asarray(a.q_nb, dtype=float)
    qb = np.asarray(b.q_nb, dtype=float)
    if float(qa @ qb) < 0.0:
        qb = -qb
    q = (1.0 - w) * qa + w * qb
    return dataclasses.replace(
        b,
        time_us=time_us,
        lat_rad=(1.0 - w) * a.lat_rad + w * b.lat_rad,
        lon_rad=(1.0 - w) * a.lon_rad + w * b.lon_rad,
        alt_msl_m=(1.0 - w) * a.alt_msl_m + w * b.alt_msl_m,
        v_ned_mps=(1.0 - w) * np.asarray(a.v_ned_mps) + w * np.asarray(b.v_ned_mps),
        q_nb=q / np.linalg.norm(q),
        omega_b_rps=(1.0 - w) * np.asarray(a.omega_b_rps) + w * np.asarray(b.omega_b_rps),
    )
