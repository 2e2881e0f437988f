"""The telemetry side of an autopilot, for tests of the estimate recorder and the scorecard.

:class:`EstimateSender` sends what an autopilot's MAVLink instance sends a ground station
(HEARTBEAT, GLOBAL_POSITION_INT, ATTITUDE, ESTIMATOR_STATUS, STATUSTEXT, COMMAND_ACK for
SET_MESSAGE_INTERVAL) over a real ``udpout`` link, as real MAVLink 2 bytes. Its "estimate" is
the truth it is given plus a *known* error: ``offset_north_m`` inside the ``windows`` (e.g. a
GNSS outage) and ``yaw_offset_deg`` always, so a test can check the scorecard's numbers against
them. Inside the windows its estimator status drops ESTIMATOR_POS_HORIZ_ABS and it sends one
failsafe STATUSTEXT, as an autopilot that lost GNSS does.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from fusion import earth, rotations
from hil.codec import mavlink2
from hil.link import LinkRole, MavlinkLink
from sim.samples import Truth

_FLAGS_OK = int(mavlink2.ESTIMATOR_ATTITUDE | mavlink2.ESTIMATOR_VELOCITY_HORIZ
                | mavlink2.ESTIMATOR_POS_HORIZ_ABS | mavlink2.ESTIMATOR_POS_VERT_ABS)


#: A STATUSTEXT longer than one message, as its two chunks ("failsafe" split between them).
LONG_TEXT_CHUNKS = ("Data link lost to the ground control station: fail",
                    "safe action is return to launch")
assert len(LONG_TEXT_CHUNKS[0]) == 50


class EstimateSender:
    """An autopilot's telemetry link (system 1, component 1) sending truth + known errors."""

    def __init__(self, url: str, *, rate_hz: float = 10.0, offset_north_m: float = 0.0,
                 windows: Sequence[tuple[float, float]] = (), yaw_offset_deg: float = 0.0,
                 autopilot: int = int(mavlink2.MAV_AUTOPILOT_PX4),
                 no_fix_before_s: float = 0.0) -> None:
        """Sends as PX4 does (``autopilot``): it refuses a message interval for a message it
        does not stream (PX4: EKF_STATUS_REPORT; ArduPilot: ESTIMATOR_STATUS), and on
        entering a window it sends a short STATUSTEXT and a long one in two MAVLink 2 chunks
        (``id`` 7, ``chunk_seq`` 0 and 1) with "failsafe" split across them. Its mission
        item (MISSION_CURRENT) is 1, and one more at each edge of a window. Before
        ``no_fix_before_s`` it has no position: GLOBAL_POSITION_INT at lat/lon 0/0, -1000 m,
        and no absolute horizontal position in ESTIMATOR_STATUS."""
        self.no_fix_before_s = no_fix_before_s
        self.refuses = (int(mavlink2.MAVLINK_MSG_ID_ESTIMATOR_STATUS)
                        if autopilot == int(mavlink2.MAV_AUTOPILOT_ARDUPILOTMEGA)
                        else int(mavlink2.MAVLINK_MSG_ID_EKF_STATUS_REPORT))
        role = LinkRole(system_id=1, component_id=1, mav_type=int(mavlink2.MAV_TYPE_FIXED_WING),
                        autopilot=autopilot,
                        accept_msg_ids=frozenset({int(mavlink2.MAVLINK_MSG_ID_COMMAND_LONG)}))
        self.link = MavlinkLink(url, role)
        self.link.set_heartbeat_state(base_mode=int(mavlink2.MAV_MODE_FLAG_SAFETY_ARMED),
                                      custom_mode=4 << 16)
        self.period_us = round(1e6 / rate_hz)
        self.offset_north_m = offset_north_m
        self.windows = tuple(windows)
        self.yaw_offset_rad = math.radians(yaw_offset_deg)
        self.next_us = 0
        self.sent = 0
        self.commands: list[int] = []
        self._announced = False

    def in_window(self, time_s: float) -> bool:
        return any(a <= time_s < b for a, b in self.windows)

    def send_truth(self, truth: Truth) -> None:
        """Send the estimate of ``truth`` when due (every ``1/rate_hz`` simulated s)."""
        for msg in self.link.recv(0.0):
            if msg.get_msgId() == mavlink2.MAVLINK_MSG_ID_COMMAND_LONG:
                self.commands.append(int(msg.param1))
                result = (mavlink2.MAV_RESULT_DENIED if int(msg.param1) == self.refuses
                          else mavlink2.MAV_RESULT_ACCEPTED)
                self.link.send_message(mavlink2.MAVLink_command_ack_message(
                    msg.command, int(result)))
        if truth.time_us < self.next_us:
            return
        self.next_us = truth.time_us + self.period_us
        t_s = truth.time_us * 1e-6
        inside = self.in_window(t_s)
        lat, alt = truth.lat_rad, truth.alt_msl_m
        if inside:
            r_n, _ = earth.principal_radii(lat)
            lat = lat + self.offset_north_m / (float(r_n) + alt)
        roll, pitch, yaw = (float(v) for v in rotations.quat_to_euler(truth.q_nb))
        yaw = (yaw + self.yaw_offset_rad + math.pi) % (2 * math.pi) - math.pi
        ms = truth.time_us // 1000
        v = np.round(truth.v_ned_mps * 100.0).astype(int)
        lat_e7 = round(math.degrees(lat) * 1e7)
        lon_e7 = round(math.degrees(truth.lon_rad) * 1e7)
        no_fix = t_s < self.no_fix_before_s
        if no_fix:
            lat_e7, lon_e7, alt = 0, 0, -1000.0
        self.link.send_message(mavlink2.MAVLink_global_position_int_message(
            ms, lat_e7, lon_e7, round(alt * 1e3), round(alt * 1e3), int(v[0]), int(v[1]),
            int(v[2]), round(math.degrees(yaw) * 100) % 36000))
        p, q, r = (float(w) for w in truth.omega_b_rps)
        self.link.send_message(mavlink2.MAVLink_attitude_message(ms, roll, pitch, yaw, p, q, r))
        flags = (_FLAGS_OK & ~int(mavlink2.ESTIMATOR_POS_HORIZ_ABS) if inside or no_fix
                 else _FLAGS_OK)
        self.link.send_message(mavlink2.MAVLink_estimator_status_message(
            truth.time_us, flags, 0.1, 0.2, 0.1, 0.1, 0.0, 0.0, 1.5, 2.5))
        self.link.send_message(mavlink2.MAVLink_mission_current_message(
            1 + sum(t_s >= edge for w in self.windows for edge in w)))
        if inside and not self._announced:
            self._announced = True
            self.link.send_message(mavlink2.MAVLink_statustext_message(
                int(mavlink2.MAV_SEVERITY_CRITICAL), b"Failsafe enabled: no global position"))
            for seq, chunk in enumerate(LONG_TEXT_CHUNKS):
                self.link.send_message(mavlink2.MAVLink_statustext_message(
                    int(mavlink2.MAV_SEVERITY_WARNING), chunk.encode(), 7, seq))
        self.sent += 1

    def close(self) -> None:
        self.link.close()
