"""Link roles: our MAVLink ids, heartbeat contents, and which sources and messages we accept."""

from __future__ import annotations

from typing import Final

from pydantic import BaseModel, ConfigDict, Field, field_validator

from hil.codec import (
    AUTOPILOT_COMPONENT_ID,
    SENSOR_COMPONENT_ID,
    SIM_SYSTEM_ID,
    TRUTH_COMPONENT_ID,
    mavlink2,
)

__all__ = [
    "FC_SENSOR_MSG_IDS", "HEARTBEAT_ID", "HIL_MSG_IDS", "LOCKSTEP_CUSTOM_MODE", "TIMESYNC_ID",
    "LinkRole",
]

HEARTBEAT_ID: Final = int(mavlink2.MAVLINK_MSG_ID_HEARTBEAT)
TIMESYNC_ID: Final = int(mavlink2.MAVLINK_MSG_ID_TIMESYNC)
"""Lockstep acknowledgement from the fusion service to the simulator (``ts1`` = simulated time
of the newest processed sample, ns; see :mod:`hil.live_sim`)."""
LOCKSTEP_CUSTOM_MODE: Final = 0x4C4F_434B
"""HEARTBEAT ``custom_mode`` ("LOCK" in ASCII) by which the simulator (``MAV_AUTOPILOT_INVALID``,
so no ground station interprets it) asks the fusion service for lockstep acknowledgements."""

HIL_MSG_IDS: Final = frozenset(
    {
        int(mavlink2.MAVLINK_MSG_ID_HIL_SENSOR),
        int(mavlink2.MAVLINK_MSG_ID_HIL_GPS),
        int(mavlink2.MAVLINK_MSG_ID_HIL_STATE_QUATERNION),
        int(mavlink2.MAVLINK_MSG_ID_HIL_ACTUATOR_CONTROLS),
        int(mavlink2.MAVLINK_MSG_ID_RAW_RPM),
    }
)
"""What the simulator sends (:class:`hil.codec.Encoder`)."""
FC_SENSOR_MSG_IDS: Final = frozenset(
    {
        int(mavlink2.MAVLINK_MSG_ID_HIGHRES_IMU),
        int(mavlink2.MAVLINK_MSG_ID_SCALED_IMU),
        int(mavlink2.MAVLINK_MSG_ID_SCALED_IMU2),
        int(mavlink2.MAVLINK_MSG_ID_SCALED_IMU3),
        int(mavlink2.MAVLINK_MSG_ID_RAW_IMU),
        int(mavlink2.MAVLINK_MSG_ID_GPS_RAW_INT),
        int(mavlink2.MAVLINK_MSG_ID_SCALED_PRESSURE),
        int(mavlink2.MAVLINK_MSG_ID_SCALED_PRESSURE2),
        int(mavlink2.MAVLINK_MSG_ID_SCALED_PRESSURE3),
        int(mavlink2.MAVLINK_MSG_ID_SERVO_OUTPUT_RAW),
        int(mavlink2.MAVLINK_MSG_ID_RAW_RPM),
    }
)
"""Sensor and output messages of a real flight controller that :class:`hil.codec.Decoder`
decodes (SERVO_OUTPUT_RAW, RAW_RPM: the vehicle state of :mod:`hil.codec.vehicle_messages`)."""


class LinkRole(BaseModel):
    """Who we are on a link and whom we listen to.

    Attributes
    ----------
    system_id, component_id : int
        Our MAVLink ids (1..255): heartbeats come from them, frames from them are echoes.
    mav_type, autopilot : int
        HEARTBEAT ``type`` (``MAV_TYPE``) and ``autopilot`` (``MAV_AUTOPILOT``).
    accept_sources : frozenset of (system_id, component_id or None), or None
        Sources whose frames are accepted; ``(sys, None)`` = any component of ``sys``;
        None = any source (but never our own ids).
    accept_msg_ids : frozenset of int, or None
        Message ids accepted besides HEARTBEAT (always accepted); None = any known id.
    lock_to_first_source : bool
        Bind to the system id of the first accepted frame that is not a HEARTBEAT: from then
        on frames of every other system are dropped (``wrong_source``), so a second sender
        can neither feed the receiver nor move a ``udpin`` link's reply address (as PX4 and
        ArduPilot bind HIL input to one link and system).
    heartbeat_period_s : float
        Our heartbeat period and the nominal period of the peer's, s (MAVLink: 1 Hz).
    peer_timeout_heartbeats : int
        A peer is lost after this many heartbeat periods without its heartbeat.
    """

    model_config = ConfigDict(frozen=True, extra="forbid")

    system_id: int = Field(ge=1, le=255)
    component_id: int = Field(ge=1, le=255)
    mav_type: int = Field(ge=0, le=255)
    autopilot: int = Field(ge=0, le=255)
    accept_sources: frozenset[tuple[int, int | None]] | None = None
    accept_msg_ids: frozenset[int] | None = None
    lock_to_first_source: bool = False
    heartbeat_period_s: float = Field(default=1.0, gt=0.0, allow_inf_nan=False)
    peer_timeout_heartbeats: int = Field(default=5, ge=1)

    @field_validator("accept_sources")
    @classmethod
    def _check_sources(
        cls, value: frozenset[tuple[int, int | None]] | None
    ) -> frozenset[tuple[int, int | None]] | None:
        for sys_id, comp_id in value or ():
            if not 1 <= sys_id <= 255 or (comp_id is not None and not 0 <= comp_id <= 255):
                raise ValueError(
                    f"accept_sources entry {(sys_id, comp_id)}: system id must be in "
                    "[1, 255] and component id in [0, 255] or None"
                )
        return value

    @field_validator("accept_msg_ids")
    @classmethod
    def _check_msg_ids(cls, value: frozenset[int] | None) -> frozenset[int] | None:
        unknown = sorted(i for i in value or () if i not in mavlink2.mavlink_map)
        if unknown:
            raise ValueError(f"accept_msg_ids {unknown} are not in hilnav's dialect")
        return value

    @property
    def peer_timeout_s(self) -> float:
        """Silence after which a peer is lost, s."""
        return self.peer_timeout_heartbeats * self.heartbeat_period_s

    def accepts_source(self, system_id: int, component_id: int) -> bool:
        """Whether frames from (system_id, component_id) are accepted."""
        if (system_id, component_id) == (self.system_id, self.component_id):
            return False
        allowed = self.accept_sources
        return (
            allowed is None or (system_id, component_id) in allowed or (system_id, None) in allowed
        )

    def accepts_msg_id(self, msg_id: int) -> bool:
        """Whether a message id is accepted from an accepted source."""
        allowed = self.accept_msg_ids
        return msg_id == HEARTBEAT_ID or allowed is None or msg_id in allowed

    # -- the roles of hilnav's processes --
    @classmethod
    def simulator(cls, *, system_id: int = SIM_SYSTEM_ID) -> LinkRole:
        """The simulator: a sensor component (200) of the simulated vehicle, neither a vehicle
        nor an autopilot (``MAV_TYPE_GENERIC``, ``MAV_AUTOPILOT_INVALID``); listens only to
        heartbeats and lockstep acknowledgements (TIMESYNC), from anyone."""
        return cls(
            system_id=system_id,
            component_id=SENSOR_COMPONENT_ID,
            mav_type=mavlink2.MAV_TYPE_GENERIC,
            autopilot=mavlink2.MAV_AUTOPILOT_INVALID,
            accept_msg_ids=frozenset({TIMESYNC_ID}),
        )

    @classmethod
    def fusion(
        cls,
        *,
        system_id: int = 1,
        component_id: int = int(mavlink2.MAV_COMP_ID_ONBOARD_COMPUTER),
        sim_system_id: int = SIM_SYSTEM_ID,
        sim_components: tuple[int, ...] = (
            SENSOR_COMPONENT_ID, TRUTH_COMPONENT_ID, AUTOPILOT_COMPONENT_ID,
        ),
    ) -> LinkRole:
        """The fusion service's input from the simulator: an onboard computer (191,
        ``MAV_TYPE_ONBOARD_CONTROLLER``) accepting HIL_SENSOR / HIL_GPS /
        HIL_STATE_QUATERNION / HIL_ACTUATOR_CONTROLS / RAW_RPM from the simulator's sensor,
        truth and autopilot components."""
        return cls(
            system_id=system_id,
            component_id=component_id,
            mav_type=mavlink2.MAV_TYPE_ONBOARD_CONTROLLER,
            autopilot=mavlink2.MAV_AUTOPILOT_INVALID,
            accept_sources=frozenset((sim_system_id, c) for c in sim_components),
            accept_msg_ids=HIL_MSG_IDS,
        )

    @classmethod
    def shadow_vehicle(cls, *, system_id: int, gcs_system_id: int | None = None) -> LinkRole:
        """The estimate shown to ground stations as a vehicle: autopilot component 1,
        ``MAV_TYPE_FIXED_WING``, ``MAV_AUTOPILOT_GENERIC``; listens to heartbeats of the
        ground station (``gcs_system_id``, any component; None = anyone)."""
        return cls(
            system_id=system_id,
            component_id=int(mavlink2.MAV_COMP_ID_AUTOPILOT1),
            mav_type=mavlink2.MAV_TYPE_FIXED_WING,
            autopilot=mavlink2.MAV_AUTOPILOT_GENERIC,
            accept_sources=None if gcs_system_id is None else frozenset({(gcs_system_id, None)}),
            accept_msg_ids=frozenset(),
        )

    @classmethod
    def companion(
        cls,
        *,
        system_id: int = 1,
        component_id: int = int(mavlink2.MAV_COMP_ID_VISUAL_INERTIAL_ODOMETRY),
        autopilot_component_id: int = int(mavlink2.MAV_COMP_ID_AUTOPILOT1),
    ) -> LinkRole:
        """The companion towards a flight controller (component 197,
        ``MAV_TYPE_ONBOARD_CONTROLLER``): accepts the autopilot's sensor messages."""
        return cls(
            system_id=system_id,
            component_id=component_id,
            mav_type=mavlink2.MAV_TYPE_ONBOARD_CONTROLLER,
            autopilot=mavlink2.MAV_AUTOPILOT_INVALID,
            accept_sources=frozenset({(system_id, autopilot_component_id)}),
            accept_msg_ids=FC_SENSOR_MSG_IDS,
        )
