"""Forwarded headers are believed only from the proxies the settings name (uvicorn trusts 127.0.0.1 by default)."""

from __future__ import annotations

import signal

import httpx
import pytest

from tests.helpers.server import add_user, start_server

pytestmark = pytest.mark.wallclock


def _guesses(base: str, forwarded: list[str], names: list[str] | None = None) -> list[int]:
    names = names or ["pat"] * len(forwarded)
    return [httpx.post(f"{base}/api/auth/token", headers={"X-Forwarded-For": ip},
                       data={"username": name, "password": f"wrong-{i}"}).status_code
            for i, (ip, name) in enumerate(zip(forwarded, names, strict=True))]


def test_a_rotating_forwarded_header_does_not_dodge_the_throttle_by_default(tmp_path):
    """Guessing many names, each from a claimed new address: the server counts the real peer's address."""
    add_user(tmp_path, "pat", "prosthetist")
    proc, base = start_server(tmp_path)
    try:
        codes = _guesses(base, [f"203.0.113.{i}" for i in range(24)], [f"user{i}" for i in range(24)])
        assert codes[:20] == [401] * 20 and set(codes[20:]) == {429}
    finally:
        proc.send_signal(signal.SIGINT)
        proc.wait(timeout=30)


def test_behind_a_named_proxy_each_forwarded_client_is_its_own_address(tmp_path):
    add_user(tmp_path, "pat", "prosthetist")
    proc, base = start_server(tmp_path, extra_args=("--trusted-proxy", "127.0.0.1"))
    try:
        assert _guesses(base, ["203.0.113.7"] * 6)[-1] == 429        # that client is throttled
        assert _guesses(base, ["198.51.100.4"])[-1] == 401            # another client behind the proxy is not
    finally:
        proc.send_signal(signal.SIGINT)
        proc.wait(timeout=30)
