"""Passwords and tokens: what is stored never logs anyone in, and a bad hash never verifies."""

from __future__ import annotations

import pytest

from backend.security import (
    MAX_PASSWORD_LENGTH,
    MIN_PASSWORD_LENGTH,
    SCRYPT_N,
    burn_password_check,
    check_password_policy,
    hash_password,
    new_token,
    set_hash_cost,
    token_digest,
    verify_password,
)
from backend.settings import Settings
from tests.conftest import TEST_HASH_COST


@pytest.fixture
def production_cost():
    """The production hash cost for one test (the run's is lowered: tests/conftest.py)."""
    set_hash_cost(Settings.model_fields["password_hash_cost"].default)
    yield
    set_hash_cost(TEST_HASH_COST)


def test_a_hash_verifies_its_password_only_and_is_salted(production_cost):
    stored = hash_password("correct horse battery")
    assert SCRYPT_N == 16384 and stored.startswith("scrypt$16384$8$1$") and "correct" not in stored
    assert verify_password("correct horse battery", stored)
    assert not verify_password("correct horse batterz", stored)
    assert hash_password("correct horse battery") != stored          # a fresh salt every time


@pytest.mark.parametrize("stored", ["", "scrypt$1$2", "bcrypt$16384$8$1$AAAA$AAAA", "scrypt$x$8$1$AAAA$AAAA",
                                    "scrypt$16384$8$1$not base64!$AAAA"])
def test_a_malformed_or_foreign_hash_never_verifies(stored):
    assert verify_password("anything at all", stored) is False


def test_the_policy_names_the_bound_it_refuses():
    check_password_policy("kw9#tq-2", "dana")
    with pytest.raises(ValueError, match=f"at least {MIN_PASSWORD_LENGTH}"):
        check_password_policy("kw9#tq-", "dana")
    with pytest.raises(ValueError, match=f"at most {MAX_PASSWORD_LENGTH}"):
        check_password_policy("kw9#tq-2" * (MAX_PASSWORD_LENGTH // 8 + 1), "dana")


@pytest.mark.parametrize("password", ["password1", "iloveyou", "Password123", "qwertyuiop", "football", "xxxxxxxx"])
def test_a_common_or_trivially_guessed_password_is_refused(password):
    with pytest.raises(ValueError, match="most common passwords"):
        check_password_policy(password, "dana")


def test_the_user_name_is_not_a_password():
    with pytest.raises(ValueError, match="not be the user name"):
        check_password_policy("Prosthetist", "prosthetist")
    check_password_policy("correct-horse-battery", "prosthetist")


def test_tokens_are_fresh_and_only_their_digest_is_kept():
    a, b = new_token(), new_token()
    assert a != b and len(a) >= 40
    assert token_digest(a) == token_digest(a) != token_digest(b)
    assert len(token_digest(a)) == 64 and a not in token_digest(a)
    assert token_digest("\udcff")        # a lone surrogate from a hostile header still digests, never raises


def test_an_unknown_user_check_does_the_same_work_and_verifies_nothing():
    assert burn_password_check("whatever password") is None


def test_a_hash_made_at_another_cost_verifies_by_its_own(production_cost):
    strong = hash_password("correct horse battery")
    set_hash_cost(16)
    assert verify_password("correct horse battery", strong)          # the stored n, not the process's
    cheap = hash_password("correct horse battery")
    assert cheap.startswith("scrypt$16$") and verify_password("correct horse battery", cheap)


@pytest.mark.parametrize("bad", [0, 1, 3, 1000, 2**21])
def test_a_hash_cost_that_is_not_a_power_of_two_in_range_is_refused(bad):
    with pytest.raises(ValueError, match="power of two"):
        set_hash_cost(bad)
    with pytest.raises(ValueError, match="password_hash_cost"):
        Settings(password_hash_cost=bad)
