"""The tasks the model knows: the range its training data cover plus a stated margin.

A little outside the data, a proposal is flagged as extrapolated (each feature's hull test, :mod:`controller_core.hull`)
and still useful: the GPRs' linear trend carries it on with a growing SD. Beyond the margin the SD no longer says
anything about the patient, so a request there is refused unless the prosthetist asks to extrapolate and writes why
(the backend audits the reason and marks the version everywhere it is shown).

Margins, where the uncertainty stops meaning anything:

* **speed ±0.35 m/s.** The level data cover 0.84–1.95 m/s. Along level walking the median, over the model's feature
  GPRs, of the predicted SD in units of the spread of that feature's training values reaches one half (its ±2 SD
  band is then as wide as everything the training data contain: the prediction no longer places the feature anywhere
  within them) at about 0.45 and 2.30 m/s, 0.39 and 0.35 m/s beyond the data; the smaller, 0.35 m/s, is the margin
  on both sides (:func:`speed_uncertainty_ratio` recomputes the figure, and a test holds the statement to it).
* **incline ±5°.** What the model knows of slopes is one person's change between level and ±10° ramps, extended
  linearly beyond them (:mod:`controller_core.incline`), with an SD of the population's between-subject SD scaled by
  |incline|/10. At 15° the change is half again the largest one measured and its SD one and a half people wide:
  further out a straight extension of one person's ramps says nothing about a patient's.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:   # the model imports nothing from here
    from controller_core.model import QuasiStiffnessModel

SPEED_MARGIN_MPS = 0.35
INCLINE_MARGIN_DEG = 5.0


@dataclass(frozen=True)
class KnownRange:
    """The training data's task range (m/s, deg) and the margin beyond it the model may extrapolate to unasked."""

    data_speed_mps: tuple[float, float]
    data_incline_deg: tuple[float, float]
    speed_margin_mps: float = SPEED_MARGIN_MPS
    incline_margin_deg: float = INCLINE_MARGIN_DEG

    @property
    def speed_mps(self) -> tuple[float, float]:
        """The speeds (m/s) a request may ask for without extrapolating on purpose."""
        return (round(self.data_speed_mps[0] - self.speed_margin_mps, 2),
                round(self.data_speed_mps[1] + self.speed_margin_mps, 2))

    @property
    def incline_deg(self) -> tuple[float, float]:
        """The inclines (deg) a request may ask for without extrapolating on purpose."""
        return (round(self.data_incline_deg[0] - self.incline_margin_deg, 1),
                round(self.data_incline_deg[1] + self.incline_margin_deg, 1))

    def beyond(self, speed_mps: float, incline_deg: float) -> str | None:
        """Why a task lies beyond the margin, in words; None inside it."""
        (s0, s1), (g0, g1) = self.speed_mps, self.incline_deg
        out = []
        if not s0 <= speed_mps <= s1:
            out.append(f"{speed_mps:g} m/s")
        if not g0 <= incline_deg <= g1:
            out.append(f"{incline_deg:+g}°")
        if not out:
            return None
        return (f"{' and '.join(out)} lies beyond what the model knows: its walking data cover "
                f"{self.data_speed_mps[0]:.2f}–{self.data_speed_mps[1]:.2f} m/s and {self.data_incline_deg[0]:+g}° to "
                f"{self.data_incline_deg[1]:+g}°, and it predicts up to {self.speed_margin_mps:g} m/s and "
                f"{self.incline_margin_deg:g}° beyond them ({s0:.2f}–{s1:.2f} m/s, {g0:+g}° to {g1:+g}°); further out "
                "its uncertainty no longer says anything about the patient")

    def to_json(self) -> dict:
        return {"data_speed_mps": [round(v, 3) for v in self.data_speed_mps],
                "data_incline_deg": list(self.data_incline_deg),
                "speed_margin_mps": self.speed_margin_mps, "incline_margin_deg": self.incline_margin_deg,
                "speed_mps": list(self.speed_mps), "incline_deg": list(self.incline_deg)}


def known_range(model: QuasiStiffnessModel) -> KnownRange:
    """The fitted model's data range (level speeds; the measured ramps' inclines, 0 without ramps) and the margins."""
    speeds = model.joint_reference_.level_speeds_
    inclines = [0.0, *(r.task.get("incline_deg", 0.0) for r in model.ramps_.records)] if model.ramps_ is not None else [0.0]
    return KnownRange(data_speed_mps=(float(np.min(speeds)), float(np.max(speeds))),
                      data_incline_deg=(float(min(inclines)), float(max(inclines))))


def speed_uncertainty_ratio(model: QuasiStiffnessModel, speeds_mps: np.ndarray) -> np.ndarray:
    """The median over feature GPRs of the predicted SD in units of the spread of that feature's training values,
    along level walking at each speed (the figure the speed margin is chosen from)."""
    bank = model.feature_model_.bank_
    tasks = np.column_stack([np.asarray(speeds_mps, dtype=float), np.zeros(len(speeds_mps))])
    _mean, sd, _out = bank.predict_many(tasks)
    return np.median(sd / bank.y_std[None], axis=1)
