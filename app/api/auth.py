"""API keys: creation, hashing, lookup and revocation (the CLI and the principal dependency use these).

A key is ``tl_`` + ``secrets.token_urlsafe(32)`` (256 random bits).  Only its
SHA-256 is stored.  A slow salted hash (bcrypt, argon2) protects *passwords*,
which are guessable; a 256-bit random key cannot be guessed, so a single fast
hash already makes a stolen table useless, and it lets a request find its key
by an indexed equality lookup instead of trying every row.

Nothing is cached: every request reads its key's row, so a revoked key stops
working on the very next request.  ``last_used_at`` is written at most once a
minute per key, so authenticated reads do not turn into writes.
"""
from __future__ import annotations

import hashlib
import secrets
from dataclasses import dataclass
from datetime import datetime, timedelta, timezone

from sqlalchemy import select

from app.runtime.db import Database
from app.runtime.models import ApiKey, utcnow

KEY_PREFIX = "tl_"
SHOWN_PREFIX_CHARS = 8  # "tl_" + 5 random characters: enough to tell keys apart in a listing
LAST_USED_RESOLUTION = timedelta(minutes=1)


def generate_key() -> str:
    return KEY_PREFIX + secrets.token_urlsafe(32)


def hash_key(key: str) -> str:
    return hashlib.sha256(key.encode("utf-8", "surrogatepass")).hexdigest()


@dataclass(frozen=True)
class KeyInfo:
    """What a listing shows of a key (never the key or its hash)."""

    name: str
    owner: str
    admin: bool
    key_prefix: str
    created_at: datetime
    revoked_at: datetime | None
    last_used_at: datetime | None


def _info(row: ApiKey) -> KeyInfo:
    return KeyInfo(name=row.name, owner=row.owner, admin=row.admin, key_prefix=row.key_prefix,
                   created_at=row.created_at, revoked_at=row.revoked_at, last_used_at=row.last_used_at)


class KeyNameTaken(Exception):
    """A key with this name exists already (names identify keys for revocation)."""


def create_key(db: Database, *, name: str, owner: str | None = None, admin: bool = False) -> tuple[KeyInfo, str]:
    """Store a new key for ``owner`` (default: ``name``); returns its info and the key, shown only now."""
    key = generate_key()
    with db.write() as s:
        if s.scalar(select(ApiKey).where(ApiKey.name == name)) is not None:
            raise KeyNameTaken(name)
        row = ApiKey(name=name, owner=owner or name, key_hash=hash_key(key), key_prefix=key[:SHOWN_PREFIX_CHARS],
                     admin=admin, created_at=utcnow())
        s.add(row)
    return _info(row), key


def list_keys(db: Database) -> list[KeyInfo]:
    with db.read() as s:
        return [_info(r) for r in s.scalars(select(ApiKey).order_by(ApiKey.created_at))]


def revoke_key(db: Database, name: str) -> bool:
    """Revoke the key called ``name``; False if there is no such key. Revoking twice keeps the first time."""
    with db.write() as s:
        row = s.scalar(select(ApiKey).where(ApiKey.name == name))
        if row is None:
            return False
        row.revoked_at = row.revoked_at or utcnow()
        return True


def authenticate(db: Database, key: str) -> KeyInfo | None:
    """The active key's info, or None for an unknown or revoked key."""
    if not key.startswith(KEY_PREFIX) or len(key) > 200:
        return None
    digest = hash_key(key)
    with db.read() as s:
        row = s.scalar(select(ApiKey).where(ApiKey.key_hash == digest))
        if row is None or row.revoked_at is not None:
            return None
        info = _info(row)
    last = info.last_used_at
    if last is not None and last.tzinfo is None:  # SQLite returns naive datetimes; stored times are UTC
        last = last.replace(tzinfo=timezone.utc)
    if last is None or utcnow() - last > LAST_USED_RESOLUTION:
        with db.write() as s:
            api_key = s.get(ApiKey, row.id)
            if api_key is not None:  # deleted meanwhile: nothing to record
                api_key.last_used_at = utcnow()
    return info
