"""The one controller factory of the bench."""

from __future__ import annotations

import pytest

from controller_core.adaptive import AdaptiveController
from controller_core.fsm import StateMachineController
from controller_core.fsmic import fsmic_table
from controller_core.table import SafetyLimitError
from device_bridge.bench.controllers import CONTROLLERS, default_envelope, make_controller


def test_each_name_gives_its_controller_with_its_rows(model):
    table = model.propose(1.0, 0.0, 70.0).table
    given = make_controller("table", 70.0, table=table)
    assert isinstance(given, StateMachineController)
    assert given.schedule == make_controller("quasi-stiffness", 70.0, model, (1.0, 0.0)).schedule
    fsmic = make_controller("fsmic", 70.0)
    assert fsmic.schedule == make_controller("table", 70.0, table=fsmic_table(70.0)).schedule
    assert fsmic.schedule != given.schedule
    assert isinstance(make_controller("adaptive", 70.0, model, envelope=default_envelope(model, 70.0)),
                      AdaptiveController)
    assert set(CONTROLLERS) == {"table", "quasi-stiffness", "fsmic", "adaptive"}


@pytest.mark.parametrize(("name", "kwargs", "message"), [
    ("pendulum", {}, "unknown controller"),
    ("table", {}, "needs a table"),
    ("quasi-stiffness", {}, "needs a trained model"),
    ("adaptive", {}, "needs a trained model"),
])
def test_what_a_controller_needs_is_asked_for_by_name(name, kwargs, message):
    with pytest.raises(ValueError, match=message):
        make_controller(name, 75.0, **kwargs)


def test_an_unsafe_table_is_refused_as_the_device_refuses_it(model):
    table = model.propose(1.2, 0.0, 75.0).table
    row = table.rows[0]
    bad = table.model_copy(update={"rows": [row.model_copy(update={"k_Nm_per_rad": 50.0}), *table.rows[1:]]})
    with pytest.raises(SafetyLimitError):
        make_controller("table", 75.0, table=bad)


def test_only_the_benchs_table_controller_converts_a_table_without_its_limits():
    """``--skip-limits`` is for bench studies: no product path (device, firmware, API, pushes) converts unchecked."""
    from pathlib import Path

    root = Path(__file__).resolve().parents[3]
    users = sorted(str(p.relative_to(root)) for folder in ("backend", "device_bridge", "controller_core")
                   for p in (root / folder).rglob("*.py") if "from_table_unchecked" in p.read_text())
    assert users == ["controller_core/fsm.py", "device_bridge/bench/controllers.py"]
