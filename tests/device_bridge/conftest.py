"""Shared by the device-link tests: two real tables."""

from __future__ import annotations

import pytest

from controller_core.table import ParameterTable


@pytest.fixture(scope="session")
def tables(model) -> list[ParameterTable]:
    """The default model's tables at 1.0 and 1.5 m/s (75 kg, level)."""
    return [model.propose(s, 0.0, 75.0).table for s in (1.0, 1.5)]
