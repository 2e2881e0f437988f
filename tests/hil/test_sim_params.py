"""SIM_* parameter changes over a real loopback MAVLink TCP link (hil.autopilot.sim_params)."""

from __future__ import annotations

import time

import pytest

from hil.autopilot.sim_params import SimParamSender
from hil.codec import mavlink2
from hil.link import LinkRole, MavlinkLink
from sim.faults.ardupilot import ParamSet


def _autopilot() -> MavlinkLink:
    return MavlinkLink("tcpin:127.0.0.1:0", LinkRole(
        system_id=1, component_id=1, mav_type=int(mavlink2.MAV_TYPE_FIXED_WING),
        autopilot=int(mavlink2.MAV_AUTOPILOT_ARDUPILOTMEGA),
        accept_msg_ids=frozenset({int(mavlink2.MAVLINK_MSG_ID_PARAM_SET)})))


def test_changes_go_out_on_simulated_time_in_order_and_acks_are_checked() -> None:
    schedule = [ParamSet(0.0, "SIM_GPS1_ENABLE", 1.0), ParamSet(2.0, "SIM_GPS1_ENABLE", 0.0),
                ParamSet(2.0, "SIM_GPS1_GLTCH_X", 0.0045),
                # the same parameter twice before any answer: each answer matches its own set
                ParamSet(3.0, "SIM_GPS1_JAM", 1.0), ParamSet(3.0, "SIM_GPS1_JAM", 0.0),
                ParamSet(9.0, "SIM_GPS1_HZ", 1.0)]
    with _autopilot() as autopilot:
        sender = SimParamSender(f"tcp:127.0.0.1:{autopilot.local_address[1]}", schedule)
        received: list[tuple[str, float]] = []
        try:
            deadline = time.monotonic() + 10.0
            t_s = 0.0
            while sender.sent < 5 and time.monotonic() < deadline:
                sender.advance(t_s)  # the first calls may find the link still connecting
                t_s = min(t_s + 0.5, 5.0)  # simulated time stops at 5 s: 9 s never comes
                for msg in autopilot.recv(0.05):
                    if msg.get_type() != "PARAM_SET":
                        continue
                    name = msg.param_id.rstrip("\x00")
                    received.append((name, msg.param_value))
                    # answer as ArduPilot does; the glitch comes back changed (rejected)
                    value = 0.0 if name == "SIM_GPS1_GLTCH_X" else msg.param_value
                    autopilot.send_message(mavlink2.MAVLink_param_value_message(
                        name.encode(), value, int(mavlink2.MAV_PARAM_TYPE_REAL32), 3, 0))
            while sender.acked + sender.rejected < 5 and time.monotonic() < deadline:
                sender.poll(0.05)
        finally:
            sender.close()
    assert [n for n, _ in received] == ["SIM_GPS1_ENABLE", "SIM_GPS1_ENABLE", "SIM_GPS1_GLTCH_X",
                                        "SIM_GPS1_JAM", "SIM_GPS1_JAM"]
    assert received[2][1] == pytest.approx(0.0045, rel=1e-6)  # float32 on the wire
    assert sender.remaining == 1  # SIM_GPS1_HZ at 9 s: not due
    assert (sender.sent, sender.acked, sender.rejected) == (5, 4, 1)
    assert sender.send_failed <= 1  # a change waiting for the connection counts once
