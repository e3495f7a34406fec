"""Loader for the standard phase-indexed table format (CSV or Parquet).

Public locomotion datasets (Reznick 2021, Camargo 2021, Embry 2018, ...) are commonly converted to a long
table with **one row per stride × phase point**. QuasiTune reads that format so a lab can train on its
own data or on a public set with ``quasitune train --data PATH``.

Columns
-------
* phase: ``phase`` in [0, 1] or ``phase_pct`` in [0, 100]; 0 = ipsilateral heel strike.
* stride identity (optional): ``subject`` and/or ``stride``; rows with the same task, subject and stride
  form one stride. Without them each task is a single curve.
* ``condition`` (optional): the walking condition a stride belongs to. With it, the strides of one condition (and
  subject) form one record whose task values are their mean: for overground walking at a self-selected speed,
  where every stride has a speed of its own. Without it, each unique combination of task values is a record.
* task columns with units in the name: ``speed_m_s`` (or ``speed_mps``), ``incline_deg``; any other
  ``*_deg`` / ``*_m_s`` task column can be named in ``task_columns``.
* joint columns with units in the name: ``knee_angle_deg`` | ``knee_angle_rad``,
  ``ankle_angle_deg`` | ``ankle_angle_rad``, ``knee_moment_Nm_per_kg``, ``ankle_moment_Nm_per_kg``; optionally
  ``hip_angle_deg`` | ``hip_angle_rad`` (kept as channel ``hip_angle``; the simulated bench drives its socket with it).
  Signs as everywhere in QuasiTune: knee flexion +, ankle dorsiflexion +, internal moment positive in
  the direction of the positive angle (``moment_sign=-1`` converts extensor/plantarflexor-positive data).

Each record's curves are the mean and SD over its strides resampled to a 101-point grid, each phase point
averaged over the strides that have a value there: force-plate data often miss the first samples after heel
strike. A stride missing more than :data:`MAX_MISSING_FRACTION` of a channel is left out, and a phase point
that fewer than half the strides cover is an error. Malformed input raises ``ValueError`` with the column and the
reason.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from controller_core.reference import JOINTS, ReferenceRecord, ReferenceSet, data_dir, sha256_of

PHASE_POINTS = 101
MAX_MISSING_FRACTION = 0.1   # of a stride's samples in any one channel
_SPEED_ALIASES = ("speed_m_s", "speed_mps")
_ANGLE_UNITS = {"deg": np.pi / 180.0, "rad": 1.0}
_MOMENT_UNITS = {"Nm_per_kg": 1.0}

if TYPE_CHECKING:
    import pandas as pd


def _pandas():
    """pandas, imported when a table is first read or written (a process that never reads one starts without it)."""
    import pandas

    return pandas


def _find_channel(df: pd.DataFrame, joint: str, quantity: str) -> tuple[str, float]:
    """Return (column, factor to SI) for a joint channel, refusing unknown units."""
    units = _ANGLE_UNITS if quantity == "angle" else _MOMENT_UNITS
    prefix = f"{joint}_{quantity}_"
    present = [c for c in df.columns if c.startswith(prefix) and not c.endswith("_sd")]
    known = [c for c in present if c[len(prefix):] in units]
    unknown = [c for c in present if c[len(prefix):] not in units]
    if unknown and not known:
        raise ValueError(
            f"column {unknown[0]!r}: unknown unit {unknown[0][len(prefix):]!r} "
            f"(expected one of {sorted(units)})"
        )
    if not known:
        raise ValueError(f"missing column for {joint} {quantity}: expected one of "
                         f"{[prefix + u for u in units]}")
    if len(known) > 1:
        raise ValueError(f"ambiguous {joint} {quantity}: several columns {known}")
    col = known[0]
    return col, units[col[len(prefix):]]


def _task_columns(df: pd.DataFrame, task_columns: tuple[str, ...] | None) -> list[str]:
    if task_columns is not None:
        missing = [c for c in task_columns if c not in df.columns]
        if missing:
            raise ValueError(f"task column(s) {missing} not in the table")
        return list(task_columns)
    cols = [c for c in _SPEED_ALIASES if c in df.columns][:1]
    if "incline_deg" in df.columns:
        cols.append("incline_deg")
    if not cols:
        raise ValueError("no task column: expected 'speed_m_s' (or 'speed_mps') and/or 'incline_deg'")
    return cols


def _canonical_task_name(col: str) -> str:
    return "speed_mps" if col in _SPEED_ALIASES else col


def read_phase_table(path: str | Path) -> pd.DataFrame:
    """Read a CSV or Parquet file into a DataFrame (format chosen by the file ending)."""
    p = Path(path)
    if not p.exists():
        raise ValueError(f"data file {str(p)!r} does not exist")
    if p.suffix.lower() in (".parquet", ".pq"):
        return _pandas().read_parquet(p)
    if p.suffix.lower() in (".csv", ".txt"):
        return _pandas().read_csv(p)
    raise ValueError(f"data file {p.name!r}: unknown format (use .csv or .parquet)")


def phase_table_to_reference(
    df: pd.DataFrame,
    task_columns: tuple[str, ...] | None = None,
    moment_sign: float = 1.0,
    label: str = "user",
    data_sha256: str = "",
) -> ReferenceSet:
    """Convert a standard-format table to a :class:`ReferenceSet` (one record per task).

    Args:
        df: the table (see the module docstring for the columns).
        task_columns: task columns to condition on; default: speed and/or incline if present.
        moment_sign: +1 for QuasiTune's convention, -1 for extensor/plantarflexor-positive data.
        label: dataset label stored in each record.
        data_sha256: hash of the source file, for provenance.
    """
    if moment_sign not in (1.0, -1.0):
        raise ValueError("moment_sign must be +1 or -1")
    if "phase" in df.columns:
        phase = df["phase"].to_numpy(dtype=float)
    elif "phase_pct" in df.columns:
        phase = df["phase_pct"].to_numpy(dtype=float) / 100.0
    else:
        raise ValueError("missing phase column: expected 'phase' (0-1) or 'phase_pct' (0-100)")
    if not np.all(np.isfinite(phase)) or phase.min() < 0.0 or phase.max() > 1.0 + 1e-9:
        raise ValueError("phase values must be finite and within [0, 1] ('phase') or [0, 100] ('phase_pct')")
    tcols = _task_columns(df, task_columns)
    task_vals = df[tcols].to_numpy(dtype=float)
    if not np.all(np.isfinite(task_vals)):
        bad = tcols[int(np.argwhere(~np.isfinite(task_vals))[0, 1])]
        raise ValueError(f"task column {bad!r} has missing or non-numeric values")
    for c in tcols:
        if c in _SPEED_ALIASES and (df[c] <= 0).any():
            raise ValueError(f"task column {c!r}: speeds must be > 0 m/s")
    channels = {}
    for joint in JOINTS:
        for quantity in ("angle", "moment"):
            col, factor = _find_channel(df, joint, quantity)
            sign = moment_sign if quantity == "moment" else 1.0
            channels[f"{joint}_{quantity}"] = df[col].to_numpy(dtype=float) * factor * sign
    if any(c.startswith("hip_angle_") for c in df.columns):
        col, factor = _find_channel(df, "hip", "angle")
        channels["hip_angle"] = df[col].to_numpy(dtype=float) * factor
    stride_keys = [c for c in ("subject", "stride") if c in df.columns]
    by_condition = "condition" in df.columns
    work = _pandas().DataFrame({"_phase": phase})
    for i in range(len(tcols)):
        work[f"_t{i}"] = np.round(task_vals[:, i], 9)
    for c in stride_keys + (["condition"] if by_condition else []):
        work[c] = df[c].to_numpy()
    for name, values in channels.items():
        work[name] = values
    tkeys = [f"_t{i}" for i in range(len(tcols))]
    keys = ([c for c in ("subject", "condition") if c in df.columns]) if by_condition else tkeys
    if by_condition and not stride_keys[-1:] == ["stride"]:
        raise ValueError("a table with a 'condition' column needs a 'stride' column: a condition's strides each "
                         "carry their own task values")
    records: list[ReferenceRecord] = []
    skipped = 0
    for key, group in work.groupby(keys, sort=True):
        key = key if isinstance(key, tuple) else (key,)
        strides = group.groupby(stride_keys, sort=True) if stride_keys else [(None, group)]
        where = dict(zip(keys if by_condition else tcols, key, strict=True))
        curves, tasks = _resampled_strides(strides, list(channels), tkeys, where)
        skipped += len(strides) - len(tasks) if stride_keys else 1 - len(tasks)
        if not tasks:
            continue
        mean, sd = _stride_statistics(curves, where)
        task = {_canonical_task_name(c): float(v) for c, v in zip(tcols, np.mean(tasks, axis=0), strict=True)}
        name = ",".join(f"{k}={v:g}" for k, v in task.items())
        if by_condition:
            name = "/".join(str(where[k]) for k in keys) + f" ({name})"
        records.append(ReferenceRecord(name=f"{label}/{name}", dataset=label, task=task,
                                       phase=np.linspace(0.0, 1.0, PHASE_POINTS), mean=mean, sd=sd,
                                       n=len(tasks)))
    if not records:
        raise ValueError("no complete stride in the table (every stride had missing values or < 10 points)")
    task_names = tuple(_canonical_task_name(c) for c in tcols)
    return ReferenceSet(
        records=tuple(records), task_names=task_names, data_sha256=data_sha256,
        provenance={"source": label, "skipped_incomplete_strides": skipped, "task_columns": tcols},
    )


def _resampled_strides(strides, names: list[str], tkeys: list[str], where: dict
                       ) -> tuple[dict[str, list[np.ndarray]], list[np.ndarray]]:
    """Each usable stride's channels on the 101-point grid (NaN where the stride has no sample) and its task."""
    grid = np.linspace(0.0, 1.0, PHASE_POINTS)
    curves: dict[str, list[np.ndarray]] = {k: [] for k in names}
    tasks: list[np.ndarray] = []
    for _, stride in strides:
        stride = stride.sort_values("_phase")
        values = stride[names].to_numpy(dtype=float)
        finite = np.isfinite(values)
        if len(stride) < 10 or (1.0 - finite.mean(axis=0)).max() > MAX_MISSING_FRACTION:
            continue
        sp = stride["_phase"].to_numpy()
        if np.any(np.diff(sp) <= 0):
            raise ValueError(f"{where}: repeated phase values within one stride (add 'subject'/'stride' columns)")
        for j, name in enumerate(names):
            ok = finite[:, j]
            curve = np.interp(grid, sp[ok], values[ok, j])
            # a grid point whose neighbouring samples include a missing one stays missing
            nearest = np.clip(np.searchsorted(sp, grid), 1, sp.size - 1)
            curve[~(ok[nearest] & ok[nearest - 1])] = np.nan
            curves[name].append(curve)
        tasks.append(stride[tkeys].to_numpy(dtype=float).mean(axis=0))
    return curves, tasks


def _stride_statistics(curves: dict[str, list[np.ndarray]], where: dict
                       ) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    """Mean and SD (ddof 1) over strides per phase point, each over the strides that have it."""
    mean, sd = {}, {}
    for name, rows in curves.items():
        stack = np.array(rows)
        count = np.isfinite(stack).sum(axis=0)
        if count.min() < max(1, stack.shape[0] / 2):
            raise ValueError(f"{where}: {name} is missing at phase {np.argmin(count)} % in more than half the strides")
        with np.errstate(invalid="ignore"):
            mean[name] = np.nanmean(stack, axis=0)
            sd[name] = np.nanstd(stack, axis=0, ddof=1) if stack.shape[0] > 1 else np.full(stack.shape[1], np.nan)
    return mean, sd


def load_phase_table(path: str | Path, task_columns: tuple[str, ...] | None = None,
                     moment_sign: float = 1.0) -> ReferenceSet:
    """Read a standard-format CSV/Parquet file and convert it (see :func:`phase_table_to_reference`)."""
    p = Path(path)
    df = read_phase_table(p)
    return phase_table_to_reference(df, task_columns=task_columns, moment_sign=moment_sign,
                                    label=p.stem, data_sha256=sha256_of(p))


def reference_to_phase_table(ref: ReferenceSet) -> pd.DataFrame:
    """Write a reference set's mean curves in the standard format (one 'stride' per record)."""
    rows = []
    for i, rec in enumerate(ref.records):
        frame = _pandas().DataFrame({"subject": rec.dataset, "stride": i, "phase": rec.phase})
        for name in ref.task_names:
            col = "speed_m_s" if name == "speed_mps" else name
            frame[col] = rec.task.get(name, np.nan)
        for joint in JOINTS:
            frame[f"{joint}_angle_deg"] = np.rad2deg(rec.mean[f"{joint}_angle"])
            frame[f"{joint}_moment_Nm_per_kg"] = rec.mean[f"{joint}_moment"]
        rows.append(frame)
    return _pandas().concat(rows, ignore_index=True)


SHIPPED_RAMPS_CSV = "vielemeyer2025_ref01_ramps.csv"


def load_shipped_ramps() -> ReferenceSet:
    """The shipped ramp curves (Vielemeyer 2025, one participant: level walking and ±10° ramps), one record per
    condition with its strides' mean speed (see ``controller_core/data/README.md``)."""
    return load_phase_table(data_dir() / SHIPPED_RAMPS_CSV)
