"""A second of telemetry packed into one value: read back exactly, malformed samples refused by name."""

from __future__ import annotations

import math
import random

import pytest

from backend.store.sample_pack import ADAPTIVE_MODES, COLUMNS, SAMPLES_PER_ROW, merge, pack, unpack


def _sample(seq: int, rng: random.Random, adaptive: bool = True) -> tuple:
    """A sample with awkward floats (random bits of mantissa, tiny and large magnitudes): exactness, not smoothness."""
    task = (rng.uniform(0.5, 2.0), rng.uniform(-10, 10), rng.uniform(0.5, 2.0), -0.0) if adaptive else (None,) * 4
    return (seq, seq / 100.0, rng.choice((0, 1, 2)), rng.choice((0, 1, 2, 3, None)), rng.uniform(-1, 2) * 1e-7,
            rng.gauss(0, 3), rng.uniform(-120, 120), math.pi * rng.random(), rng.gauss(0, 1) * 1e12,
            rng.uniform(-160, 160), 735.25, -5e-324, *task, rng.choice((*ADAPTIVE_MODES, None)) if adaptive else None)


@pytest.mark.parametrize("adaptive", [True, False])
def test_a_second_reads_back_exactly_in_sequence_order(adaptive):
    rng = random.Random(7)
    rows = [_sample(300 + i, rng, adaptive) for i in rng.sample(range(SAMPLES_PER_ROW), 60)]
    back = unpack(pack(rows))
    assert back == sorted(rows, key=lambda r: r[0])
    for got, want in zip(back, sorted(rows, key=lambda r: r[0]), strict=True):   # bit for bit, -0.0 included
        assert [math.copysign(1, x) if isinstance(x, float) else x for x in got] == \
               [math.copysign(1, x) if isinstance(x, float) else x for x in want]
        assert [type(x) for x in got] == [type(x) for x in want]


def test_smooth_telemetry_packs_far_below_its_raw_size():
    """Synthetic, smooth signals (said so): the shuffle + zlib packing keeps well under the 8 bytes per value raw."""
    rows = [(i, i / 100, 1, 0, 0.3 * math.sin(i / 16), 0.1 * math.cos(i / 16), -20 * math.sin(i / 16),
             0.1 * math.sin(i / 16 + 1), 0.0, 5.0, 700.0 + 50 * math.sin(i / 8), -10.0, None, None, None, None, None)
            for i in range(SAMPLES_PER_ROW)]
    assert len(pack(rows)) < 0.6 * SAMPLES_PER_ROW * len(COLUMNS) * 8


@pytest.mark.parametrize(("change", "words"), [
    (lambda r: r[:-1], "has 17 values"),
    (lambda r: (r[0], None, *r[2:]), "t_s is missing"),
    (lambda r: (*r[:4], float("nan"), *r[5:]), "knee_angle_rad must be finite"),
    (lambda r: (*r[:4], "0.1", *r[5:]), "knee_angle_rad must be a number"),
    (lambda r: (*r[:2], 1.5, *r[3:]), "mode must be a whole number"),
    (lambda r: (*r[:-1], "sprinting"), "adaptive_mode 'sprinting' is not one of"),
])
def test_a_malformed_sample_is_refused_naming_the_value(change, words):
    good = _sample(5, random.Random(1))
    with pytest.raises(ValueError, match=words):
        pack([good, change(_sample(6, random.Random(2)))])


def test_samples_of_two_seconds_or_a_repeated_number_are_refused():
    rng = random.Random(3)
    with pytest.raises(ValueError, match="not one second's"):
        pack([_sample(99, rng), _sample(100, rng)])
    with pytest.raises(ValueError, match="appears twice"):
        pack([_sample(4, rng), _sample(4, rng)])
    with pytest.raises(ValueError, match="1 to 100 samples"):
        pack([])


def test_a_merge_keeps_what_was_stored_and_counts_what_is_new():
    rng = random.Random(4)
    stored = [_sample(i, rng) for i in (0, 1, 2)]
    retry = [_sample(i, rng) for i in (2, 3)]            # 2 again, with other values: the stored one stays
    merged, added = merge(stored, retry)
    assert added == 1 and [r[0] for r in merged] == [0, 1, 2, 3] and merged[2] == stored[2]


def test_the_legs_fixed_point_signals_are_kept_as_scaled_integers():
    """Synthetic (said so): values made the way the host decodes the leg's CAN signals (raw × scale, angles then × π/180)
    over a random walk of raw counts; packed as whole numbers they cost a fraction of their float64 size, exactly."""
    rng, deg = random.Random(9), math.pi / 180      # the host's degrees-to-radians factor
    raw = [0] * 6
    rows = []
    for i in range(SAMPLES_PER_ROW):
        raw = [r + rng.randint(-40, 40) for r in raw]
        rows.append((i, 1_795_750_000.0 + i * 0.01 + rng.random() * 1e-4, 1, i % 4,
                     raw[0] * 0.01 * deg, raw[1] * 0.1 * deg, raw[2] * 0.01,
                     raw[3] * 0.01 * deg, raw[4] * 0.1 * deg, raw[5] * 0.01,
                     700 + (i % 7) * 0.5, -20 + (i % 11) * 0.01, None, None, None, None, None))
    blob = pack(rows)
    assert unpack(blob) == rows
    assert len(blob) < 25 * SAMPLES_PER_ROW          # float64 columns alone would be 8 × 17 = 136 bytes a sample
