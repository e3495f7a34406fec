"""Password hashing (scrypt, memory-hard) and opaque bearer tokens.

Passwords: ``hashlib.scrypt`` with n = 2¹⁴, r = 8, p = 1 (16 MiB per hash, tens of milliseconds), a 16-byte
random salt, stored as ``scrypt$n$r$p$salt$hash`` (base64) so the cost can be raised later without breaking
old hashes. The cost of new hashes is the process's (:func:`set_hash_cost`, from the one Settings'
``password_hash_cost``): a test run lowers it, since a hash's cost is what it is for and a suite makes hundreds.
Tokens: 32 random bytes (URL-safe base64) handed to the client once; only their SHA-256 is stored, so a copy of
the database does not log anyone in. Tokens expire (``expires_in`` seconds).
"""

from __future__ import annotations

import base64
import functools
import hashlib
import hmac
import re
import secrets

SCRYPT_N, SCRYPT_R, SCRYPT_P = 2**14, 8, 1
_cost_n = SCRYPT_N       # n of the hashes this process makes (set_hash_cost)
_MAXMEM = 64 * 1024 * 1024
MIN_PASSWORD_LENGTH = 8
MAX_PASSWORD_LENGTH = 1024


def _b64(b: bytes) -> str:
    return base64.b64encode(b).decode("ascii")


def _scrypt(password: str, salt: bytes, n: int, r: int, p: int) -> bytes:
    return hashlib.scrypt(password.encode("utf-8"), salt=salt, n=n, r=r, p=p, maxmem=_MAXMEM, dklen=32)


def check_password_policy(password: str, username: str) -> None:
    """Refuse a password that is too short or absurdly long, or is the user's name or a common password (one of
    zxcvbn's lists of leaked passwords, whole, in any case or with common letter swaps), or guessable in few tries
    (zxcvbn's score 0): ValueError with the reason, in words the user can act on."""
    if len(password) < MIN_PASSWORD_LENGTH:
        raise ValueError(f"password must be at least {MIN_PASSWORD_LENGTH} characters")
    if len(password) > MAX_PASSWORD_LENGTH:
        raise ValueError(f"password must be at most {MAX_PASSWORD_LENGTH} characters")
    from zxcvbn import zxcvbn

    found = zxcvbn(password, user_inputs=[username])
    whole = [m for m in found["sequence"] if m.get("pattern") == "dictionary" and m["token"] == password]
    letters, name = re.sub(r"[^a-z]", "", password.casefold()), re.sub(r"[^a-z]", "", username.casefold())
    if password.casefold() == username.casefold() or any(m.get("dictionary_name") == "user_inputs" for m in whole) \
            or (name and letters and letters == name * (len(letters) // len(name))):   # the name, repeated or dressed
        raise ValueError("the password must not be the user name (nor the name with digits or signs added)")
    if any(m.get("dictionary_name") == "passwords" for m in whole) or found["score"] == 0:
        raise ValueError("that password is one of the most common passwords (or as easy to guess): choose another, "
                         "e.g. three or four unrelated words")


def set_hash_cost(n: int) -> None:
    """The scrypt n of the hashes this process makes from now on (a power of two, 2 to 2²⁰; 2¹⁴ in production).
    Hashes already stored keep their own n: verifying reads it from the hash."""
    global _cost_n
    if not (isinstance(n, int) and 2 <= n <= 2**20 and n & (n - 1) == 0):
        raise ValueError(f"the password hash cost must be a power of two from 2 to 2**20, got {n!r}")
    _cost_n = n


def hash_password(password: str) -> str:
    """Salted scrypt hash in the self-describing ``scrypt$n$r$p$salt$hash`` form."""
    salt = secrets.token_bytes(16)
    digest = _scrypt(password, salt, _cost_n, SCRYPT_R, SCRYPT_P)
    return f"scrypt${_cost_n}${SCRYPT_R}${SCRYPT_P}${_b64(salt)}${_b64(digest)}"


def verify_password(password: str, stored: str) -> bool:
    """Constant-time check of ``password`` against a stored hash (False on any malformed hash)."""
    try:
        scheme, n, r, p, salt, digest = stored.split("$")
        if scheme != "scrypt":
            return False
        expected = base64.b64decode(digest)
        got = _scrypt(password, base64.b64decode(salt), int(n), int(r), int(p))
    except (ValueError, TypeError):
        return False
    return hmac.compare_digest(got, expected)


@functools.cache
def _dummy_hash(n: int) -> str:
    return hash_password(secrets.token_urlsafe(16))


def burn_password_check(password: str) -> None:
    """Spend the same time as a real check, for unknown users: a failed login takes as long whether or not
    the name exists (no user enumeration by timing)."""
    verify_password(password, _dummy_hash(_cost_n))


def new_token() -> str:
    """A fresh bearer token (shown to the client once)."""
    return secrets.token_urlsafe(32)


def token_digest(token: str) -> str:
    """What is stored for a token: its SHA-256, hex."""
    return hashlib.sha256(token.encode("utf-8", "surrogatepass")).hexdigest()
