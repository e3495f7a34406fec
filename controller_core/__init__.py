"""QuasiTune numerics: reference data, features, GPR, GMM/GMR, KMP, quasi-stiffness fit, parameter table.

Pure numerics: no web, database or CAN code. Typical use::

    from controller_core import load_default_model
    model = load_default_model()
    proposal = model.propose(speed_mps=1.25, incline_deg=0.0, mass_kg=75.0)
    proposal.to_dict()["table"]
"""

from controller_core.model import QuasiStiffnessModel
from controller_core.model_io import load_default_model, load_model, save_model
from controller_core.proposal import Proposal
from controller_core.table import ParameterTable, SafetyLimitError, SafetyLimits, assert_safe, check_table
from controller_core.task import InvalidTaskError, validate_task

__all__ = [
    "InvalidTaskError", "ParameterTable", "Proposal", "QuasiStiffnessModel", "SafetyLimitError",
    "SafetyLimits", "assert_safe", "check_table", "load_default_model", "load_model", "save_model", "validate_task",
]
