"""The hardened compose profile (docs/deploy/docker-compose.hardened.yml), checked offline.

No Docker engine here: the override is merged onto docker-compose.yml as Compose merges it
(mappings merged, ``command`` / ``healthcheck.test`` replaced), the result is validated against
the Compose Specification, every hilnav command and health check is parsed by the CLI itself,
and the zenohd configuration is compared with :class:`RouterSecurity`'s and then *run* on
loopback with real certificates: an mTLS client with the fusion's common name publishes
estimates, the monitor's cannot, a client without a certificate is refused.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import jsonschema
import pytest
import yaml
import zenoh

from hil.bus import Bus, ClientSecurity
from hil.bus.security import RouterSecurity
from hil.router import free_tcp_port
from tests.helpers.certs import make_pki

from ..hil.test_bus_security import SHORT, _forgery_refused
from .test_compose import COMPOSE, ROOT, argv, compose_spec, hilnav_params, option

HARDENED = ROOT / "docs" / "deploy" / "docker-compose.hardened.yml"
CLIENTS = ("fusion", "sim", "monitor")


def _merge(base: Any, over: Any, path: tuple[str, ...] = ()) -> Any:
    if isinstance(base, dict) and isinstance(over, dict):
        out = dict(base)
        for k, v in over.items():
            out[k] = _merge(base[k], v, (*path, k)) if k in base else v
        return out
    return over  # scalars and sequences (command, healthcheck.test) are replaced


def hardened() -> dict[str, Any]:
    return _merge(yaml.safe_load(COMPOSE.read_text()), yaml.safe_load(HARDENED.read_text()))


def zenohd_config() -> dict[str, Any]:
    doc = hardened()
    content = doc["configs"]["zenohd_hardened"]["content"]
    cfg: dict[str, Any] = json.loads(content)  # JSON is JSON5: zenohd reads it as is
    return cfg


def test_merged_profile_follows_the_compose_specification() -> None:
    schema = compose_spec()
    validator = jsonschema.validators.validator_for(schema)(schema)
    errors = sorted(validator.iter_errors(hardened()), key=lambda e: list(e.path))
    assert not errors, "\n".join(f"{list(e.path)}: {e.message}" for e in errors)


def test_every_command_and_health_check_parses_and_uses_mtls_and_the_key() -> None:
    doc = hardened()
    for name in CLIENTS:
        service = doc["services"][name]
        secrets = set(service["secrets"])
        for args in (argv(service["command"]), service["healthcheck"]["test"][2:]):
            assert hilnav_params(args), name
            endpoint = option(args, "--zenoh") if "--zenoh" in args else option(args,
                                                                                 "--connect")
            assert endpoint == "tls/zenohd:7447", name
            assert option(args, "--tls-cert") == f"/run/secrets/{name}.crt", name
            assert option(args, "--tls-key") == f"/run/secrets/{name}.key", name
            used = {a.removeprefix("/run/secrets/") for a in args if a.startswith("/run/")}
            assert used <= secrets, (name, used - secrets)
        assert option(argv(service["command"]), "--zenoh-key-file") == "/run/secrets/zenoh.key"
    # the fusion's health check challenges the fusion (the key), not only its token
    test = doc["services"]["fusion"]["healthcheck"]["test"]
    assert "--alive" in test and "--zenoh-key-file" in test
    for name in ("fusion", "sim"):
        assert "/run/secrets/mavlink.key" in argv(doc["services"][name]["command"])
    assert set(doc["secrets"]) == {s for x in doc["services"].values()
                                   for s in x.get("secrets", [])}


def test_zenohd_config_is_the_one_router_security_builds() -> None:
    cfg = zenohd_config()
    tls = cfg["transport"]["link"]["tls"]
    expected = RouterSecurity.model_construct(
        users_file=None, tls_cert=Path(tls["listen_certificate"]),
        tls_key=Path(tls["listen_private_key"]), tls_ca=Path(tls["root_ca_certificate"]),
        mtls=True, acl=True, fusion=("fusion",), sim=("sim",), insecure=False,
    ).zenoh_config()
    assert {k: cfg[k] for k in expected} == expected
    assert cfg["listen"]["endpoints"] == ["tls/0.0.0.0:7447"]
    assert cfg["scouting"]["multicast"]["enabled"] is False
    assert "plugins" not in cfg  # no REST admin API
    assert set(hardened()["services"]["zenohd"]["secrets"]) == {
        Path(tls[k]).name for k in ("listen_certificate", "listen_private_key",
                                    "root_ca_certificate")}


@pytest.fixture()
def running_zenohd(tmp_path: Path) -> Any:
    """zenohd's hardened config with the container paths pointing at a test PKI, on loopback."""
    pki = make_pki(tmp_path, ("fusion", "sim", "monitor", "viewer"))
    cfg = zenohd_config()
    tls = cfg["transport"]["link"]["tls"]
    tls |= {"listen_certificate": str(pki.server_cert),
            "listen_private_key": str(pki.server_key), "root_ca_certificate": str(pki.ca)}
    endpoint = f"tls/localhost:{free_tcp_port()}"
    cfg["listen"]["endpoints"] = [endpoint]
    session = zenoh.open(zenoh.Config.from_json5(json.dumps(cfg)))
    try:
        yield endpoint, pki
    finally:
        session.close()


def test_the_hardened_router_config_really_enforces_it(running_zenohd: Any) -> None:
    endpoint, pki = running_zenohd

    def who(name: str) -> ClientSecurity:
        cert, k = pki.client(name)
        return ClientSecurity(tls_ca=pki.ca, tls_cert=cert, tls_key=k)

    with Bus(endpoint, vehicle="h", config=SHORT, security=ClientSecurity(tls_ca=pki.ca)) as bare:
        assert not bare.wait_connected(2.0)
    # the monitor's certificate is valid but read-only: its estimates go nowhere
    _forgery_refused(endpoint, fusion=who("fusion"), viewer=who("viewer"),
                     attacker=who("monitor"), sim=who("sim"))

