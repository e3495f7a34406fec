"""The routers' tests run on both databases: ``api`` here is the in-process app on SQLite and on PostgreSQL."""

from __future__ import annotations

import pytest


@pytest.fixture
def api(tmp_path, model, api_storage):
    """In-process API on a database of its own (each kind in turn), one signed-in user per role."""
    from tests.helpers.api import make_api

    api, client = make_api(tmp_path, lambda: model, **api_storage)
    with client:
        yield api
