"""Zenoh security with real sessions on loopback: each option must take effect, not only parse.

A client with the wrong password, no certificate or a certificate from another CA is refused; a
client outside the access-control role cannot publish estimates, declare the ``alive`` token or
answer ``fusion/config``; with the shared payload key a forged, foreign-key or replayed sample is
dropped and a fake ``alive`` token is reported. The attacker is always a real second Zenoh
session. Certificates are made in the test (``tests/helpers/certs.py``).
"""

from __future__ import annotations

import json
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pydantic
import pytest
import zenoh

from hil.bus import Bus, BusConfig, Message, Topic, check_bus, estimate_payload, key
from hil.bus.config import _DEFAULT_RATES
from hil.bus.security import PASSWORD_ENV, ClientSecurity, RouterSecurity, is_loopback_endpoint
from hil.router import ZenohRouter, free_tcp_port, router_main
from tests.helpers.certs import Pki, make_pki

from .test_bus import real_estimate, wait_for

UNLIMITED = BusConfig(rates_hz=dict.fromkeys(_DEFAULT_RATES), connect_timeout_s=1.0)
SHORT = BusConfig(connect_timeout_s=0.5, retry_s=0.1)
KEY = bytes(range(32))


@pytest.fixture(scope="module")
def pki(tmp_path_factory: pytest.TempPathFactory) -> Pki:
    return make_pki(tmp_path_factory.mktemp("pki"), ("fusion", "sim", "viewer", "mallory"))


@pytest.fixture(scope="module")
def rogue_pki(tmp_path_factory: pytest.TempPathFactory) -> Pki:
    """Another CA: its certificates carry the right names but the wrong signature."""
    return make_pki(tmp_path_factory.mktemp("rogue"), ("fusion",), ca_name="rogue CA")


@pytest.fixture(scope="module")
def users(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("users") / "users.txt"
    path.write_text("fusion:fusion-pw\nsim:sim-pw\nviewer:viewer-pw\nmallory:mallory-pw\n")
    return path


def login(user: str, password: str, **tls: Any) -> ClientSecurity:
    return ClientSecurity(user=user, password=pydantic.SecretStr(password), **tls)


def raw_client(endpoint: str, security: ClientSecurity | None = None) -> zenoh.Session:
    """The attacker's own Zenoh session (no hilnav code on its side)."""
    cfg: dict[str, Any] = {"mode": "client",
                           "connect": {"endpoints": [endpoint], "timeout_ms": 2000},
                           "scouting": {"multicast": {"enabled": False}}}
    if security is not None:
        cfg["transport"] = security.transport()
    return zenoh.open(zenoh.Config.from_json5(json.dumps(cfg)))


class Inbox:
    """Payloads received by a subscription, by their ``source`` field."""

    def __init__(self) -> None:
        self.messages: list[Message] = []
        self._lock = threading.Lock()

    def __call__(self, msg: Message) -> None:
        with self._lock:
            self.messages.append(msg)

    def raws(self) -> list[bytes]:
        with self._lock:
            return [m.raw for m in self.messages]


def _estimate_bytes(tag: str) -> bytes:
    payload = estimate_payload(real_estimate())
    payload["mode"] = tag
    return json.dumps(payload).encode()


# ------------------------------------------------------------------ authentication (usrpwd)
@pytest.fixture(scope="module")
def pwd_router(users: Path) -> Iterator[str]:
    with ZenohRouter(security=RouterSecurity(users_file=users)) as r:
        yield r.endpoint


def test_usrpwd_refuses_a_wrong_password_and_an_anonymous_client(pwd_router: str) -> None:
    with Bus(pwd_router, vehicle="pw", config=SHORT,
             security=login("viewer", "not-the-password")) as wrong:
        assert not wrong.wait_connected(2.0)
        assert wrong.session is None and wrong.stats().connect_attempts >= 1
    with Bus(pwd_router, vehicle="pw", config=SHORT) as anonymous:
        assert not anonymous.wait_connected(2.0)
    with Bus(pwd_router, vehicle="pw", config=SHORT, security=login("viewer", "viewer-pw")) as ok:
        assert ok.wait_connected(5.0)


def test_the_password_comes_from_a_file_or_the_environment(tmp_path: Path) -> None:
    secret = tmp_path / "pw"
    secret.write_text("s3cret\n")
    from_file = ClientSecurity.from_options(user="fusion", password_file=secret, environ={})
    assert from_file.password is not None and from_file.password.get_secret_value() == "s3cret"
    from_env = ClientSecurity.from_options(user="fusion", environ={PASSWORD_ENV: "e"})
    assert from_env.transport()["auth"]["usrpwd"] == {"user": "fusion", "password": "e"}
    assert "s3cret" not in repr(from_file)  # never printed with the options
    with pytest.raises(pydantic.ValidationError, match="password"):
        ClientSecurity.from_options(user="fusion", environ={})
    with pytest.raises(ValueError, match="needs --zenoh-user"):
        ClientSecurity.from_options(password_file=secret, environ={})


# ------------------------------------------------------------------------------- TLS / mTLS
def test_tls_needs_the_routers_ca(pki: Pki, rogue_pki: Pki) -> None:
    sec = RouterSecurity(tls_cert=pki.server_cert, tls_key=pki.server_key)
    with ZenohRouter(security=sec) as router:
        assert router.endpoint.startswith("tls/")
        with Bus(router.endpoint, vehicle="t", config=SHORT,
                 security=ClientSecurity(tls_ca=rogue_pki.ca)) as wrong_ca:
            assert not wrong_ca.wait_connected(2.0)
        with Bus(router.endpoint, vehicle="t", security=ClientSecurity(tls_ca=pki.ca)) as ok:
            assert ok.wait_connected(5.0)
    with pytest.raises(ValueError, match="tls/ endpoints"):
        Bus("tcp/127.0.0.1:7447", security=ClientSecurity(tls_ca=pki.ca))


def test_mtls_refuses_a_client_without_a_certificate_or_with_a_foreign_one(
    pki: Pki, rogue_pki: Pki
) -> None:
    sec = RouterSecurity(tls_cert=pki.server_cert, tls_key=pki.server_key, tls_ca=pki.ca,
                         mtls=True)
    with ZenohRouter(security=sec) as router:
        ep = router.endpoint
        with Bus(ep, vehicle="m", config=SHORT, security=ClientSecurity(tls_ca=pki.ca)) as bare:
            assert not bare.wait_connected(2.0)
        cert, k = rogue_pki.client("fusion")
        foreign = ClientSecurity(tls_ca=pki.ca, tls_cert=cert, tls_key=k)
        with Bus(ep, vehicle="m", config=SHORT, security=foreign) as rogue:
            assert not rogue.wait_connected(2.0)
        cert, k = pki.client("fusion")
        good = ClientSecurity(tls_ca=pki.ca, tls_cert=cert, tls_key=k)
        with Bus(ep, vehicle="m", security=good) as ok:
            assert ok.wait_connected(5.0)


# --------------------------------------------------------------------------- access control
def _forgery_refused(endpoint: str, fusion: ClientSecurity, viewer: ClientSecurity,
                     attacker: ClientSecurity, sim: ClientSecurity) -> None:
    """The fusion's estimate reaches the viewer; the attacker's does not (nor its token, its
    config answer, or the sim's attempt to publish on fusion/**)."""
    inbox = Inbox()
    est_key = key("acl", Topic.ESTIMATE)
    with Bus(endpoint, vehicle="acl", config=UNLIMITED, security=viewer) as sub, \
            Bus(endpoint, vehicle="acl", config=UNLIMITED, security=fusion) as pub:
        sub.subscribe(Topic.ESTIMATE, inbox)
        assert sub.wait_connected(5.0) and pub.wait_connected(5.0)
        assert wait_for(lambda: pub.has_subscribers(Topic.ESTIMATE))
        mallory = raw_client(endpoint, attacker)
        sim_session = raw_client(endpoint, sim)
        try:
            # kept in variables: a dropped handle would undeclare itself
            token = mallory.liveliness().declare_token(key("acl", Topic.ALIVE))
            answer = mallory.declare_queryable(
                key("acl", Topic.CONFIG), lambda q: q.reply(q.key_expr, b'{"forged": true}'))
            mallory.put(est_key, _estimate_bytes("forged-by-mallory"))
            sim_session.put(est_key, _estimate_bytes("forged-by-sim"))
            # the real one after the forgeries: once it is in, the forgeries had their chance
            pub.publish(Topic.ESTIMATE, json.loads(_estimate_bytes("real")))
            assert wait_for(lambda: any(b"real" in r for r in inbox.raws()))
            assert not any(b"forged" in r for r in inbox.raws())
            assert not sub.fusion_alive(timeout_s=1.0), "the attacker's token got through"
            assert sub.query_config(timeout_s=1.0) is None, "the attacker answered fusion/config"
            # the real fusion can do both
            pub.declare_liveliness()
            pub.declare_config_queryable(lambda: {"tuning": 1})
            assert wait_for(lambda: sub.fusion_alive(timeout_s=1.0))
            reply = sub.query_config(timeout_s=2.0)
            assert reply is not None and "forged" not in json.dumps(reply)
            del token, answer
        finally:
            mallory.close()
            sim_session.close()


def test_acl_lets_only_the_fusion_role_publish_estimates_usrpwd(users: Path) -> None:
    sec = RouterSecurity(users_file=users, acl=True)
    with ZenohRouter(security=sec) as router:
        _forgery_refused(router.endpoint, fusion=login("fusion", "fusion-pw"),
                         viewer=login("viewer", "viewer-pw"),
                         attacker=login("mallory", "mallory-pw"), sim=login("sim", "sim-pw"))


def test_acl_by_certificate_common_name_under_mtls(pki: Pki) -> None:
    sec = RouterSecurity(tls_cert=pki.server_cert, tls_key=pki.server_key, tls_ca=pki.ca,
                         mtls=True, acl=True)

    def who(name: str) -> ClientSecurity:
        cert, k = pki.client(name)
        return ClientSecurity(tls_ca=pki.ca, tls_cert=cert, tls_key=k)

    with ZenohRouter(security=sec) as router:
        _forgery_refused(router.endpoint, fusion=who("fusion"), viewer=who("viewer"),
                         attacker=who("mallory"), sim=who("sim"))


def test_acl_lets_the_sim_publish_sensors(users: Path) -> None:
    with ZenohRouter(security=RouterSecurity(users_file=users, acl=True)) as router:
        inbox = Inbox()
        with Bus(router.endpoint, vehicle="s", config=UNLIMITED,
                 security=login("viewer", "viewer-pw")) as sub, \
                Bus(router.endpoint, vehicle="s", config=UNLIMITED,
                    security=login("sim", "sim-pw")) as sim:
            sub.subscribe_key("hilnav/s/**", inbox)
            assert wait_for(lambda: sim.has_subscribers(Topic.EVENTS))
            sim.publish_event(1_000_000, "gnss_off", "sim event")
            assert wait_for(lambda: any(b"gnss_off" in r for r in inbox.raws()))


def test_the_admin_space_is_closed(users: Path) -> None:
    for sec in (RouterSecurity(), RouterSecurity(users_file=users, acl=True)):
        with ZenohRouter(security=sec) as router:
            client = raw_client(router.endpoint, login("viewer", "viewer-pw")
                                if sec.users_file else None)
            try:
                zids = {str(z) for z in client.info.routers_zid()}
                assert zids
                keys = [str(r.ok.key_expr) for r in client.get("@/**", timeout=1.0)
                        if r.ok is not None]
                # the client's own session space names the router too: look for the router's
                assert not [k for k in keys if any(k.startswith(f"@/{z}/") for z in zids)], keys
            finally:
                client.close()


# ---------------------------------------------------------------------- router lock-down
def test_router_refuses_to_listen_beyond_loopback_without_authentication(users: Path) -> None:
    with pytest.raises(ValueError, match="beyond loopback"):
        ZenohRouter(host="0.0.0.0")
    with pytest.raises(ValueError, match="beyond loopback"):
        router_main(listen=f"tcp/0.0.0.0:{free_tcp_port()}", duration_s=0.1)
    # accepted (not opened here) with authentication, or when the user says so
    assert ZenohRouter(host="0.0.0.0", security=RouterSecurity(users_file=users)).endpoint
    assert ZenohRouter(host="0.0.0.0", security=RouterSecurity(insecure=True)).endpoint
    assert is_loopback_endpoint("tcp/127.0.0.1:7447") and is_loopback_endpoint("tcp/[::1]:1")
    assert not is_loopback_endpoint("tcp/zenohd:7447")


def test_router_security_rejects_inconsistent_options(pki: Pki, users: Path) -> None:
    with pytest.raises(pydantic.ValidationError, match="--acl needs"):
        RouterSecurity(acl=True)
    with pytest.raises(pydantic.ValidationError, match="--mtls needs"):
        RouterSecurity(mtls=True, tls_cert=pki.server_cert, tls_key=pki.server_key)
    with pytest.raises(pydantic.ValidationError, match="not a readable file"):
        RouterSecurity(users_file=users.parent / "missing.txt")
    with pytest.raises(ValueError, match="needs --tls-cert"):
        RouterSecurity().check_listen(["tls/127.0.0.1:7447"])


# ----------------------------------------------------------------- authenticated payloads
def test_forged_foreign_key_and_replayed_estimates_are_dropped(router: str) -> None:
    inbox = Inbox()
    captured: list[tuple[bytes, bytes]] = []
    est_key = key("hm", Topic.ESTIMATE)
    with Bus(router, vehicle="hm", config=UNLIMITED, auth_key=KEY) as sub, \
            Bus(router, vehicle="hm", config=UNLIMITED, auth_key=KEY) as pub, \
            Bus(router, vehicle="hm", config=UNLIMITED, auth_key=bytes(32)) as wrong_key:
        sub.subscribe(Topic.ESTIMATE, inbox)
        spy = raw_client(router)
        try:
            def keep(s: zenoh.Sample) -> None:
                if s.attachment is not None:
                    captured.append((s.payload.to_bytes(), s.attachment.to_bytes()))

            spy.declare_subscriber(est_key, keep)
            assert wait_for(lambda: pub.has_subscribers(Topic.ESTIMATE))
            pub.publish(Topic.ESTIMATE, json.loads(_estimate_bytes("real-1")))
            assert wait_for(lambda: len(captured) == 1 and len(inbox.messages) == 1)
            # attacker 1: no tag; attacker 2: a tag made with another key; attacker 3: replay
            spy.put(est_key, _estimate_bytes("forged-untagged"))
            wrong_key.publish(Topic.ESTIMATE, json.loads(_estimate_bytes("forged-wrong-key")))
            payload, tag = captured[0]
            spy.put(est_key, payload, attachment=tag)
            # a tag is bound to its payload: the real tag on a forged payload fails too
            spy.put(est_key, _estimate_bytes("forged-retagged"), attachment=tag)
            pub.publish(Topic.ESTIMATE, json.loads(_estimate_bytes("real-2")))
            assert wait_for(lambda: any(b"real-2" in r for r in inbox.raws()))
            assert wait_for(lambda: sub.stats().unauthenticated == 3
                            and sub.stats().replayed == 1)
            assert [json.loads(r)["mode"] for r in inbox.raws()] == ["real-1", "real-2"]
            # a consumer without the key still gets everything (the key is opt-in per process)
        finally:
            spy.close()


def test_check_alive_flags_a_fake_token_only_with_the_key(router: str) -> None:
    def check(auth_key: bytes | None) -> tuple[int, list[str]]:
        lines: list[str] = []
        code = check_bus(router, "lt", alive=True, timeout_s=3.0, report=lines.append,
                         auth_key=auth_key)
        return code, lines

    with Bus(router, vehicle="lt", auth_key=KEY) as fusion:
        fusion.declare_liveliness()
        fusion.declare_config_queryable(lambda: {"tuning": 1})
        assert wait_for(lambda: check(KEY)[0] == 0)
    # the fusion is gone; the attacker declares its token and answers fusion/config
    mallory = raw_client(router)
    try:
        token = mallory.liveliness().declare_token(key("lt", Topic.ALIVE))
        answer = mallory.declare_queryable(
            key("lt", Topic.CONFIG), lambda q: q.reply(q.key_expr, b'{"schema_version": 1}'))
        assert wait_for(lambda: check(None)[0] == 0)  # without the key: fooled
        code, lines = check(KEY)
        assert code == 1 and "forged token?" in lines[0]
        del token, answer
    finally:
        mallory.close()


def test_monitor_flags_a_fake_token_and_forged_estimates(
    router: str, capsys: pytest.CaptureFixture[str]
) -> None:
    from hil.bus import BusAccess
    from hil.monitor import monitor_main

    access = BusAccess(auth_key=KEY)
    mallory = raw_client(router)
    stop = threading.Event()

    def forge() -> None:
        while not stop.is_set():
            mallory.put(key("mv", Topic.ESTIMATE), _estimate_bytes("forged"))
            stop.wait(0.05)

    token = mallory.liveliness().declare_token(key("mv", Topic.ALIVE))
    thread = threading.Thread(target=forge)
    thread.start()
    try:
        assert monitor_main(connect=router, vehicle="mv", record=None, duration_s=3.5,
                            headless=True, bus_access=access) == 0
    finally:
        stop.set()
        thread.join()
        del token
        mallory.close()
    line = [ln for ln in capsys.readouterr().out.splitlines() if " mv " in ln][-1]
    assert "alive=yes UNVERIFIED" in line and "REJECTED forged" in line, line
    assert "mode=gnss" not in line and "mode=forged" not in line  # nothing forged was shown
    # the real fusion, holding the key, is verified
    with Bus(router, vehicle="mv", auth_key=KEY) as fusion:
        fusion.declare_liveliness()
        fusion.declare_config_queryable(lambda: {"tuning": 1})
        assert monitor_main(connect=router, vehicle="mv", record=None, duration_s=2.5,
                            headless=True, bus_access=access) == 0
    line = [ln for ln in capsys.readouterr().out.splitlines() if " mv " in ln][-1]
    assert "alive=yes verified" in line and "REJECTED" not in line, line
