"""Model benchmark (``python -m benchmarks model``): fit time of the default model, propose() latency on a warm
model, cached vs uncached KMP, one state-machine step, and two machine figures (``machine_*``) that let a latency
measured on one machine be read against another's: one small numpy call, and one product of the size a KMP update
multiplies by (``propose()`` is mostly the first kind)."""

from __future__ import annotations

import time

import numpy as np

from controller_core.model_io import train_default


def timings(fn, repeats: int) -> np.ndarray:
    for _ in range(min(50, repeats)):  # warm-up
        fn()
    out = np.empty(repeats)
    for i in range(repeats):
        t0 = time.perf_counter()
        fn()
        out[i] = time.perf_counter() - t0
    return out


def run(repeats: int = 2000) -> dict[str, float]:
    """Return timings in milliseconds (medians and p99) and the KMP speed-up ratio."""
    t0 = time.perf_counter()
    model = train_default()
    fit_s = time.perf_counter() - t0
    rng = np.random.default_rng(0)
    tasks = np.column_stack([rng.uniform(0.8, 2.0, 64), rng.uniform(-8, 8, 64)])
    it = iter(range(10**9))

    def propose() -> None:
        sp, inc = tasks[next(it) % len(tasks)]
        model.propose(float(sp), float(inc), 75.0)

    prop = timings(propose, repeats) * 1e3
    feats = model.predict_features(1.3, 2.0)
    kmp = model.joint_reference_.joints_["knee"].kmp
    vias = model.joint_reference_.via_points("knee", kmp.mu_ref_, feats)
    cached = timings(lambda: kmp.predict(vias), repeats) * 1e3
    uncached = timings(lambda: kmp.predict_uncached(vias), max(50, repeats // 10)) * 1e3
    return {
        "fit_default_model_s": round(fit_s, 3),
        "propose_median_ms": round(float(np.median(prop)), 4),
        "propose_p99_ms": round(float(np.percentile(prop, 99)), 4),
        "kmp_cached_median_ms": round(float(np.median(cached)), 4),
        "kmp_cached_p99_ms": round(float(np.percentile(cached, 99)), 4),
        "kmp_uncached_median_ms": round(float(np.median(uncached)), 4),
        "kmp_uncached_p99_ms": round(float(np.percentile(uncached, 99)), 4),
        "kmp_speedup_ratio": round(float(np.median(uncached) / np.median(cached)), 2),
        **fsm_step_timings(model.propose(1.2, 0.0, 75.0).table, repeats * 10),
        **machine_timings(repeats * 10),
        "repeats": repeats,
    }


def fsm_step_timings(table, repeats: int = 20000) -> dict[str, float]:
    """Median and p99 time (µs) of one state-machine step over a replayed reference stride."""
    from controller_core.fsm import ImpedanceSchedule, SensorSample, StateMachineController
    from controller_core.walking_reference import level_walking_reference

    ref = level_walking_reference(1.2)
    n = ref.phase.shape[0] - 1
    dt = ref.stride_time_s / n
    weight = 75.0 * 9.81
    count = repeats + 50
    samples = [SensorSample(time_s=i * dt, knee_angle_rad=float(ref.knee_angle_rad[i % n]), knee_velocity_rad_s=0.0,
                            ankle_angle_rad=float(ref.ankle_angle_rad[i % n]), ankle_velocity_rad_s=0.0,
                            load_N=float(ref.vgrf_bw[i % n] * weight),
                            ankle_moment_Nm=float(ref.ankle_moment_Nm_per_kg[i % n] * 75.0)) for i in range(count)]
    ctrl = StateMachineController(ImpedanceSchedule.from_table(table))
    it = iter(samples)

    def step() -> None:
        ctrl.step(next(it))

    t = timings(step, repeats) * 1e6
    return {"fsm_step_median_us": round(float(np.median(t)), 3), "fsm_step_p99_us": round(float(np.percentile(t, 99)), 3)}


def machine_timings(repeats: int = 20000) -> dict[str, float]:
    """Median time (µs) of one small numpy call (two 10-element arrays added) and of a 100 × 100 by 100 × 10
    product: how fast this machine is at what ``propose()`` does most, to compare latencies across machines."""
    a, b = np.ones(10), np.ones(10)
    A, C = np.random.default_rng(0).normal(size=(100, 100)), np.random.default_rng(1).normal(size=(100, 10))
    small = timings(lambda: np.add(a, b), repeats) * 1e6
    product = timings(lambda: A @ C, repeats) * 1e6
    return {"machine_numpy_call_median_us": round(float(np.median(small)), 3),
            "machine_matmul_100x100x10_median_us": round(float(np.median(product)), 3)}
