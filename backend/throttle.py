"""Sign-in throttling: failed sign-ins counted in moving windows per user name at a client address, per client
address, and per user name from anywhere (the ``limits`` package, in memory: one API process holds the counts, as it
holds the device)."""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

from limits import RateLimitItemPerMinute
from limits.storage import MemoryStorage
from limits.strategies import MovingWindowRateLimiter


@dataclass
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
    _limiter: MovingWindowRateLimiter = field(init=False, repr=False)

    def __post_init__(self) -> None:
        self._limiter = MovingWindowRateLimiter(MemoryStorage())
        self._user = RateLimitItemPerMinute(self.per_user_per_minute)
        self._address = RateLimitItemPerMinute(self.per_address_per_minute)
        self._anywhere = RateLimitItemPerMinute(self.per_user_anywhere_per_minute)

    def _windows(self, username: str, address: str) -> tuple:
        return ((self._user, "user-at", f"{username}\x00{address}"), (self._address, "address", address),
                (self._anywhere, "user", username))

    def retry_after_s(self, username: str, address: str) -> int:
        """0 when a sign-in may be tried now, else the seconds until one may."""
        waits = [self._limiter.get_window_stats(item, kind, key).reset_time - time.time()
                 for item, kind, key in self._windows(username, address) if not self._limiter.test(item, kind, key)]
        return max(1, math.ceil(max(waits))) if waits else 0

    def failed(self, username: str, address: str) -> None:
        """Count one failed sign-in against the name at this address, the address and the name."""
        for item, kind, key in self._windows(username, address):
            self._limiter.hit(item, kind, key)
