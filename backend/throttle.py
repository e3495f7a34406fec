"""Sign-in throttling: failed sign-ins counted in a moving window per user name and per client address
(the ``limits`` package, in memory: one API process holds the counts, as it holds the device)."""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

from limits import RateLimitItemPerMinute
from limits.storage import MemoryStorage
from limits.strategies import MovingWindowRateLimiter


@dataclass
class LoginThrottle:
    """Args:
        per_user_per_minute: failed sign-ins allowed for one user name per minute.
        per_address_per_minute: failed sign-ins allowed from one client address per minute (all names).
    """

    per_user_per_minute: int = 5
    per_address_per_minute: int = 20
    _limiter: MovingWindowRateLimiter = field(init=False, repr=False)

    def __post_init__(self) -> None:
        self._limiter = MovingWindowRateLimiter(MemoryStorage())
        self._user = RateLimitItemPerMinute(self.per_user_per_minute)
        self._address = RateLimitItemPerMinute(self.per_address_per_minute)

    def retry_after_s(self, username: str, address: str) -> int:
        """0 when a sign-in may be tried now, else the seconds until one may."""
        waits = [self._limiter.get_window_stats(item, kind, key).reset_time - time.time()
                 for item, kind, key in ((self._user, "user", username), (self._address, "address", address))
                 if not self._limiter.test(item, kind, key)]
        return max(1, math.ceil(max(waits))) if waits else 0

    def failed(self, username: str, address: str) -> None:
        """Count one failed sign-in against the name and the address."""
        self._limiter.hit(self._user, "user", username)
        self._limiter.hit(self._address, "address", address)
