"""The content hash of a table or an envelope: what storage keys on and checks at every read.

A version is stored as its canonical JSON (sorted keys, no spaces, no NaN) and keyed by the SHA-256 of exactly that
text, so the hash covers every value, unit-named field and provenance note, and reading the row back can prove the
bytes are the ones written. (The CRC-32 the device verifies is the link's own, over the raw wire values:
:func:`device_bridge.protocol.wire_crc32`.)
"""

from __future__ import annotations

import hashlib
import json

from pydantic import BaseModel


def canonical_text(value: object) -> str:
    """The one JSON text of a value: sorted keys, no spaces, no NaN."""
    return json.dumps(value, sort_keys=True, separators=(",", ":"), allow_nan=False)


def canonical_json(content: BaseModel) -> str:
    """The one text a table or an envelope is stored and hashed as."""
    return canonical_text(content.model_dump(mode="json"))


def content_sha256(text: str) -> str:
    """SHA-256 (hex) of stored canonical JSON."""
    return hashlib.sha256(text.encode()).hexdigest()
