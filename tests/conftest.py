"""Shared fixtures. The default-model cache goes to a per-session temporary directory."""

from __future__ import annotations

import os
import tempfile

import pytest

os.environ.setdefault("QUASITUNE_CACHE_DIR", tempfile.mkdtemp(prefix="quasitune-test-cache-"))


@pytest.fixture(scope="session")
def reference():
    from controller_core.reference import load_shipped_reference

    return load_shipped_reference()


@pytest.fixture(scope="session")
def model():
    from controller_core import load_default_model

    return load_default_model()


@pytest.fixture
def api(tmp_path, model):
    """In-process API on a temporary database, one signed-in user per role (see tests/api_helpers.py)."""
    from api_helpers import make_api

    api, client = make_api(tmp_path, lambda: model)
    with client:
        yield api
