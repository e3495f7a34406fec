"""Envelope benchmark (``python -m benchmarks envelope``): a 25-node envelope proposed on a warm model, one blend at a
task (what the leg does once per stride), one adaptive control tick, envelope pushes over a clean virtual bus, and
envelope pushes through a faulty bus (mixed envelopes must be 0), and the device's view of the envelope (``as_run``:
rounding, checks and CRC)."""

from __future__ import annotations

import time

import numpy as np

from benchmarks.model import timings
from controller_core.model_io import load_default_model

SPEEDS = np.linspace(0.6, 1.6, 5)
INCLINES = np.linspace(-10.0, 10.0, 5)


def _stats(values: np.ndarray, unit: str, name: str) -> dict[str, float]:
    return {f"{name}_median_{unit}": round(float(np.median(values)), 4),
            f"{name}_p99_{unit}": round(float(np.percentile(values, 99)), 4)}


def _adaptive_tick_us(blender, repeats: int) -> dict[str, float]:
    """One control tick of the adaptive controller (state machine + estimator) over a replayed bench walk."""
    from controller_core.adaptive import AdaptiveController
    from controller_core.fsm import GaitState
    from controller_core.task_estimator import TaskEstimator
    from controller_core.walking_reference import level_walking_reference
    from device_bridge.sim.bench_trajectory import plan_bench_trajectory
    from device_bridge.sim.plant import SimulatedLeg

    ref = level_walking_reference(1.2)
    leg = SimulatedLeg()
    traj = plan_bench_trajectory(ref, leg.geometry, 75.0, repeats / 1000.0 + 0.1, leg.timestep_s)
    x = leg.reset(traj, float(ref.knee_angle_rad[85]), float(ref.ankle_angle_rad[85]))
    ctrl = AdaptiveController(blender, TaskEstimator(leg.geometry.thigh_m, leg.geometry.shank_m), (1.2, 0.0))
    samples = []
    for _ in range(repeats):            # record what the leg would feel, then time the controller on it alone
        samples.append(x)
        cmd = ctrl.step(x)
        x = leg.step(cmd.knee_torque_Nm, cmd.ankle_torque_Nm)
    ctrl.reset(GaitState.SWING_EXTENSION)
    out = np.empty(len(samples))
    for i, s in enumerate(samples):
        t0 = time.perf_counter()
        ctrl.step(s)
        out[i] = time.perf_counter() - t0
    return _stats(out[100:] * 1e6, "us", "adaptive_tick")


def _pushes(envelopes, pushes: int) -> np.ndarray:
    import can

    from device_bridge.device_node import DeviceNode
    from device_bridge.host import DeviceLink

    channel = f"bench-envelope-{time.monotonic_ns()}"
    node = DeviceNode(can.Bus(interface="virtual", channel=channel)).start()
    link = DeviceLink(can.Bus(interface="virtual", channel=channel)).start()
    try:
        return np.array([link.push(envelopes[i % len(envelopes)], version=i + 1).elapsed_ms
                         for i in range(pushes)])
    finally:
        link.close()
        node.close()


def run(repeats: int = 50, pushes: int = 100, trials: int = 500) -> dict:
    """Timings (ms, µs) and the faulty-bus outcome counts."""
    from controller_core.envelope_blend import EnvelopeBlender
    from device_bridge.soak import soak

    model = load_default_model()
    for _ in range(3):
        model.propose_envelope(SPEEDS, INCLINES, 75.0)
    envelope_ms = timings(lambda: model.propose_envelope(SPEEDS, INCLINES, 75.0), repeats) * 1e3
    rng = np.random.default_rng(0)
    tasks = iter(np.column_stack([rng.uniform(0.5, 1.7, 10**6), rng.uniform(-11, 11, 10**6)]).tolist())
    propose_ms = timings(lambda: model.propose(*next(tasks), 75.0), 500) * 1e3
    env = model.propose_envelope(SPEEDS, INCLINES, 75.0)
    blender = EnvelopeBlender(env.speeds_mps, env.inclines_deg, env.tables())
    blend_us = timings(lambda: blender.at(*next(tasks)), 20000) * 1e6
    from device_bridge.as_run import as_run
    as_run_ms = timings(lambda: as_run(env), repeats) * 1e3     # what every store, approval and push asks of it
    envelopes = [model.propose_envelope(SPEEDS, INCLINES, m) for m in (60.0, 75.0, 90.0)]
    push_ms = _pushes(envelopes, pushes)
    faulty = soak(envelopes, trials, drop=0.1, corrupt=0.02, reorder=0.05, seed=0, push_timeout_s=4.0)
    return {
        "envelope_nodes": len(env.nodes),
        **_stats(envelope_ms, "ms", "propose_envelope"),
        **_stats(propose_ms, "ms", "propose_one_table_for_scale"),
        **_stats(blend_us, "us", "blend"),
        **_stats(as_run_ms, "ms", "as_run"),
        **_adaptive_tick_us(blender, 5000),
        **_stats(push_ms, "ms", "envelope_push_clean_virtual_bus"),
        "envelope_pushes": pushes,
        "faulty_bus": {k: faulty[k] for k in ("trials", "committed", "kept_old", "committed_unconfirmed", "mixed",
                                              "crc_mismatch", "median_push_ms", "p99_push_ms", "faults")},
    }
