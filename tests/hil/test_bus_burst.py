"""A burst through the bus loses nothing; the low-latency transport is asked for.

GIVEN a bus whose ``publish`` queues samples for its publisher thread (Zenoh ``DROP``),
WHEN 2,000 estimates are published back to back to a direct peer whose callback is slow
(0.1 ms per sample),
THEN every sample arrives exactly once and in publication order, and no counter shows a drop;
and ``BusConfig(low_latency=True)`` gives Zenoh the two keys of its low-latency transport,
which falls back to the default transport when the other end did not ask.
"""

from __future__ import annotations

import time
from typing import Any

import pytest

from hil.bus import Bus, BusConfig, Message, Topic
from hil.bus.keys import PUBLISHED_TOPICS
from hil.router import free_tcp_port


def _wait(predicate: Any, timeout_s: float) -> bool:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(0.01)
    return bool(predicate())


def _peers(low_latency: bool) -> tuple[str, BusConfig, BusConfig]:
    listen = f"tcp/127.0.0.1:{free_tcp_port()}"
    pub_cfg = BusConfig(rates_hz=dict.fromkeys(PUBLISHED_TOPICS), low_latency=low_latency)
    return listen, pub_cfg, BusConfig(low_latency=low_latency)


def test_a_burst_to_a_slow_direct_peer_arrives_whole_and_in_order() -> None:
    listen, pub_cfg, sub_cfg = _peers(low_latency=False)
    got: list[int] = []

    def on_estimate(m: Message) -> None:
        time.sleep(0.0001)
        if m.payload is not None:
            got.append(int(m.payload["time_us"]))

    with Bus(None, vehicle="burst", mode="peer", listen=listen, config=pub_cfg) as pub, \
            Bus(listen, vehicle="burst", mode="peer", config=sub_cfg) as sub:
        sub.subscribe(Topic.ESTIMATE, on_estimate)
        assert sub.wait_connected(10.0)
        assert _wait(lambda: pub.has_subscribers(Topic.ESTIMATE), 10.0)
        n = 2000
        for t in range(n):
            pub.publish(Topic.ESTIMATE, {"time_us": t})
        assert _wait(lambda: len(got) >= n, 20.0), f"{len(got)} of {n} arrived"
        time.sleep(0.1)  # a duplicate would show up now
        st = pub.stats()
    assert got == list(range(n))
    assert (st.enqueued, st.published) == (n, n)
    assert (st.dropped_queue_full, st.put_errors, st.queued) == (0, 0, 0)


def test_low_latency_asks_zenoh_for_its_low_latency_transport_with_qos_off() -> None:
    def transport(bus: Bus) -> tuple[str, str]:
        cfg = bus._zenoh_config()
        return (cfg.get_json("transport/unicast/lowlatency"),
                cfg.get_json("transport/unicast/qos/enabled"))

    assert transport(Bus(None, mode="peer", config=BusConfig(low_latency=True))) == (
        "true", "false")
    assert transport(Bus(None, mode="peer")) == ("false", "true")  # Zenoh's defaults


@pytest.mark.parametrize(("pub_ll", "sub_ll"), [(True, False), (False, True)])
def test_a_low_latency_peer_still_talks_to_one_that_did_not_ask(pub_ll: bool,
                                                                 sub_ll: bool) -> None:
    """Both ends must ask; when one does not, the link falls back to Zenoh's default transport
    (so a fusion with ``--zenoh-low-latency`` serves every subscriber)."""
    listen, pub_cfg, _ = _peers(low_latency=pub_ll)
    got: list[int] = []
    with Bus(None, vehicle="mixed", mode="peer", listen=listen, config=pub_cfg) as pub, \
            Bus(listen, vehicle="mixed", mode="peer",
                config=BusConfig(low_latency=sub_ll)) as sub:
        sub.subscribe(Topic.ESTIMATE, lambda m: got.append(int(m.payload["time_us"]))
                      if m.payload else None)
        assert sub.wait_connected(10.0)
        assert _wait(lambda: pub.has_subscribers(Topic.ESTIMATE), 10.0)
        pub.publish(Topic.ESTIMATE, {"time_us": 7})
        assert _wait(lambda: got == [7], 10.0), got
