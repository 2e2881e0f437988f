"""The autopilot's own estimate and health, recorded from its MAVLink telemetry.

An autopilot in the loop reports what it believes on a link of its own, as it does to a ground
station (PX4 SITL: its MAVLink instance to UDP 14550; ArduPilot SITL: ``--out
udp:127.0.0.1:14550``). :class:`AutopilotTelemetry` listens there (a :class:`hil.link.MavlinkLink`
owned by one background thread, as a ground station: system 255, component 190) and records

* the estimate: GLOBAL_POSITION_INT (position, velocity), ATTITUDE (roll, pitch, yaw),
  LOCAL_POSITION_NED when sent; :meth:`AutopilotTelemetry.estimate_track` merges them into a
  :class:`hil.tracks.Track` that the scorer takes exactly as it takes hilnav's;
* its health: HEARTBEAT (mode, armed, system status: every change), STATUSTEXT (failsafe and
  warning messages), ESTIMATOR_STATUS (PX4: solution flags, test ratios, 1-sigma accuracies),
  EKF_STATUS_REPORT (ArduPilot: flags and its "variances", which are normalised innovation test
  ratios, not covariances).

Once the autopilot's heartbeat is heard, the recorder asks for the messages it needs at
``rate_hz`` (MAV_CMD_SET_MESSAGE_INTERVAL, which PX4 and ArduPilot both honour) and counts the
acknowledgements. It asks each autopilot only for what it has: the estimator status is
ESTIMATOR_STATUS from PX4 (PX4 does not stream EKF_STATUS_REPORT and refuses it) and
EKF_STATUS_REPORT from ArduPilot; another autopilot is asked for neither.

Talking back
    The recorder owns the link in its thread; a :class:`LinkClient` attached before the start
    (:meth:`AutopilotTelemetry.attach`: the scenario's commander, hilnav's aiding frames) is
    handed every message received and gives what to send, so the link is never used from two
    threads. PARAM_VALUE and the mission protocol's answers are accepted for it.

Before the autopilot has a position
    A booting ArduPilot sends GLOBAL_POSITION_INT at lat/lon 0/0 (and -1000 m) until its EKF
    has an origin. Position reports are dropped (``positions_before_fix``) until the first
    one that is not exactly 0/0 while the latest estimator status (when one was heard) says
    the absolute horizontal position is valid (``POS_HORIZ_ABS``); from then on every report
    is kept, outages included. :attr:`AutopilotTelemetry.estimate_from_s` is that first time:
    the autopilot's estimate is scored from there.

STATUSTEXT
    A text longer than one message (50 characters) arrives in chunks (MAVLink 2 ``id`` != 0,
    ``chunk_seq`` 0, 1, ...): the chunks are joined by ``id``; a chunk shorter than 50
    characters (or NUL-terminated) ends the text; a text whose end never comes is kept as it
    stands once ``TEXT_CHUNK_TIMEOUT_S`` of autopilot time passed, or when the recording is
    read.

Time axis
    Every report is stamped with the autopilot's ``time_boot_ms`` (ESTIMATOR_STATUS with its
    ``time_usec``; EKF_STATUS_REPORT and STATUSTEXT, which carry no time, with the newest
    autopilot time heard). In lockstep SITL the autopilot's clock *is* the simulator's:
    PX4's ``SimulatorMavlink::handle_message_hil_sensor`` sets ``CLOCK_MONOTONIC`` (hence
    ``hrt_absolute_time``, from which ``time_boot_ms`` is taken) to the ``time_usec`` of each
    HIL_SENSOR of IMU id 0; ArduPilot's ``SIM_JSON.cpp`` (``JSON::recv_fdm``) advances its
    ``time_now_us`` by the difference of consecutive JSON ``timestamp`` values, starting from 0.
    Our HIL_SENSOR ``time_usec`` and the JSON timestamp are the simulated time since the flight
    start (``Truth.time_us``), so ``time_us = time_boot_ms * 1000 + time_offset_us`` with
    ``time_offset_us = 0`` puts the estimate on the simulated time axis, to the 1 ms resolution
    of ``time_boot_ms``. This does not hold for an autopilot that is not in lockstep (HITL on
    its own crystal; ArduPilot after a physics reset, when the timestamp went backwards):
    give ``time_offset_us`` there, or score the estimate knowing its clock drifts.
    Times are kept in integer microseconds and reported in seconds as ``time_us / 1e6`` (the
    nearest float to the autopilot's millisecond, never 2.2159999999999997 for 2216 ms).
"""

from __future__ import annotations

import threading
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Final, Protocol

import numpy as np

from hil.codec import mavlink2
from hil.codec.estimate_messages import (
    AttitudeReport,
    LocalPositionReport,
    PositionReport,
    decode_attitude,
    decode_global_position_int,
    decode_local_position_ned,
)
from hil.link import LinkRole, MavlinkLink
from hil.signing import Signer
from hil.tracks import Track

__all__ = ["COMMAND_REPLY_IDS", "TELEMETRY_MSG_IDS", "AutopilotTelemetry", "LinkClient",
           "ground_station_role"]

_GPI: Final = int(mavlink2.MAVLINK_MSG_ID_GLOBAL_POSITION_INT)
_ATT: Final = int(mavlink2.MAVLINK_MSG_ID_ATTITUDE)
_LPN: Final = int(mavlink2.MAVLINK_MSG_ID_LOCAL_POSITION_NED)
_EST: Final = int(mavlink2.MAVLINK_MSG_ID_ESTIMATOR_STATUS)
_EKF: Final = int(mavlink2.MAVLINK_MSG_ID_EKF_STATUS_REPORT)
_TXT: Final = int(mavlink2.MAVLINK_MSG_ID_STATUSTEXT)
_ACK: Final = int(mavlink2.MAVLINK_MSG_ID_COMMAND_ACK)
_HB: Final = int(mavlink2.MAVLINK_MSG_ID_HEARTBEAT)
_MSC: Final = int(mavlink2.MAVLINK_MSG_ID_MISSION_CURRENT)

TELEMETRY_MSG_IDS: Final = frozenset({_GPI, _ATT, _LPN, _EST, _EKF, _TXT, _ACK, _MSC})
"""What the recorder accepts besides HEARTBEAT."""
COMMAND_REPLY_IDS: Final = frozenset({
    int(mavlink2.MAVLINK_MSG_ID_PARAM_VALUE), int(mavlink2.MAVLINK_MSG_ID_MISSION_REQUEST_INT),
    int(mavlink2.MAVLINK_MSG_ID_MISSION_REQUEST), int(mavlink2.MAVLINK_MSG_ID_MISSION_ACK)})
"""What the autopilot answers a commander with (:meth:`AutopilotTelemetry.attach`)."""
#: Messages asked for at ``rate_hz``: the estimate, and the estimator status each autopilot has.
_REQUESTED: Final = (_GPI, _ATT, _LPN)
#: ... and the mission item it flies, at this rate (Hz).
_MISSION_CURRENT_HZ: Final = 2.0
_STATUS_OF: Final = {int(mavlink2.MAV_AUTOPILOT_PX4): _EST,
                     int(mavlink2.MAV_AUTOPILOT_ARDUPILOTMEGA): _EKF}
_ARMED: Final = int(mavlink2.MAV_MODE_FLAG_SAFETY_ARMED)
#: ESTIMATOR_STATUS_FLAGS / EKF_STATUS_FLAGS bit of a valid absolute horizontal position.
POS_HORIZ_ABS: Final = int(mavlink2.ESTIMATOR_POS_HORIZ_ABS)
_MAX_TEXTS: Final = 1000
_TEXT_CHUNK: Final = 50  # characters of one STATUSTEXT
TEXT_CHUNK_TIMEOUT_S: Final = 2.0
"""Autopilot seconds after which an incomplete chunked STATUSTEXT is kept as it stands."""
_SEVERITY_WARNING: Final = int(mavlink2.MAV_SEVERITY_WARNING)
_CLIENT_POLL_S: Final = 0.005


class LinkClient(Protocol):
    """Something that talks to the autopilot over the recorder's link
    (:class:`hil.autopilot.commander.Commander`): it is handed every message received and
    gives the messages to send, both from the recorder's thread."""

    def deliver(self, msg: Any) -> None: ...

    def take_outgoing(self) -> list[Any]: ...


def ground_station_role(autopilot_system_id: int | None = None) -> LinkRole:
    """The recorder on the autopilot's telemetry link: a ground station (system 255, component
    190, ``MAV_TYPE_GCS``) accepting the estimate, health and acknowledgement messages of the
    autopilot ``autopilot_system_id`` (None: the first system that speaks, then only it)."""
    return LinkRole(
        system_id=255,
        component_id=int(mavlink2.MAV_COMP_ID_MISSIONPLANNER),
        mav_type=int(mavlink2.MAV_TYPE_GCS),
        autopilot=int(mavlink2.MAV_AUTOPILOT_INVALID),
        accept_sources=None if autopilot_system_id is None
        else frozenset({(autopilot_system_id, None)}),
        accept_msg_ids=TELEMETRY_MSG_IDS | COMMAND_REPLY_IDS,
        lock_to_first_source=autopilot_system_id is None,
    )


@dataclass(frozen=True)
class _Status:
    """One estimator health report: time (autopilot clock, us), flags, named values."""

    time_us: int
    flags: int
    values: dict[str, float]


class AutopilotTelemetry:
    """Records an autopilot's estimate and health from its telemetry link (see the module
    docstring).

    Parameters
    ----------
    url : str
        The telemetry link, e.g. ``"udpin:127.0.0.1:14550"`` (port 0: a free port, see
        :attr:`local_address`).
    autopilot_system_id : int, optional
        Only this system's messages are recorded (default: the first that speaks).
    rate_hz : float or None
        Ask the autopilot for its estimate messages at this rate (autopilot time); None: take
        the rates it sends anyway.
    time_offset_us : int
        Added to ``time_boot_ms * 1000`` to reach simulated time (0 in lockstep SITL).
    signer : hil.signing.Signer, optional
        MAVLink 2 signing on the telemetry link.

    Raises
    ------
    ValueError
        A bad URL or a port that cannot be bound (from :class:`hil.link.MavlinkLink`), a
        rate that is not > 0.
    """

    def __init__(self, url: str, *, autopilot_system_id: int | None = None,
                 rate_hz: float | None = 10.0, time_offset_us: int = 0,
                 signer: Signer | None = None) -> None:
        if rate_hz is not None and not rate_hz > 0:
            raise ValueError(f"telemetry rate must be > 0 Hz, got {rate_hz}")
        self.url = url
        self.rate_hz = rate_hz
        self.time_offset_us = int(time_offset_us)
        self._link = MavlinkLink(url, ground_station_role(autopilot_system_id), signer=signer)
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._positions: list[PositionReport] = []
        self._attitudes: list[AttitudeReport] = []
        self._locals: list[LocalPositionReport] = []
        self._status: list[_Status] = []
        self._texts: list[dict[str, Any]] = []
        self._chunks: dict[int, tuple[int, int, list[str]]] = {}  # id: (time_us, severity, parts)
        self._armed: bool | None = None
        self._position_from_us: int | None = None
        self._modes: list[dict[str, Any]] = []
        self._mission_current: list[dict[str, Any]] = []
        self._autopilot: tuple[int, int] | None = None
        self._autopilot_kind: int | None = None
        self._last_time_us = 0
        self._requested = False
        self._count: dict[str, int] = dict.fromkeys(
            ("position_reports", "positions_before_fix", "attitude_reports",
             "local_position_reports",
             "rejected_reports", "out_of_order", "heartbeats", "statustexts",
             "statustexts_dropped", "estimator_status", "ekf_status", "interval_requests",
             "interval_acks_ok", "interval_acks_refused"), 0)
        self._link_counters: dict[str, int] | None = None
        self._clients: list[LinkClient] = []
        self._custom_mode: int | None = None
        self.error: str | None = None
        """Why the recording thread ended early (None: it did not)."""
        self.local_address = self._link.local_address
        """Where the link listens (``(host, port)`` for ``udpin`` / ``tcpin``)."""

    # -- life cycle --
    def attach(self, client: LinkClient) -> None:
        """Let ``client`` talk to the autopilot over this link (before :meth:`start`): the
        recorder's thread, which owns the link, hands it every message and sends what it
        gives (pymavlink messages, packed as the ground station, or whole frames, sent with
        their own ids), polling every ``_CLIENT_POLL_S`` wall seconds."""
        if self._thread is not None:
            raise RuntimeError("attach a link client before starting the recorder")
        self._clients.append(client)

    def start(self) -> AutopilotTelemetry:
        """Start recording in a background thread; returns self."""
        if self._thread is not None:
            raise RuntimeError("telemetry recorder already started")
        self._thread = threading.Thread(target=self._run, name="autopilot-telemetry",
                                        daemon=True)
        self._thread.start()
        return self

    def stop(self, timeout_s: float = 5.0) -> None:
        """Stop recording and close the link (idempotent)."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout_s)
        else:
            self._link.close()

    def __enter__(self) -> AutopilotTelemetry:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def _run(self) -> None:
        link = self._link
        try:
            clients = list(self._clients)
            wait_s = _CLIENT_POLL_S if clients else 0.1
            while not self._stop.is_set():
                for msg in link.recv(wait_s):
                    self._on_message(msg)
                    for client in clients:
                        client.deliver(msg)
                for client in clients:
                    for out in client.take_outgoing():
                        if isinstance(out, bytes):
                            link.send(out)
                        else:
                            link.send_message(out)
                if not self._requested and self._autopilot is not None and self.rate_hz:
                    self._request_rates()
            for msg in link.recv(0.0):  # what arrived before the stop
                self._on_message(msg)
        except Exception as exc:  # the recorder ends; the run reports why
            self.error = f"{type(exc).__name__}: {exc}"
        finally:
            link.close()
            self._link_counters = link.counters()

    # -- receiving --
    def _on_message(self, msg: Any) -> None:
        msg_id = msg.get_msgId()
        source = (msg.get_srcSystem(), msg.get_srcComponent())
        with self._lock:
            if msg_id == _HB:
                self._on_heartbeat(msg, source)
            elif msg_id == _GPI:
                self._on_position(msg)
            elif msg_id == _ATT:
                self._add(decode_attitude(msg), self._attitudes, "attitude_reports")
            elif msg_id == _LPN:
                self._add(decode_local_position_ned(msg), self._locals,
                          "local_position_reports")
            elif msg_id == _EST:
                self._on_estimator_status(msg)
            elif msg_id == _EKF:
                self._on_ekf_status(msg)
            elif msg_id == _TXT:
                self._on_text(msg)
            elif msg_id == _ACK:
                self._on_ack(msg)
            elif msg_id == _MSC:
                self._on_mission_current(msg)

    def _stamp(self, time_us: int) -> int:
        return time_us + self.time_offset_us

    def _seconds(self, time_us: int) -> float:
        """Autopilot time (us) -> simulated seconds, as exact as the float allows."""
        return self._stamp(time_us) / 1e6

    def _on_position(self, msg: Any) -> None:
        if self._position_from_us is None:
            no_origin = int(msg.lat) == 0 and int(msg.lon) == 0
            no_position = bool(self._status) and not self._status[-1].flags & POS_HORIZ_ABS
            if no_origin or no_position:
                self._count["positions_before_fix"] += 1
                self._last_time_us = max(self._last_time_us, int(msg.time_boot_ms) * 1000)
                return
        report = decode_global_position_int(msg)
        if report is not None and self._position_from_us is None:
            self._position_from_us = report.time_us
        self._add(report, self._positions, "position_reports")

    def _add(self, report: Any, into: list[Any], counter: str) -> None:
        if report is None:
            self._count["rejected_reports"] += 1
            return
        t = report.time_us
        if into and t < into[-1].time_us:
            self._count["out_of_order"] += 1
        self._last_time_us = max(self._last_time_us, t)
        into.append(report)
        self._count[counter] += 1

    def _on_heartbeat(self, msg: Any, source: tuple[int, int]) -> None:
        if int(msg.autopilot) == int(mavlink2.MAV_AUTOPILOT_INVALID):
            return  # a ground station or companion on the same link, not the autopilot
        if self._autopilot is None:
            self._autopilot = source
            self._autopilot_kind = int(msg.autopilot)
        if source != self._autopilot:
            return
        self._count["heartbeats"] += 1
        armed = bool(int(msg.base_mode) & _ARMED)
        self._armed = armed
        self._custom_mode = int(msg.custom_mode)
        state = {"custom_mode": int(msg.custom_mode), "armed": armed,
                 "system_status": int(msg.system_status)}
        if not self._modes or {k: self._modes[-1][k] for k in state} != state:
            self._modes.append({"time_s": self._seconds(self._last_time_us), **state})

    def _on_estimator_status(self, msg: Any) -> None:
        t = int(msg.time_usec)
        self._last_time_us = max(self._last_time_us, t)
        self._status.append(_Status(t, int(msg.flags), {
            "vel_ratio": float(msg.vel_ratio), "pos_horiz_ratio": float(msg.pos_horiz_ratio),
            "pos_vert_ratio": float(msg.pos_vert_ratio), "mag_ratio": float(msg.mag_ratio),
            "tas_ratio": float(msg.tas_ratio),
            "pos_horiz_accuracy_m": float(msg.pos_horiz_accuracy),
            "pos_vert_accuracy_m": float(msg.pos_vert_accuracy)}))
        self._count["estimator_status"] += 1

    def _on_ekf_status(self, msg: Any) -> None:
        self._status.append(_Status(self._last_time_us, int(msg.flags), {
            "velocity_variance": float(msg.velocity_variance),
            "pos_horiz_variance": float(msg.pos_horiz_variance),
            "pos_vert_variance": float(msg.pos_vert_variance),
            "compass_variance": float(msg.compass_variance)}))
        self._count["ekf_status"] += 1

    def _on_text(self, msg: Any) -> None:
        self._count["statustexts"] += 1
        raw = msg.text if isinstance(msg.text, str) else bytes(msg.text).decode(
            "utf-8", "replace")
        text = raw.split("\x00", 1)[0]
        ends = len(text) < _TEXT_CHUNK or "\x00" in raw
        text_id = int(getattr(msg, "id", 0) or 0)
        now = self._last_time_us
        self._flush_chunks(now - round(TEXT_CHUNK_TIMEOUT_S * 1e6))
        if text_id == 0:
            self._keep_text(now, int(msg.severity), text)
            return
        t0, severity, parts = self._chunks.get(text_id, (now, int(msg.severity), []))
        seq = int(getattr(msg, "chunk_seq", 0) or 0)
        if seq != len(parts):  # a lost or repeated chunk: keep what came, start again
            if parts:
                self._keep_text(t0, severity, "".join(parts))
            t0, severity, parts = now, int(msg.severity), []
        parts.append(text)
        if ends:
            self._chunks.pop(text_id, None)
            self._keep_text(t0, severity, "".join(parts))
        else:
            self._chunks[text_id] = (t0, severity, parts)

    def _flush_chunks(self, before_us: int) -> None:
        """Keep the incomplete chunked texts begun before ``before_us`` as they stand."""
        for text_id, (t0, severity, parts) in list(self._chunks.items()):
            if t0 <= before_us:
                del self._chunks[text_id]
                self._keep_text(t0, severity, "".join(parts))

    def _keep_text(self, time_us: int, severity: int, text: str) -> None:
        if len(self._texts) >= _MAX_TEXTS:
            self._count["statustexts_dropped"] += 1
            return
        self._texts.append({"time_s": self._seconds(time_us), "severity": severity,
                            "text": text})

    def _on_mission_current(self, msg: Any) -> None:
        """Keep each change of the mission item flown, at the autopilot's latest time
        (MISSION_CURRENT carries no time of its own)."""
        seq = int(msg.seq)
        if self._mission_current and self._mission_current[-1]["seq"] == seq:
            return
        self._mission_current.append({"time_s": self._seconds(self._last_time_us),
                                      "seq": seq})

    def _on_ack(self, msg: Any) -> None:
        if int(msg.command) != int(mavlink2.MAV_CMD_SET_MESSAGE_INTERVAL):
            return
        ok = int(msg.result) == int(mavlink2.MAV_RESULT_ACCEPTED)
        self._count["interval_acks_ok" if ok else "interval_acks_refused"] += 1

    def _request_rates(self) -> None:
        assert self._autopilot is not None and self.rate_hz is not None
        target_sys, target_comp = self._autopilot
        interval_us = 1e6 / self.rate_hz
        status = _STATUS_OF.get(self._autopilot_kind or 0)
        wanted = [(msg_id, interval_us) for msg_id in _REQUESTED]
        if status is not None:
            wanted.append((status, interval_us))
        wanted.append((_MSC, 1e6 / _MISSION_CURRENT_HZ))
        for msg_id, every_us in wanted:
            cmd = mavlink2.MAVLink_command_long_message(
                target_sys, target_comp, int(mavlink2.MAV_CMD_SET_MESSAGE_INTERVAL), 0,
                float(msg_id), every_us, 0, 0, 0, 0, 0)
            if self._link.send_message(cmd):
                self._count["interval_requests"] += 1
        self._requested = True

    # -- results --
    @property
    def armed(self) -> bool | None:
        """The armed flag of the autopilot's latest HEARTBEAT (None: none heard yet)."""
        with self._lock:
            return self._armed

    @property
    def custom_mode(self) -> int | None:
        """The ``custom_mode`` of the autopilot's latest HEARTBEAT (None: none heard yet)."""
        with self._lock:
            return self._custom_mode

    @property
    def estimate_from_s(self) -> float | None:
        """Simulated time of the first position report kept (the autopilot had a position
        from then on); None before one."""
        with self._lock:
            t = self._position_from_us
        return None if t is None else self._seconds(t)

    @property
    def connected(self) -> bool:
        """Whether the autopilot's heartbeat was heard."""
        with self._lock:
            return self._autopilot is not None

    def counters(self) -> dict[str, int]:
        """Report counters of the recorder plus the link's (prefixed ``link_``)."""
        with self._lock:
            out = dict(self._count)
        link = self._link_counters
        if link is None and self._thread is None:
            link = self._link.counters()
        for k, v in (link or {}).items():
            out[f"link_{k}"] = int(v)
        return out

    def estimate_track(self) -> Track:
        """The autopilot's estimate on the simulated time axis, at its GLOBAL_POSITION_INT
        times, the ATTITUDE angles interpolated to them (yaw unwrapped); positions outside
        the attitude reports' span are left out (never extrapolated).

        Raises
        ------
        ValueError
            No position or no attitude report was received.
        """
        with self._lock:
            pos = list(self._positions)
            att = list(self._attitudes)
        if not pos or not att:
            raise ValueError(
                f"the autopilot's telemetry held {len(pos)} GLOBAL_POSITION_INT and "
                f"{len(att)} ATTITUDE reports: nothing to score")
        pos.sort(key=lambda r: r.time_us)
        att.sort(key=lambda r: r.time_us)
        t_att = np.array([r.time_us for r in att], dtype=np.float64)
        eul = np.array([r.euler_rad for r in att])
        t_pos = np.array([r.time_us for r in pos], dtype=np.float64)
        keep = (t_pos >= t_att[0]) & (t_pos <= t_att[-1])
        if not np.any(keep):
            raise ValueError("the autopilot's position and attitude reports do not overlap "
                             "in time: nothing to score")
        t = t_pos[keep]
        euler = np.column_stack(
            [np.interp(t, t_att, np.unwrap(eul[:, k]) if k == 2 else eul[:, k])
             for k in range(3)])
        euler[:, 2] = (euler[:, 2] + np.pi) % (2.0 * np.pi) - np.pi
        kept = [r for r, k in zip(pos, keep, strict=True) if k]
        return Track(
            time_s=(t + self.time_offset_us) / 1e6,
            lat_rad=np.array([r.lat_rad for r in kept]),
            lon_rad=np.array([r.lon_rad for r in kept]),
            alt_m=np.array([r.alt_msl_m for r in kept]),
            v_ned_mps=np.array([r.v_ned_mps for r in kept]),
            euler_rad=euler,
        )

    def health(self) -> dict[str, Any]:
        """The autopilot's health for the scorecard: its mode / armed / status changes, the
        mission item it flies at each change (``mission_current``: MISSION_CURRENT's ``seq``
        in the list it was sent, ArduPilot's home slot 0 included), its
        STATUSTEXT messages (``warnings``: severity WARNING or worse; ``failsafes``: those
        that say "failsafe"), and its estimator status (flags at every change, the times the
        absolute horizontal position was declared lost / regained, the largest test ratios
        or variances and accuracies)."""
        with self._lock:
            self._flush_chunks(self._last_time_us)
            modes = [dict(m) for m in self._modes]
            mission_current = [dict(m) for m in self._mission_current]
            texts = [dict(t) for t in self._texts]
            status = list(self._status)
            kind = self._autopilot_kind
            source = self._autopilot
        flags_changes: list[dict[str, Any]] = []
        pos_lost: list[float] = []
        pos_regained: list[float] = []
        peaks: dict[str, float] = {}
        prev: int | None = None
        for s in status:
            t = self._seconds(s.time_us)
            if s.flags != prev:
                flags_changes.append({"time_s": t, "flags": s.flags})
                had = prev is not None and bool(prev & POS_HORIZ_ABS)
                has = bool(s.flags & POS_HORIZ_ABS)
                if had and not has:
                    pos_lost.append(t)
                elif has and prev is not None and not had:
                    pos_regained.append(t)
                prev = s.flags
            for k, v in s.values.items():
                if np.isfinite(v):
                    peaks[k] = max(peaks.get(k, v), v)
        return {
            "autopilot_type": kind,
            "system_id": None if source is None else source[0],
            "component_id": None if source is None else source[1],
            "modes": modes,
            "armed_ever": any(m["armed"] for m in modes),
            "mission_current": mission_current,
            "statustext": texts,
            "warnings": [t for t in texts if t["severity"] <= _SEVERITY_WARNING],
            "failsafes": [t for t in texts if "failsafe" in t["text"].lower()],
            "estimator": {
                "reports": len(status),
                "flags_changes": flags_changes,
                "pos_horiz_abs_lost_s": pos_lost,
                "pos_horiz_abs_regained_s": pos_regained,
                "max": peaks,
            },
        }

    def snapshot(self) -> Mapping[str, Any]:
        """Counts of what was received so far (for progress lines)."""
        with self._lock:
            return {"positions": len(self._positions), "attitudes": len(self._attitudes),
                    "connected": self._autopilot is not None}
