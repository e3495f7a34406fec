"""The learning quasi-stiffness model: task → features → joint curves → parameter table.

:class:`QuasiStiffnessModel` composes three pieces, each with its own settings:

* :class:`~controller_core.feature_model.FeatureModel`: GPRs from the task to the target features, with their std;
* :class:`~controller_core.joint_reference.JointReference`: the registered GMR reference of each joint at the task,
  reshaped by KMP through via-points at the predicted features;
* :class:`~controller_core.table_rules.TableRules`: sub-phase windows, line fits, guards, thresholds, damping.

A proposal (curves with std, for people), a table (means only) and an envelope (a grid of tables, batched) take
the same path and differ only in its arguments: features at the tasks, curves at the tasks, a table per task.
"""

from __future__ import annotations

import copy
import hashlib

import numpy as np

from controller_core.envelope import DEFAULT_STEPS, Envelope, NeighbourSteps, build_envelope, validate_axes
from controller_core.feature_model import FeatureModel, incline_points
from controller_core.incline import InclineChange
from controller_core.joint_reference import LANDMARKS, JointReference
from controller_core.proposal import FeaturePrediction, Proposal
from controller_core.published_features import PublishedPoint
from controller_core.quasi_stiffness import SubphaseFit
from controller_core.reference import ReferenceSet, level_curves_at
from controller_core.table import ParameterTable, Provenance, check_table
from controller_core.table_rules import Boundaries, TableRules
from controller_core.task import validate_task


def training_data_sha256(reference: ReferenceSet, published: list[PublishedPoint],
                         ramps: ReferenceSet | None = None) -> str:
    """SHA-256 of everything a model learns from: the source hashes of the reference and ramp sets and the
    published points."""
    h = hashlib.sha256(reference.data_sha256.encode())
    for p in published:
        h.update(repr((p.feature, p.speed_mps, p.incline_deg, p.value, p.se, p.source)).encode())
    if ramps is not None:
        h.update(ramps.data_sha256.encode())
    return h.hexdigest()


class QuasiStiffnessModel:
    """Learning quasi-stiffness model (scikit-learn style: settings here, fitted state with ``_``).

    The default settings were chosen by the leave-one-condition-out evaluation (``quasitune evaluate``), which makes
    that evaluation optimistic for them.

    Args:
        feature_model: the task → features estimator (None: its defaults); fitted as ``feature_model_``.
        joint_reference: the features → curves estimator (None: its defaults); fitted as ``joint_reference_``.
        table_rules: how curves become a table (None: its defaults); kept as ``table_rules_``.
        model_version: a label stored in every table's provenance (``quasitune train`` sets the package version
            and a hash of this code).
    """

    def __init__(self, feature_model: FeatureModel | None = None, joint_reference: JointReference | None = None,
                 table_rules: TableRules | None = None, model_version: str = "unversioned") -> None:
        self.feature_model = feature_model
        self.joint_reference = joint_reference
        self.table_rules = table_rules
        self.model_version = model_version

    def fit(self, reference: ReferenceSet, published: list[PublishedPoint] | None = None,
            ramps: ReferenceSet | None = None) -> QuasiStiffnessModel:
        """Fit every part of the model.

        Args:
            reference: training curves; their tasks must be finite in every task dimension.
            published: extra feature-value points (e.g. published incline features).
            ramps: one person's level and ramp walking, from which the change a slope makes is learned
                (:mod:`controller_core.incline`); None: incline is known from ``published`` alone.
        """
        self.table_rules_ = copy.deepcopy(self.table_rules or TableRules())
        self.table_rules_.check()
        (self.joint_reference or JointReference()).check()   # every setting refused before the data is touched
        if "speed_mps" not in reference.task_names:
            raise ValueError("the reference set needs a 'speed_mps' task column")
        tasks = np.array([[r.task.get("speed_mps", np.nan), r.task.get("incline_deg", 0.0)] for r in reference.records],
                         dtype=float).reshape(-1, 2)
        if not np.all(np.isfinite(tasks)):
            raise ValueError("every training record needs a finite speed (m/s) and incline (deg)")
        self.reference_, self.train_tasks_, self.ramps_ = reference, tasks, ramps
        self.published_ = list(published or [])
        self.data_sha256_ = training_data_sha256(reference, self.published_, ramps)
        self.incline_ = (None if ramps is None
                         else InclineChange().fit(ramps, lambda v: level_curves_at(reference, v)[0]))
        ramp_points = ([] if self.incline_ is None
                       else incline_points(self.incline_, lambda v: level_curves_at(reference, v), reference.phase))
        self.feature_model_ = copy.deepcopy(self.feature_model or FeatureModel()).fit(
            reference, tasks, self.published_, ramp_points)
        self.joint_reference_ = copy.deepcopy(self.joint_reference or JointReference()).fit(
            reference, tasks, self._train_landmarks(), self.incline_)
        return self

    def _train_landmarks(self) -> np.ndarray:
        """The training records' landmark phases, a row per record (what the joint reference is registered on)."""
        return np.array([[f[name][0] for name in LANDMARKS] for f in self.feature_model_.train_features_])

    def with_joint_reference(self, joint_reference: JointReference) -> QuasiStiffnessModel:
        """A copy of this fitted model whose features → curves part is ``joint_reference``, fitted on the same data;
        the feature model is shared, not fitted again (a baseline that differs only in its curves costs one fit)."""
        joint_reference.check()
        other = copy.copy(self)
        other.joint_reference = joint_reference
        other.joint_reference_ = copy.deepcopy(joint_reference).fit(self.reference_, self.train_tasks_,
                                                                    self._train_landmarks(), self.incline_)
        return other

    @property
    def s_query_(self) -> np.ndarray:
        """The phase grid (fraction of the gait cycle) every predicted curve is given on."""
        return self.joint_reference_.s_query_

    def predict_features(self, speed_mps: float, incline_deg: float) -> list[FeaturePrediction]:
        """Every feature at a task (SI values; a timing feature's value is its phase)."""
        return self.feature_model_.predict(speed_mps, incline_deg)

    def predict_features_many(self, tasks: np.ndarray) -> list[list[FeaturePrediction]]:
        """:meth:`predict_features` at many (speed, incline) tasks in one evaluation of the GPRs."""
        return self.feature_model_.predict_many(tasks)

    def propose(self, speed_mps: float, incline_deg: float = 0.0, mass_kg: float = 75.0,
                with_vias: bool = True, swing_inertia_ratio: tuple[float, float] = (1.0, 1.0)) -> Proposal:
        """Predicted features, curves with their std, the fitted lines and the parameter table for a task and patient.

        Args:
            speed_mps: walking speed (m/s), in [0.1, 3].
            incline_deg: incline (deg, + uphill), within ±20.
            mass_kg: patient body mass (kg), 20-200.
            with_vias: False gives the reference through KMP without via-points (a baseline).
            swing_inertia_ratio: the patient's leg's swing inertia about the knee and the ankle over the reference
                leg's: the swing rows' stiffness and damping scale with it
                (:func:`controller_core.table_rules.swing_scale`).

        Raises:
            InvalidTaskError: NaN or out-of-range input.
        """
        validate_task(speed_mps, incline_deg, mass_kg)
        features = self.predict_features(speed_mps, incline_deg)
        curves = self.joint_reference_.curves(np.array([[speed_mps, incline_deg]]), [features], with_std=True,
                                              with_vias=with_vias)[0]
        table, bounds, fits = self._table(speed_mps, incline_deg, mass_kg, features, curves.means, swing_inertia_ratio)
        return Proposal(
            speed_mps=speed_mps, incline_deg=incline_deg, mass_kg=mass_kg, model_version=self.model_version,
            data_sha256=self.data_sha256_, extrapolation=table.provenance.extrapolation, features=features,
            phase=self.s_query_, means=curves.means, stds=curves.stds, boundaries=bounds, fits=fits, table=table,
            violations=check_table(table), vias=curves.vias)

    def propose_table(self, speed_mps: float, incline_deg: float = 0.0, mass_kg: float = 75.0,
                      features: list[FeaturePrediction] | None = None, swing_inertia_ratio: tuple[float, float] = (1.0, 1.0)
                      ) -> tuple[ParameterTable, list[FeaturePrediction]]:
        """The table of :meth:`propose` and the features it came from, without the curves' std.

        Args:
            features: the task's features when already predicted (:meth:`predict_features_many`).
            swing_inertia_ratio: as :meth:`propose`.

        Raises:
            InvalidTaskError: NaN or out-of-range input.
        """
        validate_task(speed_mps, incline_deg, mass_kg)
        if features is None:
            features = self.predict_features(speed_mps, incline_deg)
        curves = self.joint_reference_.curves(np.array([[speed_mps, incline_deg]]), [features], with_std=False)[0]
        return self._table(speed_mps, incline_deg, mass_kg, features, curves.means, swing_inertia_ratio)[0], features

    def propose_envelope(self, speeds_mps: list[float] | np.ndarray, inclines_deg: list[float] | np.ndarray,
                         mass_kg: float = 75.0, nominal: tuple[float, float] = (1.2, 0.0),
                         steps: NeighbourSteps = DEFAULT_STEPS,
                         swing_inertia_ratio: tuple[float, float] = (1.0, 1.0)) -> Envelope:
        """Tables over a speed × incline grid, each the table :meth:`propose_table` gives (computed together: one
        GPR evaluation, the reference trend once per speed, one stacked KMP solve per joint), held to the neighbour
        rule (:mod:`controller_core.envelope`); ``swing_inertia_ratio`` as :meth:`propose`. Check the result with
        :func:`controller_core.envelope.check_envelope`.

        Raises:
            InvalidTaskError: a bad axis (fewer than 2 or more than 15 values, not increasing, out of range) or mass.
        """
        validate_task(1.0, 0.0, mass_kg)
        speeds, inclines = list(np.asarray(speeds_mps, dtype=float)), list(np.asarray(inclines_deg, dtype=float))
        validate_axes(speeds, inclines)
        grid = [(s, g) for s in speeds for g in inclines]
        features = self.predict_features_many(np.array(grid))
        curves = self.joint_reference_.curves(np.array(grid), features, with_std=False)
        tables = {task: (self._table(*task, mass_kg, f, c.means, swing_inertia_ratio)[0], f)
                  for task, f, c in zip(grid, features, curves, strict=True)}

        def node_table(speed: float, incline: float, mass: float) -> tuple[ParameterTable, list[FeaturePrediction]]:
            return tables[(speed, incline)]      # the same table as propose_table(speed, incline, mass) gives

        return build_envelope(node_table, speeds, inclines, mass_kg, self.model_version, self.data_sha256_, nominal,
                              steps)

    def _table(self, speed_mps: float, incline_deg: float, mass_kg: float, features: list[FeaturePrediction],
               means: dict[str, np.ndarray], swing_inertia_ratio: tuple[float, float] = (1.0, 1.0)
               ) -> tuple[ParameterTable, Boundaries, dict[str, list[SubphaseFit]]]:
        """The table through a task's mean curves, stamped with where it came from."""
        provenance = Provenance(model_version=self.model_version, data_sha256=self.data_sha256_, speed_mps=speed_mps,
                                incline_deg=incline_deg, patient_mass_kg=mass_kg,
                                extrapolation=any(f.extrapolation for f in features))
        return self.table_rules_.table(self.s_query_, means, features, mass_kg, provenance, swing_inertia_ratio)
