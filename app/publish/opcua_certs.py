"""The OPC UA server's application instance certificate (OPC 10000-4 6.1, OPC 10000-6 6.2.2).

With a certificate the server offers, beside security policy None, the Basic256Sha256
policy with SignAndEncrypt, and asks clients on the None endpoint to encrypt the user name
token's password with the certificate's key (the UserTokenPolicy's SecurityPolicyUri,
OPC 10000-4 7.41): an API key never crosses the network in clear.

`TCPCAL_OPCUA_CERTIFICATE` and `TCPCAL_OPCUA_PRIVATE_KEY` name the files (PEM or DER) to use;
without them a self-signed certificate is made for the process at start-up (asyncua's
cert_gen, RSA 2048, one year), which clients that pin server certificates must trust again
after each restart.
"""

from __future__ import annotations

import socket
from dataclasses import dataclass
from pathlib import Path

from asyncua.crypto import cert_gen
from cryptography import x509
from cryptography.hazmat.primitives.serialization import Encoding
from cryptography.x509.oid import ExtendedKeyUsageOID

from app.publish.sink import SinkError

#: The server's ApplicationUri, also in its certificate's subjectAltName (OPC 10000-6 6.2.2).
APPLICATION_URI = "urn:tcpcal:publisher"


@dataclass(frozen=True)
class ServerCertificate:
    """A certificate and its private key, each as read (PEM or DER) with its format."""

    certificate: bytes
    certificate_format: str
    private_key: bytes
    private_key_format: str


def _format(content: bytes) -> str:
    return "pem" if content.lstrip().startswith(b"-----BEGIN") else "der"


def certificate_from_files(certificate: str, private_key: str) -> ServerCertificate:
    """The certificate and key in these files; SinkError naming the file that is missing."""
    contents = []
    for setting, name in (
        ("TCPCAL_OPCUA_CERTIFICATE", certificate),
        ("TCPCAL_OPCUA_PRIVATE_KEY", private_key),
    ):
        try:
            contents.append(Path(name).read_bytes())
        except OSError as exc:
            raise SinkError(f"{setting}={name!r} cannot be read: {exc.strerror or exc}") from None
    cert, key = contents
    return ServerCertificate(cert, _format(cert), key, _format(key))


def self_signed(host: str) -> ServerCertificate:
    """A new self-signed server certificate for this host (and the machine's name)."""
    key = cert_gen.generate_private_key()
    names: list[x509.GeneralName] = [x509.UniformResourceIdentifier(APPLICATION_URI)]
    for dns in dict.fromkeys((host, socket.gethostname(), "localhost")):
        if dns and dns != "0.0.0.0":
            names.append(x509.DNSName(dns))
    cert = cert_gen.generate_self_signed_app_certificate(
        key, "tcpcal publisher", {}, names, [ExtendedKeyUsageOID.SERVER_AUTH]
    )
    return ServerCertificate(
        cert.public_bytes(Encoding.DER), "der", cert_gen.dump_private_key_as_pem(key), "pem"
    )


def server_certificate(
    certificate: str | None, private_key: str | None, *, host: str
) -> ServerCertificate:
    """The configured certificate, or a self-signed one when neither file is set."""
    if certificate and private_key:
        return certificate_from_files(certificate, private_key)
    if certificate or private_key:
        raise SinkError(
            "set both TCPCAL_OPCUA_CERTIFICATE and TCPCAL_OPCUA_PRIVATE_KEY, or neither "
            "(a self-signed certificate is made at start-up)"
        )
    return self_signed(host)
