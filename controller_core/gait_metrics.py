"""Gait metrics of a recorded walk: heel strikes, stride-averaged curves on the phase grid, RMSE, events.

Pure numpy on arrays sampled at a fixed period; used for simulated walks and for monitored sessions alike.
Units follow the inputs (SI in, SI out) except where a name says otherwise.
"""

from __future__ import annotations

import itertools

import numpy as np

from controller_core.walking_reference import WalkingReference

PHASE_GRID = np.linspace(0.0, 1.0, 101)
GAIT_CHANNELS = ("knee_angle_deg", "ankle_angle_deg", "knee_moment_Nm_per_kg", "ankle_moment_Nm_per_kg")


def rising_edges(signal: np.ndarray, threshold: float, min_low_samples: int = 1) -> np.ndarray:
    """Indices where ``signal`` goes above ``threshold`` after at least ``min_low_samples`` samples at or below it."""
    above = np.asarray(signal) > threshold
    idx = []
    low_run = 0
    for i, a in enumerate(above):
        if a:
            if low_run >= min_low_samples and i > 0:
                idx.append(i)
            low_run = 0
        else:
            low_run += 1
    return np.asarray(idx, dtype=int)


def heel_strikes(contact_N: np.ndarray, threshold_N: float, min_swing_samples: int) -> np.ndarray:
    """Sample indices of heel strikes: foot contact force rising above ``threshold_N`` after a swing of at
    least ``min_swing_samples`` samples without contact."""
    return rising_edges(contact_N, threshold_N, min_swing_samples)


def stride_curves(signal: np.ndarray, strikes: np.ndarray, grid: np.ndarray = PHASE_GRID) -> np.ndarray:
    """(strides, len(grid)) array: each stride between consecutive strikes resampled on the phase grid."""
    signal = np.asarray(signal, dtype=float)
    out = []
    for a, b in itertools.pairwise(strikes):
        seg = signal[a: b + 1]
        s = np.linspace(0.0, 1.0, seg.shape[0])
        out.append(np.interp(grid, s, seg))
    return np.asarray(out).reshape(-1, grid.shape[0])


def rmse(a: np.ndarray, b: np.ndarray) -> float:
    """Root-mean-square difference of two equally shaped arrays."""
    d = np.asarray(a, dtype=float) - np.asarray(b, dtype=float)
    return float(np.sqrt(np.mean(d * d)))


def episodes(flag: np.ndarray, min_gap_samples: int = 1) -> int:
    """Number of separate runs of True in ``flag`` (runs closer than ``min_gap_samples`` count as one)."""
    starts = rising_edges(np.asarray(flag, dtype=float), 0.5, min_gap_samples).shape[0]
    return int(starts + (1 if len(flag) and flag[0] else 0))


def state_entry_delays(states: np.ndarray, state: int, events: np.ndarray, lead_samples: int = 0) -> np.ndarray:
    """Samples from each event to the machine's next entry into ``state`` (float array, one per event).

    An entry counts for an event if it lies at or after ``event − lead_samples`` (an entry just before the
    event gives a negative delay) and before the next event (or the end of the record); an event with no such
    entry gives NaN. ``states`` is the state per sample; an entry is a sample in ``state`` whose predecessor is
    not (the first sample never counts).
    """
    states = np.asarray(states)
    events = np.asarray(events, dtype=int)
    if lead_samples < 0:
        raise ValueError(f"lead_samples must be >= 0, got {lead_samples}")
    entries = np.flatnonzero((states[1:] == state) & (states[:-1] != state)) + 1
    ends = np.append(events[1:], states.shape[0])
    delays = np.full(events.shape[0], np.nan)
    for i, (event, end) in enumerate(zip(events, ends, strict=True)):
        j = int(np.searchsorted(entries, event - lead_samples))
        if j < entries.shape[0] and entries[j] < end:
            delays[i] = entries[j] - event
    return delays


def gait_channels(knee_angle_rad: np.ndarray, ankle_angle_rad: np.ndarray, knee_torque_Nm: np.ndarray,
                  ankle_torque_Nm: np.ndarray, mass_kg: float) -> dict[str, np.ndarray]:
    """Recorded joint signals (SI) in the units they are scored in: :data:`GAIT_CHANNELS` (deg, N·m/kg)."""
    return {"knee_angle_deg": np.degrees(knee_angle_rad), "ankle_angle_deg": np.degrees(ankle_angle_rad),
            "knee_moment_Nm_per_kg": np.asarray(knee_torque_Nm) / mass_kg,
            "ankle_moment_Nm_per_kg": np.asarray(ankle_torque_Nm) / mass_kg}


def reference_curves(reference: WalkingReference, grid: np.ndarray = PHASE_GRID) -> dict[str, np.ndarray]:
    """The reference's :data:`GAIT_CHANNELS` on the phase grid (deg, N·m/kg)."""
    s = reference.phase
    return {"knee_angle_deg": np.degrees(np.interp(grid, s, reference.knee_angle_rad)),
            "ankle_angle_deg": np.degrees(np.interp(grid, s, reference.ankle_angle_rad)),
            "knee_moment_Nm_per_kg": np.interp(grid, s, reference.knee_moment_Nm_per_kg),
            "ankle_moment_Nm_per_kg": np.interp(grid, s, reference.ankle_moment_Nm_per_kg)}


def rmse_key(channel: str) -> str:
    """``knee_angle_deg`` → ``knee_angle_rmse_deg``; ``knee_moment_Nm_per_kg`` → ``knee_moment_rmse_Nm_per_kg``."""
    return channel.replace("_deg", "_rmse_deg").replace("_Nm_per_kg", "_rmse_Nm_per_kg")


def per_stride_key(channel: str) -> str:
    """``knee_angle_deg`` → ``knee_angle_per_stride_rmse_deg``: the mean over strides of each stride's RMSE."""
    return rmse_key(channel).replace("_rmse_", "_per_stride_rmse_")


def ci95_key(key: str) -> str:
    """The key of a value's 95 % interval: ``knee_angle_rmse_deg`` → ``knee_angle_rmse_ci95_deg`` (the unit stays
    last)."""
    for unit in ("_deg", "_Nm_per_kg"):
        if key.endswith(unit):
            return key[: -len(unit)] + "_ci95" + unit
    raise ValueError(f"{key!r} does not end in a unit this module knows (_deg, _Nm_per_kg)")


def difference_keys(channel: str) -> tuple[str, str, str]:
    """Keys of a two-walk comparison of a channel's RMSE: the difference, its 95 % interval, the verdict
    (``knee_angle_deg`` → ``knee_angle_rmse_difference_deg``, ``knee_angle_rmse_difference_ci95_deg``,
    ``knee_angle_verdict``)."""
    key = rmse_key(channel).replace("_rmse_", "_rmse_difference_")
    return key, ci95_key(key), channel.removesuffix("_deg").removesuffix("_Nm_per_kg") + "_verdict"


def channel_strides(measured: dict[str, np.ndarray], strikes: np.ndarray) -> dict[str, np.ndarray]:
    """Each measured channel cut into strides on the phase grid (:func:`stride_curves`); empty with fewer than
    two strikes."""
    if strikes.shape[0] < 2:
        return {}
    return {name: stride_curves(signal, strikes) for name, signal in measured.items()}


def strided_errors(strided: dict[str, np.ndarray], channels: tuple[str, ...] | list[str],
                   reference: dict[str, np.ndarray], rng: np.random.Generator | None = None,
                   per_stride: bool = False) -> tuple[dict[str, np.ndarray], dict[str, object]]:
    """Stride-averaged curves of ``strided`` (:func:`channel_strides`) and their RMSE against the reference,
    keyed by :func:`rmse_key`; a channel without strides gets None. With ``rng``, each RMSE also gets its 95 %
    interval over strides under :func:`ci95_key` (:func:`bootstrap_rmse`; None with fewer than two strides).

    With ``per_stride``, each channel also gets the mean of its strides' own RMSEs under :func:`per_stride_key`.
    The two differ when strides scatter: errors of opposite sign on different strides cancel in the
    stride-averaged curve, not in the per-stride mean, which is what the leg does on a typical stride.
    """
    means = {name: curves.mean(axis=0) for name, curves in strided.items()}
    errors: dict[str, object] = {}
    for name in channels:
        key = rmse_key(name)
        errors[key] = rmse(means[name], reference[name]) if name in means else None
        if per_stride:
            errors[per_stride_key(name)] = (float(np.mean([rmse(stride, reference[name]) for stride in strided[name]]))
                                            if name in strided else None)
        if rng is not None:
            errors[ci95_key(key)] = (list(percentile_interval(bootstrap_rmse(strided[name], reference[name], rng=rng)))
                                     if name in strided and strided[name].shape[0] >= 2 else None)
    return means, errors


def bootstrap_rmse(strides: np.ndarray, reference: np.ndarray, n_boot: int = 2000,
                   rng: np.random.Generator | None = None) -> np.ndarray:
    """RMSE against ``reference`` of the stride-averaged curve, for ``n_boot`` resamples of the strides.

    Each resample draws as many strides as were walked, with replacement (rows of ``strides``, shape
    (strides, grid)); its mean curve is scored like the walk itself. The spread of the returned (n_boot,) values
    is how much the walk's RMSE depends on which strides happened to be walked. Strides are treated as
    exchangeable, which holds for a walk that has settled into a cycle; strides that alternate (a limp) would
    need a block bootstrap.

    Raises:
        ValueError: fewer than two strides, or shapes that do not match.
    """
    strides = np.asarray(strides, dtype=float)
    reference = np.asarray(reference, dtype=float)
    if strides.ndim != 2 or strides.shape[0] < 2:
        raise ValueError(f"need at least two strides as rows, got an array of shape {strides.shape}")
    if strides.shape[1] != reference.shape[0]:
        raise ValueError(f"strides have {strides.shape[1]} grid points, the reference {reference.shape[0]}")
    n = strides.shape[0]
    rng = np.random.default_rng(0) if rng is None else rng
    counts = rng.multinomial(n, np.full(n, 1.0 / n), size=n_boot)   # how often each stride is drawn
    d = counts @ strides / n - reference
    return np.sqrt(np.mean(d * d, axis=1))


def bootstrap_means(values: np.ndarray, n_boot: int = 2000, rng: np.random.Generator | None = None) -> np.ndarray:
    """The mean of ``values`` (one per stride) for ``n_boot`` resamples of them with replacement."""
    values = np.asarray(values, dtype=float)
    rng = np.random.default_rng(0) if rng is None else rng
    counts = rng.multinomial(values.size, np.full(values.size, 1.0 / values.size), size=n_boot)
    return counts @ values / values.size


def verdict(interval: tuple[float, float]) -> str:
    """``A lower`` / ``B lower`` when an interval of A − B excludes zero, else ``not resolved``."""
    lo, hi = interval
    return "A lower" if hi < 0.0 else "B lower" if lo > 0.0 else "not resolved"


def percentile_interval(samples: np.ndarray, level: float = 0.95) -> tuple[float, float]:
    """Central ``level`` interval of bootstrap samples (percentile method)."""
    if not 0.0 < level < 1.0:
        raise ValueError(f"level must be within (0, 1), got {level!r}")
    lo, hi = np.percentile(np.asarray(samples, dtype=float), [50.0 * (1.0 - level), 50.0 * (1.0 + level)])
    return float(lo), float(hi)


def rmse_difference(strides_a: np.ndarray, strides_b: np.ndarray, reference: np.ndarray, level: float = 0.95,
                    n_boot: int = 2000, seed: int = 0) -> dict[str, object]:
    """How much walk A's stride-averaged RMSE exceeds walk B's, with a bootstrap interval.

    The two walks are independent, so their strides are resampled independently (:func:`bootstrap_rmse`);
    ``verdict`` is ``"A lower"`` or ``"B lower"`` when the interval excludes zero, else ``"not resolved"``:
    the difference is within what the stride-to-stride variation of the two walks allows.

    Returns:
        ``difference`` (RMSE_A − RMSE_B, in the curves' unit), ``interval`` (lo, hi) at ``level``, ``verdict``.
    """
    rng = np.random.default_rng(seed)
    a = bootstrap_rmse(strides_a, reference, n_boot, rng)
    b = bootstrap_rmse(strides_b, reference, n_boot, rng)
    diff = rmse(np.asarray(strides_a, dtype=float).mean(axis=0), reference) - \
        rmse(np.asarray(strides_b, dtype=float).mean(axis=0), reference)
    interval = percentile_interval(a - b, level)
    return {"difference": diff, "interval": interval, "verdict": verdict(interval)}
