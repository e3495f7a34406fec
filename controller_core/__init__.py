"""QuasiTune numerics: reference data, features, GPR, GMM/GMR, KMP, quasi-stiffness fit, parameter table.

Pure numerics: no web, database or CAN code. Typical use::

    from controller_core import load_default_model
    model = load_default_model()
    proposal = model.propose(speed_mps=1.25, incline_deg=0.0, mass_kg=75.0)
    proposal.to_dict()["table"]

The names below are imported on first use (PEP 562), so that the leg's own modules (``controller_core.fsm``,
``table``, ``adaptive`` …) load without the model's scikit-learn and SciPy: the leg's computer installs neither.
"""

from __future__ import annotations

import importlib
from typing import Any

_WHERE = {
    "QuasiStiffnessModel": "model", "load_default_model": "model_io", "load_model": "model_io", "save_model": "model_io",
    "Proposal": "proposal", "ParameterTable": "table", "SafetyLimitError": "table", "SafetyLimits": "table",
    "assert_safe": "table", "check_table": "table", "InvalidTaskError": "task", "validate_task": "task",
}
__all__ = sorted(_WHERE)


def __getattr__(name: str) -> Any:
    if name not in _WHERE:
        raise AttributeError(f"module 'controller_core' has no attribute {name!r}")
    return getattr(importlib.import_module(f"controller_core.{_WHERE[name]}"), name)
