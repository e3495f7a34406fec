"""Sign-in throttling: failed sign-ins counted in moving windows per user name at a client address, per client
address, and per user name from anywhere, in the database (``login_failures``), so every API instance sees the same
counts and a lock-out holds whichever instance the next attempt reaches.

Why not a package: the ``limits`` package this replaced keeps its windows in memory, Redis, Memcached, MongoDB or etcd,
none of which QuasiTune runs; the database every instance already shares holds them with two indexed queries.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

from sqlalchemy import Connection, delete, insert, select

from backend.store.tables import login_failures

WINDOW_S = 60.0       # every window is a minute long
KEEP_S = 2 * WINDOW_S  # rows older than this are purged as new failures arrive


def user_key(username: str) -> str:
    """The name a failure counts against: as typed, lower-cased (sign-in ignores case, so must the count)."""
    return username.lower()


@dataclass(frozen=True)
class LoginThrottle:
    """Three windows, so that one attacker cannot lock out a clinic: an attacker's failures lock the names they try
    only from their own address, and their own address, while a name attacked from many addresses is slowed down
    only past a much larger count.

    Args:
        per_user_per_minute: failed sign-ins allowed for one user name from one client address per minute.
        per_address_per_minute: failed sign-ins allowed from one client address per minute (all names).
        per_user_anywhere_per_minute: failed sign-ins allowed for one user name from all addresses per minute.
    """

    per_user_per_minute: int = 5
    per_address_per_minute: int = 20
    per_user_anywhere_per_minute: int = 100

    def retry_after_s(self, conn: Connection, username: str, address: str, now: float | None = None) -> int:
        """0 when a sign-in may be tried now, else the whole seconds until one may."""
        now = time.time() if now is None else now
        c, key = login_failures.c, user_key(username)
        windows = ((self.per_user_per_minute, (c.username_key == key, c.address == address)),
                   (self.per_address_per_minute, (c.address == address,)),
                   (self.per_user_anywhere_per_minute, (c.username_key == key,)))
        waits = []
        for limit, where in windows:
            # the limit-th newest failure in the window: the window allows one more once it has aged out
            nth = conn.execute(select(c.at_unix).where(*where, c.at_unix > now - WINDOW_S)
                               .order_by(c.at_unix.desc()).offset(limit - 1).limit(1)).scalar()
            if nth is not None:
                waits.append(nth + WINDOW_S - now)
        return max(1, math.ceil(max(waits))) if waits else 0


def record_failure(conn: Connection, username: str, address: str, now: float | None = None) -> None:
    """Count one failed sign-in against the name at this address, the address and the name (inside the caller's write
    transaction, with its audit entry), and drop the rows no window reads any more."""
    now = time.time() if now is None else now
    conn.execute(delete(login_failures).where(login_failures.c.at_unix < now - KEEP_S))
    conn.execute(insert(login_failures).values(at_unix=now, username_key=user_key(username), address=address))
