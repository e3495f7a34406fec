"""The guided calibration's four steps in order, over a leg's raw readings: what both the leg's own prompts
(:mod:`device_bridge.osl.calibration_guide`) and the clinic's device page (:mod:`device_bridge.remote_calibration`)
drive, so the steps, their order and their checks exist once.

A step begins (:meth:`CalibrationSession.begin`), takes one raw reading per control period
(:meth:`CalibrationSession.feed`: the leg's sensors as they read, before any calibration) until it has its samples,
and then gives its result: accepted (:class:`~device_bridge.osl.calibration.StepResult` per subject) or refused
(:class:`~device_bridge.osl.calibration.CalibrationRefusedError`). Measuring a step again drops the later steps'
results (the direction is read from the zero, the load cell's sign from its zero); :meth:`CalibrationSession.result`
gives the calibration once all four are accepted.
"""

from __future__ import annotations

import statistics
from collections.abc import Mapping

from device_bridge.osl.calibration import (
    CalibrationRefusedError,
    StepResult,
    joint_direction,
    joint_zero,
    loadcell_sign,
    loadcell_zero,
)
from device_bridge.osl.config import Calibration, JointCalibration, LoadcellCalibration
from device_bridge.protocol import CalibrationRefusal, CalibrationStep

RAW_READINGS = ("knee", "knee_actuator", "ankle", "ankle_actuator", "fz", "my")   # rad, rad, rad, rad, N, N·m
DEFAULT_SAMPLES = 100    # 0.2 s at 500 Hz


class CalibrationSession:
    """One guided calibration (module docstring).

    Args:
        samples: raw readings per step.

    Attributes:
        step_: the step being measured (None between steps).
        results_: each accepted step's results (per subject).
    """

    def __init__(self, samples: int = DEFAULT_SAMPLES) -> None:
        if samples < 2:
            raise ValueError(f"a calibration step needs at least 2 readings, got {samples}")
        self.samples = samples
        self.step_: CalibrationStep | None = None
        self.results_: dict[CalibrationStep, tuple[StepResult, ...]] = {}
        self._body_mass_kg = float("nan")
        self._readings: dict[str, list[float]] = {}
        self._zero_pose: dict[str, float] = {}

    def begin(self, step: CalibrationStep, body_mass_kg: float = float("nan")) -> None:
        """Start measuring ``step`` (``body_mass_kg``: the patient's, for the load cell's sign). Refused
        (OUT_OF_ORDER) before the steps it needs; the results of this step and the later ones are dropped."""
        step = CalibrationStep(step)
        needs = {CalibrationStep.DIRECTION: CalibrationStep.JOINT_ZERO,
                 CalibrationStep.LOADCELL_SIGN: CalibrationStep.LOADCELL_ZERO}.get(step)
        if needs is not None and needs not in self.results_:
            raise CalibrationRefusedError(CalibrationRefusal.OUT_OF_ORDER, "leg")
        for later in [s for s in self.results_ if s >= step]:
            del self.results_[later]
        self.step_, self._body_mass_kg = step, body_mass_kg
        self._readings = {k: [] for k in RAW_READINGS}

    def feed(self, raw: Mapping[str, float]) -> tuple[StepResult, ...] | None:
        """One raw reading (:data:`RAW_READINGS`; a missing one counts as not a number); the step's results once it
        has its samples (then the step is done), else None. Raises CalibrationRefusedError for a refused step (also
        done: begin it again)."""
        if self.step_ is None:
            return None
        for k in RAW_READINGS:
            self._readings[k].append(float(raw.get(k, float("nan"))))
        if len(self._readings["knee"]) < self.samples:
            return None
        step, self.step_ = self.step_, None
        results = self._compute(step, self._readings)
        self.results_[step] = results
        if step == CalibrationStep.JOINT_ZERO:
            self._zero_pose = {k: statistics.fmean(v) for k, v in self._readings.items()}
        return results

    def _compute(self, step: CalibrationStep, r: dict[str, list[float]]) -> tuple[StepResult, ...]:
        if step == CalibrationStep.JOINT_ZERO:
            return joint_zero("knee", r["knee"]), joint_zero("ankle", r["ankle"])
        if step == CalibrationStep.DIRECTION:
            mean, zero = statistics.fmean, self._zero_pose
            return tuple(joint_direction(j, self._joint(j), [zero[j], mean(r[j])],
                                         [zero[f"{j}_actuator"], mean(r[f"{j}_actuator"])]) for j in ("knee", "ankle"))
        if step == CalibrationStep.LOADCELL_ZERO:
            return (loadcell_zero(r["fz"], r["my"]),)
        return (loadcell_sign(self._loadcell(), r["fz"], self._body_mass_kg),)

    def _joint(self, joint: str) -> JointCalibration:
        found = next(x for x in self.results_[CalibrationStep.JOINT_ZERO] if x.subject == joint).calibration
        assert isinstance(found, JointCalibration)
        return found

    def _loadcell(self) -> LoadcellCalibration:
        found = self.results_[CalibrationStep.LOADCELL_ZERO][0].calibration
        assert isinstance(found, LoadcellCalibration)
        return found

    def result(self) -> Calibration:
        """The calibration the four accepted steps give (refused INCOMPLETE before)."""
        if any(s not in self.results_ for s in CalibrationStep):
            raise CalibrationRefusedError(CalibrationRefusal.INCOMPLETE, "leg")
        knee, ankle = self.results_[CalibrationStep.DIRECTION]
        loadcell = self.results_[CalibrationStep.LOADCELL_SIGN][0]
        return Calibration(knee=knee.calibration, ankle=ankle.calibration, loadcell=loadcell.calibration)
