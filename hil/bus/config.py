"""Rates, queue size and connect timing of a :class:`hil.bus.Bus`."""

from __future__ import annotations

import math
from typing import Final

import pydantic

from hil.bus.keys import Topic

__all__ = ["BusConfig"]

_DEFAULT_RATES: Final[dict[Topic, float | None]] = {
    Topic.TRUTH: 25.0,
    Topic.IMU: 25.0,
    Topic.GNSS: None,
    Topic.BARO: 25.0,
    Topic.MAG: 25.0,
    Topic.AIRSPEED: 25.0,
    Topic.ESTIMATE: 25.0,
    Topic.STATUS: 2.0,
    Topic.INNOVATIONS: None,
    Topic.ERROR: 25.0,
    Topic.EVENTS: None,
    Topic.FUSION_EVENTS: None,
}


class BusConfig(pydantic.BaseModel):
    """Rates and limits of a :class:`Bus`.

    Attributes
    ----------
    rates_hz : mapping of topic -> max rate (Hz) or None (every message)
        Decimation per topic, on simulated time (``time_us`` of the payload) so a recording of
        a faster-than-real-time run is evenly sampled; payloads without ``time_us`` are
        decimated on the wall clock. Topics not listed keep their default
        (truth, IMU, baro, mag, airspeed, estimate, error 25 Hz; status 2 Hz; GNSS, innovations,
        both event topics unlimited).
    queue_size : int
        Messages waiting for the publisher thread; beyond it the oldest is dropped.
    connect_timeout_s : float
        One attempt to open the session (a client waits this long for the router), s.
    retry_s : float
        Pause between session-open attempts while no router answers, s.
    low_latency : bool
        Ask for Zenoh's low-latency unicast transport (``transport/unicast/lowlatency``, which
        needs QoS priorities off): no transmit batching queue, each sample written to the link
        by the thread that puts it. A link runs it only when *both* ends ask for it (a direct
        peer, or a router and its client); otherwise the two ends settle on the default
        transport, silently. Off by default.
    """

    model_config = pydantic.ConfigDict(frozen=True, extra="forbid")

    rates_hz: dict[Topic, float | None] = pydantic.Field(default_factory=dict)
    queue_size: int = pydantic.Field(default=4096, ge=1, le=10_000_000)
    connect_timeout_s: float = pydantic.Field(default=1.0, gt=0.0, le=60.0)
    retry_s: float = pydantic.Field(default=0.5, ge=0.0, le=60.0)
    low_latency: bool = False

    @pydantic.field_validator("rates_hz")
    @classmethod
    def _check_rates(cls, v: dict[Topic, float | None]) -> dict[Topic, float | None]:
        for topic, rate in v.items():
            if topic in (Topic.CONFIG, Topic.ALIVE):
                raise ValueError(f"{topic.value} is not a published topic")
            if rate is not None and not (math.isfinite(rate) and rate > 0.0):
                raise ValueError(f"rate of {topic.value} must be > 0 Hz or null, got {rate}")
        return v

    def rate_hz(self, topic: Topic) -> float | None:
        """Effective maximum rate of ``topic`` (None = unlimited)."""
        return self.rates_hz.get(topic, _DEFAULT_RATES.get(topic))
