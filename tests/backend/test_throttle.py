"""The sign-in throttle's three windows: one attacker cannot lock out a clinic."""

from __future__ import annotations

from backend.throttle import LoginThrottle


def test_failures_lock_a_name_only_at_the_attackers_address():
    t = LoginThrottle()
    for _ in range(5):
        t.failed("alice", "10.9.9.9")
    assert t.retry_after_s("alice", "10.9.9.9") > 0         # the attacker waits
    assert t.retry_after_s("alice", "192.0.2.10") == 0      # alice at her own workstation does not
    assert t.retry_after_s("bob", "10.9.9.9") == 0


def test_an_address_spraying_names_is_locked_and_only_that_address():
    t = LoginThrottle()
    for i in range(20):
        t.failed(f"user{i}", "10.9.9.9")
    assert t.retry_after_s("someone-else", "10.9.9.9") > 0
    assert t.retry_after_s("someone-else", "192.0.2.10") == 0


def test_a_name_attacked_from_many_addresses_is_slowed_past_a_larger_count():
    t = LoginThrottle(per_user_anywhere_per_minute=30)
    for i in range(29):
        t.failed("alice", f"10.0.0.{i}")
    assert t.retry_after_s("alice", "192.0.2.10") == 0
    t.failed("alice", "10.0.0.99")
    assert t.retry_after_s("alice", "192.0.2.10") > 0
