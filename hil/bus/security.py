"""Zenoh transport security of hilnav: authentication, TLS / mTLS, access control.

Two sides, each turned into eclipse-zenoh's own configuration keys (checked against
eclipse-zenoh 1.10):

- :class:`ClientSecurity` (every :class:`hil.bus.Bus`): ``transport/auth/usrpwd`` ``user`` /
  ``password``; ``transport/link/tls`` ``root_ca_certificate`` (the CA that signed the router's
  certificate) and, for mTLS, ``connect_certificate`` / ``connect_private_key`` /
  ``enable_mtls``.
- :class:`RouterSecurity` (``hilnav router``, ``hilnav up``'s in-process router):
  ``transport/auth/usrpwd/dictionary_file`` (lines ``user:password``); ``transport/link/tls``
  ``listen_certificate`` / ``listen_private_key`` / ``root_ca_certificate`` + ``enable_mtls``
  (clients must show a certificate signed by that CA); ``access_control`` (default deny, roles
  below); ``adminspace`` off.

Access-control roles (a role is a set of user names or certificate common names):

==========  ==================================================================================
everyone    authenticated clients may subscribe, query and watch liveliness under ``hilnav/**``
fusion      may also publish, declare the queryable and the ``alive`` token under
            ``hilnav/*/fusion/**``
sim         may also publish under ``hilnav/*/sim/**``, ``hilnav/*/sensors/**`` and
            ``hilnav/*/scenario/**``
==========  ==================================================================================

Nothing else is allowed (default deny): not the admin space ``@/**``, not any other key.
"""

from __future__ import annotations

import dataclasses
import ipaddress
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, Final, Self

import pydantic

__all__ = [
    "PASSWORD_ENV",
    "BusAccess",
    "ClientSecurity",
    "RouterSecurity",
    "check_peer_link",
    "endpoint_host",
    "is_loopback_endpoint",
]

PASSWORD_ENV: Final = "HILNAV_ZENOH_PASSWORD"
"""Environment variable holding the Zenoh usrpwd password (never on the command line)."""

_READ_RULE: Final = [
    {"id": "read-in", "flows": ["ingress"], "permission": "allow", "key_exprs": ["hilnav/**"],
     "messages": ["declare_subscriber", "query", "liveliness_query",
                  "declare_liveliness_subscriber"]},
    # declare_subscriber out: a publisher learns whether anyone listens (matching status), also
    # for a subscription wider than its own keys (a monitor's hilnav/<vehicle>/**)
    {"id": "read-out", "flows": ["egress"], "permission": "allow", "key_exprs": ["hilnav/**"],
     "messages": ["put", "delete", "reply", "liveliness_token", "declare_subscriber"]},
]
_FUSION_RULE: Final = [
    {"id": "fusion-in", "flows": ["ingress"], "permission": "allow",
     "key_exprs": ["hilnav/*/fusion/**"],
     "messages": ["put", "delete", "declare_queryable", "reply", "liveliness_token"]},
    # the router forwards queries on fusion/config to the fusion's queryable
    {"id": "fusion-out", "flows": ["egress"], "permission": "allow",
     "key_exprs": ["hilnav/*/fusion/**"], "messages": ["query"]},
]
_SIM_RULE: Final = [
    {"id": "sim-in", "flows": ["ingress"], "permission": "allow",
     "key_exprs": ["hilnav/*/sim/**", "hilnav/*/sensors/**", "hilnav/*/scenario/**"],
     "messages": ["put", "delete"]},
]


def endpoint_host(endpoint: str) -> str:
    """The host part of ``proto/host:port`` (brackets of an IPv6 literal removed)."""
    rest = endpoint.split("/", 1)[-1].split("#", 1)[0]
    host = rest.rsplit(":", 1)[0] if ":" in rest else rest
    return host.strip("[]")


def is_loopback_endpoint(endpoint: str) -> bool:
    """Whether ``endpoint`` listens on this machine only (127.0.0.0/8, ::1, localhost)."""
    host = endpoint_host(endpoint)
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False  # a name other than localhost may resolve to any interface


def check_peer_link(endpoints: Sequence[str], security: ClientSecurity) -> None:
    """Refuse a direct peer link (``hilnav fusion --zenoh-listen``, ``hilnav monitor --peer``)
    that is not plain loopback: ``ValueError`` (one line) for an endpoint beyond loopback or for
    login / TLS options. Login, TLS and access control are the router's: a direct peer link
    has none of them, so it stays on this machine. The shared payload key (HMAC tags,
    :mod:`hil.bus.auth`) works on it as on the router."""
    exposed = [e for e in endpoints if not is_loopback_endpoint(e)]
    if exposed:
        raise ValueError(f"a direct peer link stays on loopback (it has no login, TLS or access "
                         f"control); {', '.join(exposed)} is not: use the router "
                         "(hilnav router --users-file / --mtls) beyond this machine")
    if not security.empty:
        raise ValueError("--zenoh-user / --tls-* are router features: a direct peer link "
                         "(--zenoh-listen, --peer) has no login or TLS; use the router, or the "
                         "shared payload key (--zenoh-key-file) to authenticate samples")


def _readable(path: Path | None, what: str) -> Path | None:
    if path is None:
        return None
    if not path.is_file():
        raise ValueError(f"{what} {path} is not a readable file")
    try:
        with path.open("rb"):
            pass
    except OSError as exc:
        raise ValueError(f"{what} {path}: {exc.strerror}") from None
    return path.resolve()


def _uses_tls(endpoints: Sequence[str]) -> bool:
    return any(e.startswith("tls/") for e in endpoints)


class ClientSecurity(pydantic.BaseModel):
    """How one hilnav process authenticates to the router.

    Attributes
    ----------
    user : str, optional
        usrpwd user name (the router's dictionary file must list it).
    password : SecretStr, optional
        Its password; use :meth:`from_options` to read it from a file or ``HILNAV_ZENOH_PASSWORD``.
    tls_ca : Path, optional
        CA certificate (PEM) that signed the router's certificate (``tls/`` endpoints).
    tls_cert, tls_key : Path, optional
        This client's certificate and private key (PEM) for mTLS; the certificate's common name
        is the name access control knows the client by.
    """

    model_config = pydantic.ConfigDict(frozen=True, extra="forbid")

    user: str | None = None
    password: pydantic.SecretStr | None = None
    tls_ca: Path | None = None
    tls_cert: Path | None = None
    tls_key: Path | None = None

    @pydantic.model_validator(mode="after")
    def _check(self) -> Self:
        if (self.user is None) != (self.password is None):
            raise ValueError(
                f"Zenoh usrpwd needs both a user and a password (password from "
                f"--zenoh-password-file or {PASSWORD_ENV})")
        if self.user is not None and (not self.user or ":" in self.user):
            raise ValueError(f"Zenoh user {self.user!r} must be non-empty without ':'")
        if (self.tls_cert is None) != (self.tls_key is None):
            raise ValueError("mTLS needs both --tls-cert and --tls-key")
        if self.tls_cert is not None and self.tls_ca is None:
            raise ValueError("--tls-cert needs --tls-ca (the CA of the router's certificate)")
        _readable(self.tls_ca, "--tls-ca")
        _readable(self.tls_cert, "--tls-cert")
        _readable(self.tls_key, "--tls-key")
        return self

    @classmethod
    def from_options(
        cls,
        *,
        user: str | None = None,
        password_file: Path | None = None,
        tls_ca: Path | None = None,
        tls_cert: Path | None = None,
        tls_key: Path | None = None,
        environ: Mapping[str, str] | None = None,
    ) -> Self:
        """Build from CLI options; the password comes from ``password_file`` (first line) or,
        without one, from ``HILNAV_ZENOH_PASSWORD`` (only read when ``user`` is given)."""
        password: str | None = None
        if password_file is not None:
            _readable(password_file, "--zenoh-password-file")
            lines = password_file.read_text().splitlines()
            password = lines[0].strip() if lines else ""
            if not password:
                raise ValueError(f"--zenoh-password-file {password_file} holds no password")
            if user is None:
                raise ValueError("--zenoh-password-file needs --zenoh-user")
        elif user is not None:
            env = os.environ if environ is None else environ
            password = env.get(PASSWORD_ENV) or None
        return cls(user=user, password=None if password is None else pydantic.SecretStr(password),
                   tls_ca=tls_ca, tls_cert=tls_cert, tls_key=tls_key)

    @property
    def empty(self) -> bool:
        """No authentication and no TLS material: an open client."""
        return self.user is None and self.tls_ca is None

    def check_endpoints(self, endpoints: Sequence[str]) -> None:
        """Raise ``ValueError`` when TLS material is given but no endpoint is ``tls/``."""
        if self.tls_ca is not None and not _uses_tls(endpoints):
            raise ValueError("--tls-ca / --tls-cert apply to tls/ endpoints; the endpoint is "
                             f"{', '.join(endpoints)}")

    def transport(self) -> dict[str, Any]:
        """The ``transport`` section of the client's Zenoh configuration."""
        out: dict[str, Any] = {}
        if self.user is not None and self.password is not None:
            out["auth"] = {"usrpwd": {"user": self.user,
                                      "password": self.password.get_secret_value()}}
        if self.tls_ca is not None:
            tls: dict[str, Any] = {"root_ca_certificate": str(self.tls_ca)}
            if self.tls_cert is not None and self.tls_key is not None:
                tls |= {"connect_certificate": str(self.tls_cert),
                        "connect_private_key": str(self.tls_key), "enable_mtls": True}
            out["link"] = {"tls": tls}
        return out


class RouterSecurity(pydantic.BaseModel):
    """How the router authenticates clients and what they may do.

    Attributes
    ----------
    users_file : Path, optional
        usrpwd dictionary: one ``user:password`` per line; clients must log in.
    tls_cert, tls_key : Path, optional
        The router's certificate and key (PEM) for ``tls/`` endpoints.
    tls_ca : Path, optional
        With ``mtls``: the CA that must have signed every client's certificate.
    mtls : bool
        Clients must present a certificate signed by ``tls_ca``.
    acl : bool
        Access control on (default deny; roles in the module docstring).
    fusion : tuple of str
        User names / certificate common names allowed to publish ``hilnav/*/fusion/**``.
    sim : tuple of str
        User names / certificate common names allowed to publish sim, sensors and scenario.
    insecure : bool
        Allow listening beyond loopback without client authentication (usrpwd or mTLS).
    """

    model_config = pydantic.ConfigDict(frozen=True, extra="forbid")

    users_file: Path | None = None
    tls_cert: Path | None = None
    tls_key: Path | None = None
    tls_ca: Path | None = None
    mtls: bool = False
    acl: bool = False
    fusion: tuple[str, ...] = ("fusion",)
    sim: tuple[str, ...] = ("sim",)
    insecure: bool = False

    @pydantic.model_validator(mode="after")
    def _check(self) -> Self:
        if (self.tls_cert is None) != (self.tls_key is None):
            raise ValueError("a TLS router needs both --tls-cert and --tls-key")
        if self.mtls and (self.tls_ca is None or self.tls_cert is None):
            raise ValueError("--mtls needs --tls-ca (the clients' CA), --tls-cert and --tls-key")
        if self.acl and not self.authenticates:
            raise ValueError("--acl needs authenticated clients: --users-file or --mtls")
        for name in (*self.fusion, *self.sim):
            if not name or ":" in name:
                raise ValueError(f"access-control name {name!r} must be non-empty without ':'")
        users = _readable(self.users_file, "--users-file")
        if users is not None and not any(
            ":" in line for line in users.read_text().splitlines() if line.strip()
        ):
            raise ValueError(f"--users-file {users} holds no user:password line")
        _readable(self.tls_cert, "--tls-cert")
        _readable(self.tls_key, "--tls-key")
        _readable(self.tls_ca, "--tls-ca")
        return self

    @property
    def authenticates(self) -> bool:
        """Whether every client must prove who it is (usrpwd or mTLS)."""
        return self.users_file is not None or self.mtls

    def check_listen(self, endpoints: Sequence[str]) -> None:
        """Refuse an exposed router: ``ValueError`` for a non-loopback endpoint without client
        authentication (unless ``insecure``), or a ``tls/`` endpoint without a certificate."""
        if _uses_tls(endpoints) and self.tls_cert is None:
            raise ValueError("a tls/ endpoint needs --tls-cert and --tls-key")
        if self.tls_cert is not None and not _uses_tls(endpoints):
            raise ValueError("--tls-cert is for tls/ endpoints; listen on tls/HOST:PORT")
        exposed = [e for e in endpoints if not is_loopback_endpoint(e)]
        if exposed and not self.authenticates and not self.insecure:
            raise ValueError(
                f"refusing to listen on {', '.join(exposed)} (beyond loopback) without client "
                "authentication: give --users-file or --mtls (see 'Securing the Zenoh bus' in "
                "docs/live.md), or --insecure to accept every client that can reach it")

    def zenoh_config(self) -> dict[str, Any]:
        """The router's ``transport``, ``access_control`` and ``adminspace`` sections."""
        transport: dict[str, Any] = {}
        if self.users_file is not None:
            transport["auth"] = {"usrpwd": {"dictionary_file": str(self.users_file)}}
        if self.tls_cert is not None and self.tls_key is not None:
            tls: dict[str, Any] = {"listen_certificate": str(self.tls_cert),
                                   "listen_private_key": str(self.tls_key)}
            if self.mtls and self.tls_ca is not None:
                tls |= {"root_ca_certificate": str(self.tls_ca), "enable_mtls": True}
            transport["link"] = {"tls": tls}
        cfg: dict[str, Any] = {
            # the admin space (@/<zid>/router/...) tells any client the topology and config
            "adminspace": {"enabled": False, "permissions": {"read": False, "write": False}},
        }
        if transport:
            cfg["transport"] = transport
        if self.acl:
            cfg["access_control"] = self._access_control()
        return cfg

    def _access_control(self) -> dict[str, Any]:
        subjects: list[dict[str, Any]] = [{"id": "everyone"}]
        policies: list[dict[str, Any]] = [
            {"id": "everyone-reads", "rules": [r["id"] for r in _READ_RULE],
             "subjects": ["everyone"]}]
        for role, names, rules in (("fusion", self.fusion, _FUSION_RULE),
                                   ("sim", self.sim, _SIM_RULE)):
            ids = []
            for i, name in enumerate(names):
                # a subject with several attributes needs all of them: one per kind of name
                ids += [f"{role}-user-{i}", f"{role}-cn-{i}"]
                subjects += [{"id": f"{role}-user-{i}", "usernames": [name]},
                             {"id": f"{role}-cn-{i}", "cert_common_names": [name]}]
            if ids:
                policies.append({"id": f"{role}-publishes", "rules": [r["id"] for r in rules],
                                 "subjects": ids})
        return {"enabled": True, "default_permission": "deny",
                "rules": [*_READ_RULE, *_FUSION_RULE, *_SIM_RULE],
                "subjects": subjects, "policies": policies}


@dataclasses.dataclass(frozen=True)
class BusAccess:
    """How one hilnav process joins the bus: its transport identity and the shared payload key.

    Attributes
    ----------
    security : ClientSecurity
        usrpwd / TLS / mTLS (empty: an open client).
    auth_key : bytes, optional
        Shared payload key (``HILNAV_ZENOH_KEY``); None: samples are neither tagged nor checked.
    """

    security: ClientSecurity = dataclasses.field(default_factory=ClientSecurity)
    auth_key: bytes | None = dataclasses.field(default=None, repr=False)
