"""Benchmark: fit time of the default model, propose() latency on a warm model, cached vs uncached KMP.

A command that prints figures (``quasitune bench``), not a timed test.
"""

from __future__ import annotations

import time

import numpy as np

from controller_core.model_io import train_default


def _timings(fn, repeats: int) -> np.ndarray:
    for _ in range(min(50, repeats)):  # warm-up
        fn()
    out = np.empty(repeats)
    for i in range(repeats):
        t0 = time.perf_counter()
        fn()
        out[i] = time.perf_counter() - t0
    return out


def run_bench(repeats: int = 2000) -> dict[str, float]:
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

    prop = _timings(propose, repeats) * 1e3
    feats = model.predict_features(1.3, 2.0)
    vias = model.via_points("knee", model.joints_["knee"].kmp.mu_ref_, feats)
    kmp = model.joints_["knee"].kmp
    cached = _timings(lambda: kmp.predict(vias), repeats) * 1e3
    uncached = _timings(lambda: kmp.predict_uncached(vias), max(50, repeats // 10)) * 1e3
    return {
        "fit_default_model_s": round(fit_s, 3),
        "propose_median_ms": round(float(np.median(prop)), 4),
        "propose_p99_ms": round(float(np.percentile(prop, 99)), 4),
        "kmp_cached_median_ms": round(float(np.median(cached)), 4),
        "kmp_cached_p99_ms": round(float(np.percentile(cached, 99)), 4),
        "kmp_uncached_median_ms": round(float(np.median(uncached)), 4),
        "kmp_uncached_p99_ms": round(float(np.percentile(uncached, 99)), 4),
        "kmp_speedup_ratio": round(float(np.median(uncached) / np.median(cached)), 2),
        "repeats": repeats,
    }
