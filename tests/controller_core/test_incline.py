"""The change a slope makes, learned from one person's ramp and level walking."""

from __future__ import annotations

import numpy as np
import pytest

from controller_core.incline import InclineChange
from controller_core.phase_table import load_shipped_ramps
from controller_core.reference import ReferenceRecord, ReferenceSet, level_curves_at

PHASE = np.linspace(0.0, 1.0, 101)
CHANNELS = ("knee_angle", "knee_moment", "ankle_angle", "ankle_moment")


def _record(name: str, speed: float, incline: float, shift: dict[str, np.ndarray], n: int = 6) -> ReferenceRecord:
    base = {c: np.sin(2 * np.pi * PHASE + i) for i, c in enumerate(CHANNELS)}
    return ReferenceRecord(name=name, dataset="synthetic", task={"speed_mps": speed, "incline_deg": incline},
                           phase=PHASE, mean={c: base[c] + shift.get(c, 0.0) for c in CHANNELS},
                           sd={c: np.full(101, 0.1) for c in CHANNELS}, n=n)


def test_a_known_change_is_recovered_with_the_speed_effect_taken_out():
    # synthetic (test-only) curves: the population's curves rise by 0.2 per m/s; the person walked level at
    # 1.3 m/s, up a +10° ramp at 1.3 m/s (a bump in early stance) and down a -10° ramp at 1.1 m/s (an offset)
    bump = 0.5 * np.exp(-((PHASE - 0.1) / 0.05) ** 2)
    population = lambda v: {c: 0.2 * v * np.ones(101) for c in CHANNELS}     # noqa: E731
    ramps = ReferenceSet(records=(
        _record("level", 1.3, 0.0, {c: 0.2 * 1.3 for c in CHANNELS}),
        _record("up", 1.3, 10.0, {"knee_angle": 0.2 * 1.3 + bump, **{c: 0.2 * 1.3 for c in CHANNELS[1:]}}),
        _record("down", 1.1, -10.0, {c: 0.2 * 1.1 - 0.3 for c in CHANNELS}),
    ))
    change = InclineChange().fit(ramps, population)
    assert np.allclose(change.predict(10.0)["knee_angle"], bump)             # the bump, nothing else
    assert np.allclose(change.predict(5.0)["knee_angle"], bump / 2)          # linear towards level
    assert np.allclose(change.predict(-10.0)["ankle_angle"], -0.3)           # the speed difference taken out
    assert np.allclose(change.predict(0.0)["knee_angle"], 0.0)
    assert change.covers(-10.0) and change.covers(7.5) and not change.covers(12.0)
    sd = {c: np.full(101, 2.0) for c in CHANNELS}
    assert np.allclose(change.std(5.0, sd)["knee_angle"], 1.0)               # half the spread halfway up
    assert np.allclose(change.std(15.0, sd)["knee_angle"], 3.0)              # and more beyond the data


def test_a_side_without_a_ramp_adds_nothing_and_is_not_covered():
    ramps = ReferenceSet(records=(_record("level", 1.3, 0.0, {}), _record("up", 1.3, 10.0, {"knee_angle": 0.4})))
    change = InclineChange().fit(ramps, lambda v: {c: np.zeros(101) for c in CHANNELS})
    assert np.allclose(change.predict(-5.0)["knee_angle"], 0.0) and not change.covers(-5.0)
    sd = {c: np.full(101, 2.0) for c in CHANNELS}
    assert np.allclose(change.std(-5.0, sd)["knee_angle"], 2.0)              # the full spread: nothing measured


def test_level_walking_alone_or_a_missing_curve_is_refused():
    level = _record("level", 1.3, 0.0, {})
    with pytest.raises(ValueError, match="level walking and at least one slope"):
        InclineChange().fit(ReferenceSet(records=(level,)), lambda v: {})
    with pytest.raises(ValueError, match="no hip_angle curve"):
        InclineChange(channels=("hip_angle",)).fit(
            ReferenceSet(records=(level, _record("up", 1.3, 10.0, {}))), lambda v: {})


def test_the_shipped_ramps_give_the_changes_people_make_on_slopes(reference):
    change = InclineChange().fit(load_shipped_ramps(), lambda v: level_curves_at(reference, v)[0])
    up, down = change.predict(10.0), change.predict(-10.0)
    assert np.degrees(up["knee_angle"][0]) > 20                  # the knee lands flexed going up (~27°)
    assert np.degrees(up["ankle_angle"][20:35]).mean() > 5       # the ankle dorsiflexes on the slope in stance
    assert down["knee_moment"][5:25].min() < -0.4                # twice the extensor moment going down
    assert up["ankle_moment"][40:55].min() < -0.15               # a bigger push-off going up
