"""The server's own signing key (Ed25519): created at first start in DATA_DIR (mode 0600), its public half served
at a well-known URL (GET /.well-known/segb-evidence-key) and printed by `segb evidence-key`, so a third party can
check an evidence bundle with no secret. A server that keeps nothing (STORE=memory) signs with a key of its own
that lives as long as the process."""

from __future__ import annotations

import hashlib
import os
from dataclasses import dataclass
from pathlib import Path

from cryptography.hazmat.primitives import serialization
from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PrivateKey, Ed25519PublicKey

KEY_FILE = "evidence-key.pem"


def fingerprint(public: Ed25519PublicKey) -> str:
    """SHA-256 of the raw public key, in hex: what people compare."""
    raw = public.public_bytes(serialization.Encoding.Raw, serialization.PublicFormat.Raw)
    return hashlib.sha256(raw).hexdigest()


def public_pem(public: Ed25519PublicKey) -> bytes:
    return public.public_bytes(serialization.Encoding.PEM, serialization.PublicFormat.SubjectPublicKeyInfo)


def read_public_key(pem: bytes) -> Ed25519PublicKey:
    """A PEM public key, or ValueError naming the problem."""
    key = serialization.load_pem_public_key(pem)
    if not isinstance(key, Ed25519PublicKey):
        raise ValueError("not an Ed25519 public key")
    return key


@dataclass(frozen=True)
class ServerKey:
    private: Ed25519PrivateKey

    @property
    def public(self) -> Ed25519PublicKey:
        return self.private.public_key()

    @property
    def fingerprint(self) -> str:
        return fingerprint(self.public)

    def public_pem(self) -> bytes:
        return public_pem(self.public)

    def sign(self, data: bytes) -> bytes:
        return self.private.sign(data)

    @classmethod
    def in_memory(cls) -> ServerKey:
        return cls(Ed25519PrivateKey.generate())

    @classmethod
    def at(cls, data_dir: Path) -> ServerKey:
        """The key in `data_dir`, created there (readable by this user only) if it is not there yet. Processes
        starting together (API workers) create it once: the file appears whole or not at all."""
        path = data_dir / KEY_FILE
        if not path.exists():
            data_dir.mkdir(parents=True, exist_ok=True)
            pem = Ed25519PrivateKey.generate().private_bytes(
                serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8, serialization.NoEncryption()
            )
            partial = path.with_name(f"{KEY_FILE}.{os.getpid()}")
            descriptor = os.open(partial, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
            with os.fdopen(descriptor, "wb") as file:
                file.write(pem)
                file.flush()
                os.fsync(file.fileno())
            try:
                os.link(partial, path)  # fails if another process made it first: theirs is kept
            except FileExistsError:
                pass
            finally:
                partial.unlink()
        key = serialization.load_pem_private_key(path.read_bytes(), password=None)
        if not isinstance(key, Ed25519PrivateKey):
            raise ValueError(f"{path} does not hold an Ed25519 private key")
        return cls(key)
