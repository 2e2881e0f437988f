"""Real X.509 certificates for TLS / mTLS tests, made on the fly with ``cryptography``.

One private CA signs a server certificate (SAN ``localhost`` and ``127.0.0.1``) and client
certificates whose common name is the client's role (Zenoh's access control matches
``cert_common_names``). Everything is PEM in a folder the test owns.
"""

from __future__ import annotations

import datetime as dt
import ipaddress
from dataclasses import dataclass
from pathlib import Path

from cryptography import x509
from cryptography.hazmat.primitives import hashes, serialization
from cryptography.hazmat.primitives.asymmetric import ec
from cryptography.x509.oid import ExtendedKeyUsageOID, NameOID

__all__ = ["Pki", "make_pki"]


@dataclass(frozen=True)
class Pki:
    """PEM files of one test PKI."""

    ca: Path
    server_cert: Path
    server_key: Path
    folder: Path

    def client(self, name: str) -> tuple[Path, Path]:
        """(certificate, key) of the client whose common name is ``name``."""
        return self.folder / f"{name}.crt", self.folder / f"{name}.key"


def _key() -> ec.EllipticCurvePrivateKey:
    return ec.generate_private_key(ec.SECP256R1())


def _write_key(key: ec.EllipticCurvePrivateKey, path: Path) -> None:
    path.write_bytes(key.private_bytes(serialization.Encoding.PEM,
                                       serialization.PrivateFormat.PKCS8,
                                       serialization.NoEncryption()))


def _cert(subject: str, key: ec.EllipticCurvePrivateKey, issuer: x509.Name,
          issuer_key: ec.EllipticCurvePrivateKey, *, ca: bool,
          san: list[x509.GeneralName] | None = None,
          usage: list[x509.ObjectIdentifier] | None = None) -> x509.Certificate:
    now = dt.datetime.now(dt.UTC)
    b = (x509.CertificateBuilder()
         .subject_name(x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, subject)]))
         .issuer_name(issuer)
         .public_key(key.public_key())
         .serial_number(x509.random_serial_number())
         .not_valid_before(now - dt.timedelta(minutes=5))
         .not_valid_after(now + dt.timedelta(days=1))
         .add_extension(x509.BasicConstraints(ca=ca, path_length=None), critical=True))
    if san:
        b = b.add_extension(x509.SubjectAlternativeName(san), critical=False)
    if usage:
        b = b.add_extension(x509.ExtendedKeyUsage(usage), critical=False)
    if ca:
        b = b.add_extension(x509.KeyUsage(
            digital_signature=True, content_commitment=False, key_encipherment=False,
            data_encipherment=False, key_agreement=False, key_cert_sign=True, crl_sign=True,
            encipher_only=False, decipher_only=False), critical=True)
    return b.sign(issuer_key, hashes.SHA256())


def _pem(cert: x509.Certificate, path: Path) -> None:
    path.write_bytes(cert.public_bytes(serialization.Encoding.PEM))


def make_pki(folder: Path, clients: tuple[str, ...] = (), *, ca_name: str = "hilnav test CA"
             ) -> Pki:
    """A CA, a server certificate for localhost / 127.0.0.1, and one client certificate per
    name in ``clients`` (common name = the name), all written into ``folder``."""
    folder.mkdir(parents=True, exist_ok=True)
    ca_key = _key()
    ca_name_x = x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, ca_name)])
    ca_cert = _cert(ca_name, ca_key, ca_name_x, ca_key, ca=True)
    _pem(ca_cert, folder / "ca.crt")
    server_key = _key()
    san: list[x509.GeneralName] = [x509.DNSName("localhost"),
                                   x509.IPAddress(ipaddress.ip_address("127.0.0.1"))]
    _pem(_cert("localhost", server_key, ca_name_x, ca_key, ca=False, san=san,
               usage=[ExtendedKeyUsageOID.SERVER_AUTH]), folder / "server.crt")
    _write_key(server_key, folder / "server.key")
    for name in clients:
        k = _key()
        _pem(_cert(name, k, ca_name_x, ca_key, ca=False, san=[x509.DNSName(name)],
                   usage=[ExtendedKeyUsageOID.CLIENT_AUTH]), folder / f"{name}.crt")
        _write_key(k, folder / f"{name}.key")
    return Pki(ca=folder / "ca.crt", server_cert=folder / "server.crt",
               server_key=folder / "server.key", folder=folder)
