"""Secrets stored in the database (controller passwords), encrypted under TCPCAL_SECRET_KEY.

Fernet (AES-128-CBC with HMAC-SHA256, from `cryptography`) under a key derived from the
configured secret with HKDF-SHA256: the database and its backups hold only the ciphertext,
and the secret itself never enters the database. A changed secret makes the stored
passwords unreadable (SecretUnavailable says to set the old one or send them again).
"""

from __future__ import annotations

import base64

from cryptography.fernet import Fernet, InvalidToken
from cryptography.hazmat.primitives import hashes
from cryptography.hazmat.primitives.kdf.hkdf import HKDF

from app.config import get_settings

SECRET_ENV = "TCPCAL_SECRET_KEY"
_SALT = b"tcpcal/secretbox/v1"
_INFO = b"controller passwords"


class SecretUnavailable(RuntimeError):
    """No secret key is configured, or the stored secret was encrypted under another one."""


def _fernet() -> Fernet:
    secret = get_settings().secret_key
    if secret is None or not secret.get_secret_value():
        raise SecretUnavailable(
            f"{SECRET_ENV} is not set: set it (a long random string, the same on every "
            "instance) to store or use controller passwords"
        )
    key = HKDF(algorithm=hashes.SHA256(), length=32, salt=_SALT, info=_INFO).derive(
        secret.get_secret_value().encode()
    )
    return Fernet(base64.urlsafe_b64encode(key))


def key_configured() -> bool:
    """True when a secret key is set."""
    secret = get_settings().secret_key
    return secret is not None and bool(secret.get_secret_value())


def encrypt(plain: str) -> str:
    """The ciphertext to store for `plain` (a Fernet token, ASCII)."""
    return _fernet().encrypt(plain.encode()).decode("ascii")


def decrypt(token: str) -> str:
    """The plain text of a stored ciphertext; SecretUnavailable when the key cannot open it."""
    try:
        return _fernet().decrypt(token.encode("ascii")).decode()
    except InvalidToken as exc:
        raise SecretUnavailable(
            f"a stored controller password cannot be decrypted with the {SECRET_ENV} now set "
            "(it was changed): set the previous one, or send the password again"
        ) from exc
