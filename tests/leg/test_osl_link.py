"""The OSL leg on the device stack: guided calibration finds how its sensors are mounted, a push from the clinic lands
and runs from the next heel strike, and a thermal trip is safe mode with its reason within one status period."""

from __future__ import annotations

import math

import pytest

from controller_core.fsm import GaitState
from controller_core.walking_reference import level_walking_reference
from device_bridge.host import LegState
from device_bridge.osl.bench_sdk import Mounting, SDKRoute
from device_bridge.osl.calibration import joint_direction, joint_zero, loadcell_sign, loadcell_zero
from device_bridge.osl.config import Calibration
from device_bridge.protocol import CalibrationStep, Fault, Mode
from device_bridge.rig import Rig
from device_bridge.sim.simulate import run_walk
from device_bridge.sim.walker import SimWalker
from tests.leg.bench import bench_leg, config, firmware_with, learned_table

DEG = math.pi / 180.0
LEG_FILE = ('thigh = "thigh"\n[geometry]\nthigh_length_m = 0.43\nshank_length_m = 0.43\nforefoot_m = 0.13\n'
            '[knee]\nactuator = "knee"\nencoder = "knee_joint"\ngear_ratio = 41.5\n[ankle]\nactuator = "ankle"\n'
            'gear_ratio = 41.5\n')
MISMOUNTED = Mounting(knee_sign=-1, knee_offset_rad=0.52, ankle_offset_rad=-0.11, fz_sign=-1, fz_offset_N=-140.0,
                      my_sign=-1, my_offset_Nm=2.5)


def _readings(leg, world, held: tuple[float, float], n: int = 5) -> list[dict[str, float]]:
    """The leg's raw sensors, read ``n`` times with the joints held at ``held`` (rad) by hand."""
    world.held = held
    out = []
    for _ in range(n):
        for d in leg.devices:
            d.update()
        out.append({"knee": leg.encoders["knee"].position, "knee_act": leg.actuators["knee"].output_position,
                    "ankle": leg.actuators["ankle"].output_position, "fz": leg.loadcell.fz, "my": leg.loadcell.my})
    return out


def test_calibration_finds_a_reversed_offset_encoder_and_an_offset_reversed_load_cell():
    """The knee's encoder mounted reversed 30° off, the ankle 6° off, the load cell reversed 140 N off: the guided steps
    find each, and the calibrated leg then reads the bench's true angles within 0.5° (and its load within 1 N) while
    walking."""
    walker = SimWalker()
    leg, world = bench_leg(config(1000.0, knee_encoder=True), MISMOUNTED, walker=walker)
    zero = _readings(leg, world, (0.0, 0.0))
    knee0 = joint_zero("knee", [r["knee"] for r in zero])
    ankle0 = joint_zero("ankle", [r["ankle"] for r in zero])
    moving = [r for a in range(0, 31, 5) for r in _readings(leg, world, (a * DEG, a / 3 * DEG), 1)]
    knee = joint_direction("knee", knee0.calibration, [r["knee"] for r in moving], [r["knee_act"] for r in moving])
    ankle = joint_direction("ankle", ankle0.calibration, [r["ankle"] for r in moving], [r["ankle"] for r in moving])
    assert knee.calibration.sign == -1 and "reversed" in knee.measured and ankle.calibration.sign == 1
    assert math.degrees(knee.calibration.zero_rad) == pytest.approx(math.degrees(0.52), abs=0.01)
    unloaded = _readings(leg, world, (0.0, 0.0))
    lc0 = loadcell_zero([r["fz"] for r in unloaded], [r["my"] for r in unloaded])
    world.held = None
    walker.stand(75.0)
    standing = []
    for _ in range(5):
        leg.loadcell.update()
        standing.append(leg.loadcell.fz)
    lc = loadcell_sign(lc0.calibration, standing, 75.0)
    assert lc.calibration.fz_sign == -1 and lc.calibration.fz_zero_N == pytest.approx(-140.0)

    cal = Calibration(knee=knee.calibration, ankle=ankle.calibration, loadcell=lc.calibration)
    calibrated, world2 = bench_leg(config(1000.0, cal, knee_encoder=True), MISMOUNTED)
    ref = level_walking_reference(1.2)
    worst = {"angle_deg": 0.0, "load_N": 0.0}

    class Watch(SDKRoute):
        def step(self, x):
            cmd = super().step(x)
            seen = self.leg.sample()
            worst["angle_deg"] = max(worst["angle_deg"], abs(math.degrees(seen.knee_angle_rad - x.knee_angle_rad)),
                                     abs(math.degrees(seen.ankle_angle_rad - x.ankle_angle_rad)))
            worst["load_N"] = max(worst["load_N"], abs(seen.load_N - x.load_N))
            return cmd

    run_walk(Watch(firmware_with(learned_table()), calibrated, world2), ref, 75.0, 4.0)
    assert worst["angle_deg"] < 0.5 and worst["load_N"] < 1.0, worst


def _rig_with_osl_leg():
    walker = SimWalker()
    rig = Rig()
    leg, world = bench_leg(config(1000.0), walker=walker, clock=rig.clock.monotonic)
    rig.node.leg = leg
    return rig, leg, world, walker


def test_a_push_lands_and_runs_from_the_next_heel_strike():
    """Walking on version 1, version 2 pushed through the host's link: staged, then active at a heel strike (the
    machine's swing → stance flexion on load), and the leg walks on it."""
    rig, _, _, walker = _rig_with_osl_leg()
    with rig:
        table = learned_table()
        walker.stand(75.0)
        rig.advance(0.2)
        rig.link.push(table, version=1)
        walker.start(level_walking_reference(1.2), 75.0)
        rig.advance(3.0)
        firmer = table.model_copy(update={"thresholds": table.thresholds.model_copy(
            update={"fold_knee_rate_deg_per_s": 100.0})})
        rig.link.push(firmer, version=2)
        fw = rig.node.firmware
        assert fw.staged_ is not None and fw.staged_.version == 2 and fw.active_.version == 1
        before = []
        rig.run_until(lambda: before.append(fw.controller_.state_) or fw.active_.version == 2, timeout_s=2.0)
        assert fw.controller_.state_ == GaitState.STANCE_FLEXION
        assert before[-2] in (GaitState.SWING_FLEXION, GaitState.SWING_EXTENSION)
        rig.advance(3.0)
        assert fw.mode_ == Mode.ACTIVE and rig.node.errors == 0 and walker.walking
        # the leg's word on itself reaches the clinic with its status: an OSL, not calibrated (the bench's defaults)
        assert rig.link.status.leg == LegState(False, False, False, "current", 100)


def test_a_thermal_trip_is_safe_mode_with_its_reason_at_the_clinic_within_one_status_period():
    rig, leg, world, walker = _rig_with_osl_leg()
    with rig:
        walker.stand(75.0)
        rig.advance(0.2)
        rig.link.push(learned_table(), version=1)
        walker.start(level_walking_reference(1.2), 75.0)
        rig.advance(2.0)
        leg.actuators["knee"].case_temperature_degC = 84.0
        world.thermal_trip.add("knee")
        tripped = rig.clock.monotonic()
        rig.run_until(lambda: rig.link.status is not None and rig.link.status.mode == Mode.SAFE
                      and bool(rig.link.status.fault_flags & Fault.OVER_TEMPERATURE), timeout_s=1.0)
        assert rig.clock.monotonic() - tripped <= rig.node.firmware.config.status_period_s
        assert rig.link.status.temperature_degC == 84.0
        assert "ThermalLimitException" in rig.node.firmware.hardware_fault_
        rig.advance(1.0)
        assert rig.node.firmware.mode_ == Mode.SAFE and rig.node.errors == 0


def test_the_guided_calibration_prompts_repeats_a_refused_step_and_keeps_its_result(tmp_path):
    """The leg's prompts, answered by poses on the bench (the same mis-mounted sensors): the unloaded step is first
    taken with the patient still on the leg and refused with its reason, then taken again; the result is kept beside
    the leg file and read back with it."""
    from device_bridge.osl.calibration import PROMPTS
    from device_bridge.osl.calibration_guide import guided_calibration
    from device_bridge.osl.config import load_config, save_calibration

    walker = SimWalker()
    leg, world = bench_leg(config(500.0, knee_encoder=True), MISMOUNTED, walker=walker)
    walker.stand(75.0)
    unloaded_asked = []

    def ask(prompt: str) -> None:
        if prompt == PROMPTS[CalibrationStep.JOINT_ZERO]:
            world.held = (0.0, 0.0)
        elif prompt == PROMPTS[CalibrationStep.DIRECTION]:
            world.held = (32 * DEG, 9 * DEG)
        elif prompt == PROMPTS[CalibrationStep.LOADCELL_ZERO]:
            unloaded_asked.append(prompt)
            world.held = None if len(unloaded_asked) == 1 else (0.0, 0.0)   # the first time, still stood on
        elif prompt == PROMPTS[CalibrationStep.LOADCELL_SIGN]:
            world.held = None

    said: list[str] = []
    cal = guided_calibration(leg, 75.0, ask, said.append, samples=20, sleep=lambda s: None)
    assert len(unloaded_asked) == 2 and any(w.startswith("refused: load cell zero") for w in said), said
    assert cal.knee.sign == -1 and cal.loadcell.fz_sign == -1 and cal.knee.calibrated and cal.loadcell.calibrated
    assert math.degrees(cal.knee.zero_rad) == pytest.approx(math.degrees(0.52), abs=0.01)

    path = tmp_path / "leg.toml"
    path.write_text(LEG_FILE)
    save_calibration(path, cal)
    assert load_config(path).calibration == cal


def test_the_clinic_calibrates_an_uncalibrated_osl_leg_through_the_sdk(tmp_path):
    """Mis-mounted and uncalibrated, the leg gives no torque; the host guides the four steps over the link (poses held
    on the bench as the prompts ask), the leg keeps the result beside its file, says so with its status, drives again
    and reads the bench's true angles within 0.5°."""
    from device_bridge.clock import SteppedClock
    from device_bridge.osl.config import calibration_path, load_config, save_calibration
    from device_bridge.protocol import CalibrationAction as A

    clock = SteppedClock(0.001)
    walker = SimWalker()
    leg, world = bench_leg(config(1000.0, knee_encoder=True), MISMOUNTED, walker=walker, clock=clock.monotonic,
                           calibrated_only=True)
    path = tmp_path / "leg.toml"
    path.write_text(LEG_FILE)
    with Rig(leg=leg, clock=clock, calibration=leg.calibration_port(lambda c: save_calibration(path, c), 50)) as rig:
        world.held = (0.0, 0.0)
        rig.advance(0.2)
        assert not leg.drives and world.torques == {"knee": 0.0, "ankle": 0.0}
        ask = rig.link.calibration.command
        assert ask(A.START).outcome == "started"
        assert ask(A.MEASURE, CalibrationStep.JOINT_ZERO).outcome == "accepted"
        world.held = (32 * DEG, 9 * DEG)
        direction = ask(A.MEASURE, CalibrationStep.DIRECTION)
        assert direction.outcome == "accepted" and "reversed" in direction.measured[0].words
        world.held = (0.0, 0.0)
        assert ask(A.MEASURE, CalibrationStep.LOADCELL_ZERO).outcome == "accepted"
        world.held = None
        walker.stand(75.0)
        assert ask(A.MEASURE, CalibrationStep.LOADCELL_SIGN, 75.0).outcome == "accepted"
        assert ask(A.KEEP).outcome == "kept"
        rig.advance(0.15)
        assert rig.link.status.leg == LegState(True, True, True, "current", 100) and leg.drives
        assert load_config(path).calibration == leg.config.calibration and calibration_path(path).exists()
        world.held = (41 * DEG, -6 * DEG)
        x = leg.sample()
        assert math.degrees(x.knee_angle_rad) == pytest.approx(41.0, abs=0.5)
        assert math.degrees(x.ankle_angle_rad) == pytest.approx(-6.0, abs=0.5)
