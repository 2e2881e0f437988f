"""``hilnav fusion``: the live fusion service.

Input (``--mavlink URL``)
    Sensor messages from hilnav's simulator (HIL_SENSOR, HIL_GPS; truth as
    HIL_STATE_QUATERNION from :data:`hil.codec.TRUTH_COMPONENT_ID`) or from a real flight
    controller (HIGHRES_IMU, SCALED_IMU*, RAW_IMU, GPS_RAW_INT, SCALED_PRESSURE*), decoded by
    :class:`hil.codec.Decoder` and run through :class:`fusion.filter.NavFilter` in arrival
    order (the same order a ``hilnav replay`` of the same frames sees: same seed, same numbers).

Outputs (all optional; none of them can block the filter)
    * ``--gcs URL``: a *shadow vehicle* for ground stations (own system id, component 1):
      HEARTBEAT (the link), GLOBAL_POSITION_INT / ATTITUDE / ATTITUDE_QUATERNION / VFR_HUD at
      ``telemetry_hz`` and SYS_STATUS / ESTIMATOR_STATUS / SYSTEM_TIME at 1 Hz (wall clock);
      minimal answers to PARAM_REQUEST_LIST / PARAM_REQUEST_READ (one parameter),
      COMMAND_LONG REQUEST_AUTOPILOT_CAPABILITIES / REQUEST_MESSAGE(AUTOPILOT_VERSION), and
      MISSION_REQUEST_LIST (zero items) so QGC / MAVProxy / MAVSDK connect without retries.
    * ``--companion URL --companion-kind gps_input|odometry``: GPS_INPUT (ArduPilot, 5 Hz)
      or ODOMETRY (PX4, 30 Hz) to a flight controller, on simulated time.
    * ``--zenoh EP``: estimate, status (mode, test ratios, health, link counters), error vs
      truth (estimate and truth of the same time), innovations (one message per aiding update,
      see below), a ``fusion/config`` queryable and a ``fusion/alive`` liveliness token
      (:class:`hil.bus.Bus`: bounded queue, never blocks).
    * ``--out DIR``: at exit, ``summary.json`` of everything received (estimate vs truth,
      GNSS outages from fix gaps), computed exactly as ``hilnav replay`` does, plus a
      ``live`` section with the link counters (sample loss).

Innovations (``fusion/innovations``)
    Every gated Kalman update of the filter is published: ``source`` (``gnss_pos``,
    ``gnss_vel``, ``baro_hgt``, ``mag_hdg``; ``bridge_pos`` / ``bridge_vel`` for pseudo-GNSS
    updates of a bridging strategy), the innovation (INS-predicted minus measured, SI units of
    the observation: m, m/s, m, rad), ``sqrt(diag(S))``, the test ratio (NIS over the gate,
    > 1 = rejected) and whether it was fused. ``time_us`` is the time of the sample whose
    processing made the update. The filter's public :class:`~fusion.filter.NavEstimate`
    carries only the last test ratio per source, so the service taps the filter's single
    update funnel (``NavFilter._correct``, see :class:`TappedNavFilter`); the numbers of the
    filter are unchanged. The source is read from which error-state block the observation
    matrix ``H`` touches (baro bias -> baro, position -> GNSS position, velocity -> GNSS
    velocity, attitude only -> magnetometer heading).

Lockstep acknowledgements (``hilnav sim --live URL --lockstep``)
    A simulator that asks for lockstep (HEARTBEAT with ``custom_mode`` =
    :data:`hil.link.LOCKSTEP_CUSTOM_MODE`) gets a TIMESYNC on the input link after every
    batch the filter has processed: ``ts1`` = ``tc1`` = simulated time in ns of the newest
    sample processed so far. The reader thread owns the link, so the filter thread wakes it
    through a socket pair to send the acknowledgement at once. Nothing is sent to other peers
    (a flight controller never sees a TIMESYNC from us).

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
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Final, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from fusion.config import FilterConfig
from fusion.error_model import StateLayout
from fusion.estimate import NavEstimate
from fusion.filter import NavFilter
from fusion.kalman import Correction
from hil.bus import Topic
from hil.codec import TRUTH_COMPONENT_ID, Decoder, mavlink2
from hil.link import (
    FC_SENSOR_MSG_IDS,
    HIL_MSG_IDS,
    LOCKSTEP_CUSTOM_MODE,
    LinkRole,
    MavlinkLink,
)
from hil.shadow import CompanionEncoder, ShadowEncoder
from hil.signing import Signer
from hil.tuning import filter_config_for_presets
from scenarios.collect import Collector
from sim.samples import GnssFix, Truth

__all__ = [
    "FusionOptions", "FusionService", "GcsResponder", "TappedNavFilter", "fusion_main",
    "innovation_source", "input_role", "interpolate_truth",
]

_TRUTH_ID: Final = int(mavlink2.MAVLINK_MSG_ID_HIL_STATE_QUATERNION)
_HEARTBEAT_ID: Final = int(mavlink2.MAVLINK_MSG_ID_HEARTBEAT)
_GCS_MSG_IDS: Final = frozenset({
    int(mavlink2.MAVLINK_MSG_ID_PARAM_REQUEST_LIST),
    int(mavlink2.MAVLINK_MSG_ID_PARAM_REQUEST_READ),
    int(mavlink2.MAVLINK_MSG_ID_COMMAND_LONG),
    int(mavlink2.MAVLINK_MSG_ID_MISSION_REQUEST_LIST),
})
_COMPANION_RATE_HZ: Final = {"gps_input": 5.0, "odometry": 30.0}
_ERROR_MATCH_KEEP: Final = 64  # recent estimates kept to pair with truth of the same time


class FusionOptions(BaseModel):
    """Validated options of the fusion service (see the module docstring)."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    mavlink: str
    zenoh: str | None = None
    vehicle: str = "sim1"
    imu: str = "industrial-mems"
    gnss: str = "modern"
    gcs: str | None = None
    shadow_system_id: int = Field(default=1, ge=1, le=255)
    companion: str | None = None
    companion_kind: Literal["gps_input", "odometry"] = "gps_input"
    companion_system_id: int = Field(default=1, ge=1, le=255)
    telemetry_hz: float = Field(default=10.0, gt=0.0, le=100.0)
    duration_s: float | None = Field(default=None, gt=0.0)
    idle_exit_s: float | None = Field(default=None, gt=0.0)
    out: Path | None = None
    settle_s: float = Field(default=60.0, ge=0.0)


def input_role() -> LinkRole:
    """The input link: an onboard computer (191) accepting simulator and flight-controller
    sensor messages from any source."""
    return LinkRole(
        system_id=1,
        component_id=int(mavlink2.MAV_COMP_ID_ONBOARD_COMPUTER),
        mav_type=int(mavlink2.MAV_TYPE_ONBOARD_CONTROLLER),
        autopilot=int(mavlink2.MAV_AUTOPILOT_INVALID),
        accept_sources=None,
        accept_msg_ids=HIL_MSG_IDS | FC_SENSOR_MSG_IDS,
    )


def shadow_role(system_id: int) -> LinkRole:
    """The shadow vehicle's role, accepting the few ground-station requests we answer."""
    base = LinkRole.shadow_vehicle(system_id=system_id)
    return base.model_copy(update={"accept_msg_ids": _GCS_MSG_IDS})


def innovation_source(layout: StateLayout, H: np.ndarray) -> str:
    """Aiding source of an observation from the error-state blocks its matrix touches.

    Parameters
    ----------
    layout : fusion.error_model.StateLayout
    H : ndarray, shape (m, n)
        Observation matrix of the update.

    Returns
    -------
    str
        ``baro_hgt`` (touches the baro bias), ``gnss_pos`` (position; a GNSS position model
        also has latency terms on velocity), ``gnss_vel`` (velocity), else ``mag_hdg``.
    """
    h = np.asarray(H)
    if np.any(h[:, layout.baro]):
        return "baro_hgt"
    if np.any(h[:, layout.pos]):
        return "gnss_pos"
    if np.any(h[:, layout.vel]):
        return "gnss_vel"
    return "mag_hdg"


class TappedNavFilter(NavFilter):
    """:class:`~fusion.filter.NavFilter` that keeps every gated update of the current step.

    ``corrections`` collects ``(H, Correction)`` of each update made through the filter's
    single update funnel; the owner reads and clears it after each :meth:`step`. The filter's
    arithmetic is untouched (the live scorecard still equals ``hilnav replay``).
    """

    def __init__(self, config: FilterConfig | None = None) -> None:
        self.corrections: list[tuple[np.ndarray, Correction]] = []
        super().__init__(config)

    def _correct(self, *args: Any, **kwargs: Any) -> Correction:
        res = super()._correct(*args, **kwargs)
        obs = args[0] if args else kwargs["obs"]
        self.corrections.append((obs.H, res))
        return res


class GcsResponder:
    """Minimal answers to ground-station requests (returns frames to send).

    One parameter is published (``HILNAV_SYSID``); AUTOPILOT_VERSION is answered to
    MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES and REQUEST_MESSAGE(148); any other command gets
    MAV_RESULT_UNSUPPORTED; mission lists have zero items.
    """

    def __init__(self, encoder: ShadowEncoder) -> None:
        self.enc = encoder
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
        return []

    def _command(self, msg: Any) -> list[bytes]:
        cmd = int(msg.command)
        src = (msg.get_srcSystem(), msg.get_srcComponent())
        wants_version = cmd == mavlink2.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES or (
            cmd == mavlink2.MAV_CMD_REQUEST_MESSAGE
            and int(msg.param1) == mavlink2.MAVLINK_MSG_ID_AUTOPILOT_VERSION
        )
        if wants_version:
            return [self.enc.command_ack(cmd, int(mavlink2.MAV_RESULT_ACCEPTED), *src),
                    self.enc.autopilot_version()]
        return [self.enc.command_ack(cmd, int(mavlink2.MAV_RESULT_UNSUPPORTED), *src)]


@dataclass
class _Stats:
    truth_other_component: int = 0
    errors_published: int = 0
    estimates: int = 0
    gcs_answers: int = 0
    innovations: int = 0
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
    """

    def __init__(self, options: FusionOptions, *, signing_key: bytes | None = None) -> None:
        self.options = options
        self.config = filter_config_for_presets(options.imu, options.gnss)
        self.nav = TappedNavFilter(self.config)
        self.decoder = Decoder()
        self.collector = Collector() if options.out is not None else None
        self.stats = _Stats()
        self._signing_key = signing_key
        self._recent: OrderedDict[int, NavEstimate] = OrderedDict()
        self.last_estimate: NavEstimate | None = None
        self._prev_truth: Truth | None = None
        self._links: dict[str, MavlinkLink] = {}
        self._bus: Any = None
        self.shadow: ShadowEncoder | None = None
        self.responder: GcsResponder | None = None
        self.companion: CompanionEncoder | None = None
        self._next_companion_us = 0
        self._wall0 = time.monotonic()
        self._queue: deque[Any] = deque()
        self._cond = threading.Condition()
        # lockstep: sources that asked for acknowledgements, newest processed sample time (us;
        # written by the filter thread, read by the reader thread), and the reader's wake-up
        self._lockstep_sources: set[tuple[int, int]] = set()
        self._processed_us = -1
        self._wake_rx: socket.socket | None = None
        self._wake_tx: socket.socket | None = None

    # ---------------------------------------------------------------- links
    def _signer(self, link_id: int) -> Signer | None:
        return None if self._signing_key is None else Signer(self._signing_key, link_id=link_id)

    def open(self, stack: contextlib.ExitStack) -> None:
        """Open every configured link and the bus (closed by ``stack``)."""
        o = self.options
        self._links["mavlink"] = stack.enter_context(
            MavlinkLink(o.mavlink, input_role(), signer=self._signer(0)))
        if o.gcs is not None:
            self.shadow = ShadowEncoder(o.shadow_system_id)
            self.responder = GcsResponder(self.shadow)
            self._links["gcs"] = stack.enter_context(
                MavlinkLink(o.gcs, shadow_role(o.shadow_system_id), signer=self._signer(1)))
        if o.companion is not None:
            role = LinkRole.companion(system_id=o.companion_system_id)
            self.companion = CompanionEncoder(role.system_id, role.component_id)
            self._links["companion"] = stack.enter_context(
                MavlinkLink(o.companion, role, signer=self._signer(2)))
        if o.zenoh is not None:
            from hil.bus import Bus

            self._bus = stack.enter_context(Bus(o.zenoh, vehicle=o.vehicle))
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
        for d in self.decoder.decode_message(msg):
            item = d.sample
            if item.time_us > self._processed_us:
                self._processed_us = item.time_us
            if isinstance(item, Truth):
                if d.component_id != TRUTH_COMPONENT_ID or d.msg_id != _TRUTH_ID:
                    self.stats.truth_other_component += 1
                    continue
                if self.collector is not None:
                    self.collector.feed(self.nav, [item])
                self._on_truth(item)
                continue
            if self.collector is not None:
                n = len(self.collector.estimates)
                self.collector.feed(self.nav, [item])
                ests = self.collector.estimates[n:]
            else:
                ests = self.nav.step(item)
            if self.nav.corrections:
                self._on_corrections(item)
            for est in ests:
                self._on_estimate(est)
            new.extend(ests)
        return new

    def _on_corrections(self, item: Any) -> None:
        """Publish the updates the last step made on ``fusion/innovations``."""
        nav = self.nav
        corrections = list(nav.corrections)
        nav.corrections.clear()
        if self._bus is None:
            return
        t = int(item.time_us)
        # pseudo-GNSS updates of a bridging strategy happen on IMU steps while bridging
        bridging = not isinstance(item, GnssFix) and nav.mode == "bridging"
        for H, res in corrections:
            source = innovation_source(nav.layout, H)
            if bridging and source.startswith("gnss_"):
                source = "bridge_" + source[5:]
            ratio = float(res.test_ratio)
            if self._bus.publish_innovation(t, source, res.innovation, S=res.S,
                                            test_ratio=ratio, accepted=ratio <= 1.0):
                self.stats.innovations += 1

    def _on_estimate(self, est: NavEstimate) -> None:
        self.stats.estimates += 1
        self.last_estimate = est
        self._recent[est.time_us] = est
        if len(self._recent) > _ERROR_MATCH_KEEP:
            self._recent.popitem(last=False)
        if est.mode == "initializing":
            return
        if self._bus is not None:
            self._bus.publish_estimate(est)
            if self._bus.due(Topic.STATUS, est.time_us):  # counters only when it is sent
                self._bus.publish_status(est, links=self.link_counters())
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
    def _gcs_step(self, now: float, schedule: dict[str, float]) -> None:
        link = self._links.get("gcs")
        if link is None or self.shadow is None or self.responder is None:
            return
        for msg in link.recv(0.0):
            for frame in self.responder.handle(msg):
                link.send(frame)
                self.stats.gcs_answers += 1
        est = self.last_estimate
        if est is not None and est.mode != "initializing" and now >= schedule["fast"]:
            for frame in self.shadow.telemetry(est):
                link.send(frame)
            schedule["fast"] = now + 1.0 / self.options.telemetry_hz
        if now >= schedule["slow"]:
            link.send(self.shadow.sys_status(est))
            link.send(self.shadow.system_time())
            if est is not None:
                link.send(self.shadow.estimator_status(est))
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
                                         force=True)

    # ---------------------------------------------------------------- scorecard
    def summary(self, wall_s: float) -> dict[str, Any] | None:
        """The live run's scorecard (as ``hilnav replay``) or None without ``--out`` / data."""
        col = self.collector
        if col is None:
            return None
        from scenarios import metrics
        from scenarios.replay import _as_dict
        from scenarios.summary import RunInfo, build_summary

        try:
            estimate = col.estimate_track()
            truth = col.truth_track()
        except ValueError:
            return None
        end_s = min(estimate.time_s[-1], truth.time_s[-1])
        outages = metrics.outages_from_fix_times(
            np.asarray(col.fix_times_us, dtype=float) * 1e-6, end_s=end_s)
        info = RunInfo(scenario="live", seed=None, sim_duration_s=col.last_time_us * 1e-6,
                       wall_s=wall_s, bridge="none", altitude="ekf")
        summary, _err = build_summary(
            info, estimate, truth, outages, settle_s=self.options.settle_s,
            health={"filter": _as_dict(self.nav.health),
                    "decoder": _as_dict(self.decoder.counters)})
        counters = self.link_counters()
        mav = counters["mavlink"]
        summary["live"] = {
            "links": counters,
            "lost_frames": mav.get("lost_seq", 0),
            "fixes": len(col.fix_times_us),
            "errors_published": self.stats.errors_published,
            "gcs_answers": self.stats.gcs_answers,
            "innovations_published": self.stats.innovations,
            "lockstep_acks": self.stats.lockstep_acks,
            "truth_from_other_components": self.stats.truth_other_component,
        }
        return summary


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


def fusion_main(
    options: FusionOptions,
    *,
    signing_key: bytes | None = None,
    stop: threading.Event | None = None,
    on_ready: Callable[[FusionService], None] | None = None,
) -> dict[str, Any] | None:
    """Run the fusion service until stopped; write ``summary.json`` into ``options.out``.

    Returns
    -------
    dict or None
        The live run's summary (None without ``out`` or without estimate + truth).
    """
    from hil.live_sim import stop_on_signals
    from scenarios.summary import write_summary

    service = FusionService(options, signing_key=signing_key)
    with contextlib.ExitStack() as stack:
        if stop is None:
            stop = stack.enter_context(stop_on_signals())
        service.open(stack)
        if on_ready is not None:
            on_ready(service)
        t0 = time.monotonic()
        service.run(stop)
        wall = time.monotonic() - t0
        first, last = service.stats.first_input_wall, service.stats.last_processed_wall
        if first is not None and last is not None:
            wall = last - first  # first frame in -> last frame fused
    summary = service.summary(wall)
    if summary is not None and options.out is not None:
        options.out.mkdir(parents=True, exist_ok=True)
        write_summary(summary, options.out / "summary.json")
    return summary

