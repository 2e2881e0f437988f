"""Benchmark: what authenticated samples cost, and what they stop, on a real router (loopback).

    python bench/zenoh_security.py          # writes bench/results/zenoh_security.json

1. CPU cost of the HMAC tag and its check per ``fusion/estimate`` payload (process time).
2. A real in-process router with usrpwd + access control; the fusion (role ``fusion``) publishes
   ``--messages`` tagged estimates while an attacker with a valid *read-only* login publishes as
   many forged ones, and a second attacker on an open router (no ACL) does the same against a
   consumer holding the key. Counted: real estimates delivered, forged ones delivered,
   forged ones rejected (by the router's ACL or by the consumer's tag check).
"""

from __future__ import annotations

import argparse
import importlib.metadata
import json
import os
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np
import zenoh

from fusion.estimate import Health, Mode, NavEstimate, TestRatios
from hil.bus import (
    PUBLISHED_TOPICS,
    Bus,
    BusConfig,
    ClientSecurity,
    Message,
    PayloadAuth,
    RouterSecurity,
    Topic,
    encode,
    estimate_payload,
    key,
)
from hil.router import ZenohRouter

KEY = os.urandom(32)
UNLIMITED = BusConfig(rates_hz=dict.fromkeys(PUBLISHED_TOPICS), queue_size=100_000)


def _estimate(i: int) -> dict[str, Any]:
    est = NavEstimate(
        time_us=1_000_000 + i * 10_000, lat_rad=0.82, lon_rad=0.14, alt_msl_m=1000.0,
        v_ned_mps=np.array([50.0, 1.0, -0.5]), q_nb=np.array([1.0, 0.0, 0.0, 0.0]),
        euler_rad=np.zeros(3), P_diag=np.full(16, 0.25), mode=Mode.GNSS,
        accel_bias_b_mps2=np.zeros(3), gyro_bias_b_rps=np.zeros(3), baro_bias_m=0.0,
        health=Health(), test_ratios=TestRatios(), time_since_gnss_s=0.0, state_layout="ins16")
    return estimate_payload(est)


def cpu_cost(n: int) -> dict[str, float]:
    auth = PayloadAuth(KEY)
    data = encode(_estimate(0))
    k = key("b", Topic.ESTIMATE)
    t0 = time.process_time()
    tags = [auth.tag(k, data) for _ in range(n)]
    tag_us = (time.process_time() - t0) / n * 1e6
    check = PayloadAuth(KEY)
    t0 = time.process_time()
    ok = sum(check.verify(k, data, t).value == "ok" for t in tags)
    verify_us = (time.process_time() - t0) / n * 1e6
    assert ok == n
    return {"payload_bytes": len(data), "tag_us": tag_us, "verify_us": verify_us}


def _login(user: str, password: str) -> ClientSecurity:
    return ClientSecurity.from_options(user=user, environ={"HILNAV_ZENOH_PASSWORD": password})


def attack(endpoint: str, *, fusion: ClientSecurity, viewer: ClientSecurity,
           attacker: ClientSecurity, n: int, auth_key: bytes | None) -> dict[str, Any]:
    real = forged = 0
    lock = threading.Lock()

    def on(msg: Message) -> None:
        nonlocal real, forged
        with lock:
            if msg.payload and msg.payload.get("source") == "forged":
                forged += 1
            else:
                real += 1

    cfg: dict[str, Any] = {"mode": "client", "connect": {"endpoints": [endpoint]},
                           "scouting": {"multicast": {"enabled": False}},
                           "transport": attacker.transport()}
    with Bus(endpoint, vehicle="b", config=UNLIMITED, security=viewer, auth_key=auth_key) as sub, \
            Bus(endpoint, vehicle="b", config=UNLIMITED, security=fusion,
                auth_key=auth_key) as pub:
        sub.subscribe(Topic.ESTIMATE, on)
        deadline = time.monotonic() + 10.0
        while not pub.has_subscribers(Topic.ESTIMATE) and time.monotonic() < deadline:
            time.sleep(0.02)
        mallory = zenoh.open(zenoh.Config.from_json5(json.dumps(cfg)))
        forged_bytes = encode({**_estimate(0), "source": "forged"})
        k = key("b", Topic.ESTIMATE)
        t0 = time.monotonic()

        def flood() -> None:
            for _ in range(n):
                mallory.put(k, forged_bytes)

        th = threading.Thread(target=flood)
        th.start()
        for i in range(n):
            pub.publish(Topic.ESTIMATE, _estimate(i))
        th.join()
        deadline = time.monotonic() + 20.0
        while real < n and time.monotonic() < deadline:
            time.sleep(0.05)
        wall_s = time.monotonic() - t0
        time.sleep(0.5)
        mallory.close()
        stats = sub.stats()
    return {"real_sent": n, "real_delivered": real, "forged_sent": n, "forged_delivered": forged,
            "rejected_by_tag": stats.unauthenticated, "wall_s": wall_s}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--messages", type=int, default=5000)
    ap.add_argument("--cpu-samples", type=int, default=50_000)
    ap.add_argument("--out", type=Path, default=Path("bench/results/zenoh_security.json"))
    args = ap.parse_args()
    result: dict[str, Any] = {"benchmark": "zenoh_security",
                              "load_average_1m": os.getloadavg()[0],
                              "eclipse_zenoh": importlib.metadata.version("eclipse-zenoh"),
                              "cpu": cpu_cost(args.cpu_samples)}
    with tempfile.TemporaryDirectory() as tmp:
        users = Path(tmp) / "users.txt"
        users.write_text("fusion:f\nviewer:v\nmallory:m\n")
        logins = {"fusion": _login("fusion", "f"), "viewer": _login("viewer", "v"),
                  "attacker": _login("mallory", "m")}
        with ZenohRouter(security=RouterSecurity(users_file=users, acl=True)) as router:
            result["acl_router_no_key"] = attack(router.endpoint, **logins, n=args.messages,
                                                 auth_key=None)
        with ZenohRouter(security=RouterSecurity(users_file=users)) as router:
            result["open_router_no_key"] = attack(router.endpoint, **logins, n=args.messages,
                                                  auth_key=None)
            result["open_router_with_key"] = attack(router.endpoint, **logins,
                                                    n=args.messages, auth_key=KEY)
    result["load_average_1m_end"] = os.getloadavg()[0]
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=2) + "\n")
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
