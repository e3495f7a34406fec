"""A second of telemetry as one compact value: the session samples stored one row per second of walking.

100 Hz telemetry is the largest thing QuasiTune stores; a row per sample costs a row header, a key and an index entry
per sample on every database (about 150 bytes on PostgreSQL). Here the samples of one second (sequence numbers
100·s … 100·s + 99) are one ``bytes`` value, zlib (level 6) over the columns one after the other (:data:`COLUMNS`
order), each column in the first of these encodings that gives its values back bit for bit:

* **missing**: every value missing (the adaptive leg's task columns while a single table runs);
* **scaled integers**: every value is ``(n × q) × f`` for whole numbers ``n``, a quantum ``q`` of
  :data:`QUANTA` and ``f`` 1 or π/180, computed in that order in float64 (what the host's decoder does with the
  leg's fixed-point CAN signals: raw × scale, then degrees to radians); stored as the first ``n`` and the differences
  (32-bit): a smooth signal's steps are small numbers that zlib folds away;
* **floats**: float64, each value XOR the one before (its sign, exponent and high mantissa bits then mostly cancel), the
  bytes shuffled (all first bytes, then all second bytes, …: the filter HDF5 and Blosc use); the fallback, and the
  host's receive times.

A missing value (SQL's NULL before) is NaN in the floats: the leg's telemetry is decoded from fixed-point signals and
is always finite, so NaN never stands for a measurement; ``adaptive_mode`` is its index in :data:`ADAPTIVE_MODES`.
Reading back gives exactly the tuples written (every float bit for bit, checked when packing). What is refused, with
the column and the reason: a row of the wrong length, a missing value where the leg always sends one, a non-finite
number, an unknown adaptive mode, a sequence number outside the second or written twice.
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


QUANTA = (1.0, 0.5, 0.1, 0.05, 0.04, 0.01, 0.005, 0.004, 0.002, 0.001, 0.0005, 0.0001)
_FACTORS = (1.0, math.pi / 180.0)
_MISSING, _SCALED, _FLOATS = 0, 1, 2
_COLUMN_HEAD = struct.Struct("<Bdd")   # encoding, quantum, factor (the last two only for scaled integers)


def _scaled(values: np.ndarray) -> tuple[float, float, np.ndarray] | None:
    """(q, f, n) with ``(n × q) × f == values`` bit for bit, or None."""
    if np.isnan(values).any():
        return None
    for f in _FACTORS:
        for q in QUANTA:
            n = np.rint(values / f / q)
            if np.abs(n).max(initial=0.0) >= 2**31:
                continue
            n = n.astype(np.int64)
            again = (n.astype(np.float64) * q) * f      # exactly as unpacking computes it (-0.0 included)
            if np.array_equal(again, values) and np.array_equal(np.signbit(again), np.signbit(values)):
                return q, f, n
    return None


def _encode_column(values: np.ndarray) -> bytes:
    if np.isnan(values).all():
        return _COLUMN_HEAD.pack(_MISSING, 0.0, 0.0)
    found = _scaled(values)
    if found is not None:
        q, f, n = found
        steps = np.diff(n, prepend=0)
        if np.abs(steps).max(initial=0) < 2**31:
            return _COLUMN_HEAD.pack(_SCALED, q, f) + steps.astype("<i4").tobytes()
    bits = values.astype("<f8").view("<u8")
    xored = bits ^ np.concatenate(([np.uint64(0)], bits[:-1]))
    return _COLUMN_HEAD.pack(_FLOATS, 0.0, 0.0) + xored.view(np.uint8).reshape(-1, 8).T.tobytes()


def _decode_column(blob: memoryview, offset: int, n: int) -> tuple[np.ndarray, int]:
    kind, q, f = _COLUMN_HEAD.unpack_from(blob, offset)
    offset += _COLUMN_HEAD.size
    if kind == _MISSING:
        return np.full(n, np.nan), offset
    if kind == _SCALED:
        steps = np.frombuffer(blob, dtype="<i4", count=n, offset=offset).astype(np.int64)
        return (np.cumsum(steps).astype(np.float64) * q) * f, offset + 4 * n
    if kind != _FLOATS:
        raise ValueError(f"stored samples hold an unknown column encoding {kind}")
    shuffled = np.frombuffer(blob, dtype=np.uint8, count=8 * n, offset=offset).reshape(8, n)
    xored = np.ascontiguousarray(shuffled.T).view("<u8").ravel()
    return np.bitwise_xor.accumulate(xored).view("<f8"), offset + 8 * n


def validate_row(row: tuple) -> None:
    """One sample as :func:`pack` checks it (ValueError naming the value; nothing else is done with it)."""
    if len(row) != len(COLUMNS):
        raise ValueError(f"a sample has {len(COLUMNS)} values ({', '.join(COLUMNS)}), got {len(row)}")
    for c, v in zip(COLUMNS, row, strict=True):
        _encode(c, v)


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
    body = b"".join(_encode_column(np.ascontiguousarray(values[:, j])) for j in range(len(COLUMNS)))
    return _HEADER.pack(FORMAT, len(rows)) + zlib.compress(body, 6)


def unpack(blob: bytes) -> list[tuple]:
    """The tuples :func:`pack` was given, in sequence order, exactly."""
    version, n = _HEADER.unpack_from(blob)
    if version != FORMAT:
        raise ValueError(f"samples stored in format {version}; this QuasiTune reads format {FORMAT}")
    body, offset, columns = memoryview(zlib.decompress(blob[_HEADER.size:])), 0, []
    for _ in COLUMNS:
        column, offset = _decode_column(body, offset, n)
        columns.append(column.tolist())
    out: list[list[object]] = [[None] * len(COLUMNS) for _ in range(n)]
    for j, column in enumerate(COLUMNS):
        for i, x in enumerate(columns[j]):
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
