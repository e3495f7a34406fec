"""A second of telemetry as one compact value: the session samples stored one row per second of walking.

100 Hz telemetry is the largest thing QuasiTune stores; a row per sample costs a row header, a key and an index entry
per sample on every database (about 200 bytes on PostgreSQL). Here the samples of one second (sequence numbers
100·s … 100·s + 99) are one ``bytes`` value:

* format 1: a version byte, then zlib (level 6) of the columns one after the other (:data:`COLUMNS` order), each as
  ``n`` little-endian float64 values whose bytes are shuffled (all first bytes, then all second bytes, …: the filter
  HDF5 and Blosc use, which lets zlib find the slowly changing exponents and high mantissa bytes of smooth signals);
* a missing value (SQL's NULL before) is NaN: the leg's telemetry is decoded from fixed-point CAN signals and is always
  finite, so NaN never stands for a measurement; integers (sequence, mode, state) are exact in float64;
* ``adaptive_mode`` is stored as its index in :data:`ADAPTIVE_MODES`.

Reading back gives exactly the tuples written (every float bit for bit). What is refused, with the column and the
reason: a row of the wrong length, a missing value where the leg always sends one, a non-finite number, an unknown
adaptive mode, a sequence number outside the second.
"""

from __future__ import annotations

import math
import struct
import zlib
from collections.abc import Iterable, Sequence

import numpy as np

FORMAT = 1
SAMPLES_PER_ROW = 100           # the leg's 100 Hz: one row per second of walking
COLUMNS = ("seq", "t_s", "mode", "fsm_state", "knee_angle_rad", "knee_velocity_rad_s", "knee_torque_Nm",
           "ankle_angle_rad", "ankle_velocity_rad_s", "ankle_torque_Nm", "load_N", "ankle_moment_Nm",
           "estimated_speed_mps", "estimated_incline_deg", "running_speed_mps", "running_incline_deg",
           "adaptive_mode")
INTEGER_COLUMNS = frozenset({"seq", "mode", "fsm_state"})
NULLABLE_COLUMNS = frozenset({"fsm_state", "estimated_speed_mps", "estimated_incline_deg", "running_speed_mps",
                              "running_incline_deg", "adaptive_mode"})
ADAPTIVE_MODES = ("nominal", "partial", "adaptive", "clamped", "unknown")
_HEADER = struct.Struct("<BH")   # format, sample count


def second_of(seq: int) -> int:
    """The row (second of walking) a sequence number belongs to."""
    return seq // SAMPLES_PER_ROW


def _encode(column: str, value: object) -> float:
    if value is None:
        if column not in NULLABLE_COLUMNS:
            raise ValueError(f"sample {column} is missing; the leg always sends it")
        return math.nan
    if column == "adaptive_mode":
        if value not in ADAPTIVE_MODES:
            raise ValueError(f"sample adaptive_mode {value!r} is not one of {', '.join(ADAPTIVE_MODES)}")
        return float(ADAPTIVE_MODES.index(value))
    if isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating):
        raise ValueError(f"sample {column} must be a number, got {value!r}")
    number = float(value)
    if not math.isfinite(number):
        raise ValueError(f"sample {column} must be finite, got {value!r}")
    if column in INTEGER_COLUMNS and number != int(number):
        raise ValueError(f"sample {column} must be a whole number, got {value!r}")
    return number


def pack(rows: Sequence[tuple]) -> bytes:
    """The rows (tuples in :data:`COLUMNS` order, one second's, in any order, no sequence number twice) as one value,
    in sequence order."""
    if not 1 <= len(rows) <= SAMPLES_PER_ROW:
        raise ValueError(f"a row of samples holds 1 to {SAMPLES_PER_ROW} samples, got {len(rows)}")
    for row in rows:
        if len(row) != len(COLUMNS):
            raise ValueError(f"a sample has {len(COLUMNS)} values ({', '.join(COLUMNS)}), got {len(row)}")
    values = np.array([[_encode(c, v) for c, v in zip(COLUMNS, row, strict=True)] for row in rows], dtype="<f8")
    values = values[np.argsort(values[:, 0], kind="stable")]
    seqs = values[:, 0]
    if seqs[0] < 0 or second_of(int(seqs[0])) != second_of(int(seqs[-1])):
        raise ValueError(f"samples {int(seqs[0])}..{int(seqs[-1])} are not one second's (sequence numbers "
                         f"{SAMPLES_PER_ROW}·s to {SAMPLES_PER_ROW}·s + {SAMPLES_PER_ROW - 1})")
    if np.any(np.diff(seqs) == 0):
        raise ValueError("a sequence number appears twice in one second's samples")
    columns = np.ascontiguousarray(values.T)                        # column after column
    shuffled = columns.view(np.uint8).reshape(len(COLUMNS), len(rows), 8).transpose(0, 2, 1)
    return _HEADER.pack(FORMAT, len(rows)) + zlib.compress(np.ascontiguousarray(shuffled).tobytes(), 6)


def unpack(blob: bytes) -> list[tuple]:
    """The tuples :func:`pack` was given, in sequence order, exactly."""
    version, n = _HEADER.unpack_from(blob)
    if version != FORMAT:
        raise ValueError(f"samples stored in format {version}; this QuasiTune reads format {FORMAT}")
    raw = np.frombuffer(zlib.decompress(blob[_HEADER.size:]), dtype=np.uint8)
    columns = raw.reshape(len(COLUMNS), 8, n).transpose(0, 2, 1).copy().view("<f8").reshape(len(COLUMNS), n)
    out: list[list[object]] = [[None] * len(COLUMNS) for _ in range(n)]
    for j, column in enumerate(COLUMNS):
        for i, x in enumerate(columns[j].tolist()):
            if x != x:   # NaN: missing
                continue
            out[i][j] = (ADAPTIVE_MODES[int(x)] if column == "adaptive_mode"
                         else int(x) if column in INTEGER_COLUMNS else x)
    return [tuple(r) for r in out]


def merge(stored: Iterable[tuple], arriving: Iterable[tuple]) -> tuple[list[tuple], int]:
    """One second's samples after a batch arrives: what was stored stays as it was (a retried batch changes
    nothing), the new sequence numbers are added; (the rows in sequence order, how many were new)."""
    rows = {r[0]: r for r in stored}
    added = 0
    for r in arriving:
        if r[0] not in rows:
            rows[r[0]] = r
            added += 1
    return [rows[k] for k in sorted(rows)], added
