"""Safe mode entered mid-stride on the bench holds the person (issue 53): the learned table walks, then the leg drops
into safe mode in mid-stance or mid-swing (as a lost link or the prosthetist's button would put it); from then on no
fall, and over the ten strides after the one it was entered in, the knee bears weight at no more than 20° of flexion.
A damper alone let the loaded knee fold to 40–65° stride after stride."""

from __future__ import annotations

import math

import numpy as np
import pytest

from controller_core.fsm import GaitState, ImpedanceSchedule, SensorSample, StateMachineController, TorqueCommand
from controller_core.gait_metrics import heel_strikes
from controller_core.safe_mode import SafeModeController
from controller_core.units import G_MPS2
from controller_core.walking_reference import level_walking_reference, sloped_walking_reference
from device_bridge.sim.simulate import fall_mask, run_walk

MASS_KG = 75.0
HELD_S = 0.03          # weight borne this long, not a toe's touch in swing


class EntersSafeMode:
    """The table's state machine until it first enters ``state`` after ``after_s``, then safe mode (the firmware's
    switch, on the bench)."""

    def __init__(self, table, state: GaitState, after_s: float) -> None:
        self.table = StateMachineController(ImpedanceSchedule.from_table(table))
        self.safe, self.state, self.after_s = SafeModeController(), state, after_s
        self.entered_s: float | None = None
        self.transitions_ = self.guard_transitions_ = 0

    def stand(self) -> None:
        self.table.stand()

    def reset(self) -> None:
        self.table.reset()
        self.safe.reset()
        self.entered_s = None

    def step(self, x: SensorSample) -> TorqueCommand:
        if self.entered_s is None:
            cmd = self.table.step(x)
            if x.time_s < self.after_s or cmd.state != self.state:
                return cmd
            self.entered_s = x.time_s
            self.safe.reset()
        return self.safe.step(x)


@pytest.mark.parametrize(("incline_deg", "entered_in"), [(0.0, GaitState.STANCE_EXTENSION),
                                                         (6.0, GaitState.STANCE_EXTENSION),
                                                         (-6.0, GaitState.SWING_FLEXION)])
def test_safe_mode_entered_mid_stride_holds_the_person(model, incline_deg, entered_in):
    ref = level_walking_reference(1.2) if incline_deg == 0 else sloped_walking_reference(1.2, incline_deg)
    leg = EntersSafeMode(model.propose(1.2, incline_deg, MASS_KG).table, entered_in, after_s=3.0)
    log = run_walk(leg, ref, MASS_KG, seconds=15.5)
    c, dt, weight = log.channels, log.timestep_s, MASS_KG * G_MPS2
    assert leg.entered_s is not None and leg.entered_s < 4.5
    after = c["time_s"] >= leg.entered_s
    falls = fall_mask(c, weight) & after
    assert not falls.any(), f"fell {np.count_nonzero(np.diff(falls.astype(int)) == 1)} times after entering safe mode"
    strikes = heel_strikes(c["contact_N"], 0.02 * weight, round(0.15 / dt))
    strikes = strikes[c["time_s"][strikes] > leg.entered_s]
    assert strikes.shape[0] >= 11, f"{strikes.shape[0]} heel strikes after entering safe mode: the person stopped"
    ten = slice(strikes[0], strikes[10])                       # the ten strides after the one it was entered in
    over = (c["load_N"] > 0.5 * weight).astype(float)
    held = np.convolve(over, np.ones(round(HELD_S / dt)), mode="full")[:over.shape[0]] >= round(HELD_S / dt)
    loaded_knee_deg = np.degrees(c["knee_angle_rad"][ten][held[ten]])
    assert loaded_knee_deg.size > 0 and loaded_knee_deg.max() <= 20.0, \
        f"the knee bore weight at {loaded_knee_deg.max():.1f}° of flexion"
    assert math.isfinite(float(c["hip_height_error_m"][after].min()))
