"""Reference gait records: typed containers and the loader for the project's shipped copy of the data.

Units (SI inside the code):

* phase ``s`` in [0, 1], 0 = ipsilateral heel strike;
* joint angles in rad (knee flexion +, ankle dorsiflexion +);
* joint moments in N·m/kg body mass, internal, positive in the direction of the positive angle
  (so the stance plantarflexor moment and the early-stance knee extensor moment are negative).

The shipped data are published group means (see ``controller_core/data/README.md``).
"""

from __future__ import annotations

import hashlib
import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

JOINTS: tuple[str, ...] = ("knee", "ankle")
CHANNELS: tuple[str, ...] = ("knee_angle", "knee_moment", "ankle_angle", "ankle_moment")
CHANNEL_UNITS_SI: dict[str, str] = {
    "knee_angle": "rad",
    "knee_moment": "N·m/kg",
    "ankle_angle": "rad",
    "ankle_moment": "N·m/kg",
}
# channel → (its name with the display unit, the factor from SI to that unit): degrees and N·m/kg on screen
CHANNEL_DISPLAY: dict[str, tuple[str, float]] = {
    "knee_angle": ("knee_angle_deg", math.degrees(1.0)), "ankle_angle": ("ankle_angle_deg", math.degrees(1.0)),
    "knee_moment": ("knee_moment_Nm_per_kg", 1.0), "ankle_moment": ("ankle_moment_Nm_per_kg", 1.0)}
DEFAULT_TASK_NAMES: tuple[str, ...] = ("speed_mps", "incline_deg")
SHIPPED_NPZ = "gait_reference_speed_conditions.npz"
SHIPPED_INCLINE_CSV = "incline_features.csv"

CITATIONS: dict[str, str] = {
    "bovi2011": "Bovi G, Rabuffetti M, Mazzoleni P, Ferrarin M. A multiple-task gait analysis approach: "
    "kinematic, kinetic and EMG reference data for healthy young and adult subjects. "
    "Gait & Posture 33(1):6-13, 2011.",
    "winter1987": "Winter DA. The Biomechanics and Motor Control of Human Gait. "
    "University of Waterloo Press, 1987.",
    "schwartz2008": "Schwartz MH, Rozumalski A, Trost JP. The effect of walking speed on the gait of "
    "typically developing children. Journal of Biomechanics 41(8):1639-1650, 2008.",
    "vielemeyer2025": "Vielemeyer J, et al. A full-body motion capture gait dataset of healthy young adults walking "
    "ramps up and down. Scientific Data, 2025 (participant Ref01).",
}


@dataclass(frozen=True)
class ReferenceRecord:
    """One walking condition: mean (and SD) curves on a phase grid.

    Attributes:
        name: human-readable identifier, e.g. ``"bovi2011/Natural (self-selected)"``.
        dataset: source key (``bovi2011``, ``winter1987``, ``schwartz2008`` or a user label).
        task: task variables, e.g. ``{"speed_mps": 1.2, "incline_deg": 0.0}``; NaN where unknown.
        phase: (P,) gait phase in [0, 1].
        mean: channel -> (P,) mean curve in SI (rad, N·m/kg).
        sd: channel -> (P,) between-subject SD in the same unit (NaN where not published).
        toe_off_phase: published (or estimated) toe-off as a fraction of the cycle, NaN if unknown.
        n: number of subjects/trials/strides behind the mean (``-1`` if not reported).
        notes: processing applied here (e.g. the Bovi ankle offset), for provenance.
    """

    name: str
    dataset: str
    task: dict[str, float]
    phase: np.ndarray
    mean: dict[str, np.ndarray]
    sd: dict[str, np.ndarray]
    toe_off_phase: float = float("nan")
    n: int = -1
    population: str = "adult"
    notes: tuple[str, ...] = ()

    def task_vector(self, task_names: tuple[str, ...]) -> np.ndarray:
        """Task values in the order of ``task_names`` (NaN for a missing entry)."""
        return np.array([self.task.get(k, np.nan) for k in task_names], dtype=float)


@dataclass(frozen=True)
class ReferenceSet:
    """A collection of records sharing one phase grid, with provenance.

    Attributes:
        records: the walking conditions.
        task_names: task variables the model is conditioned on (SI-ish names with units).
        data_sha256: hash of the source bytes the set was built from.
        provenance: free-form description of sources and processing.
    """

    records: tuple[ReferenceRecord, ...]
    task_names: tuple[str, ...] = DEFAULT_TASK_NAMES
    data_sha256: str = ""
    provenance: dict[str, object] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if not self.records:
            raise ValueError("a reference set needs at least one record")
        p0 = self.records[0].phase
        for rec in self.records[1:]:
            if rec.phase.shape != p0.shape or not np.allclose(rec.phase, p0):
                raise ValueError(f"record {rec.name!r} is on a different phase grid")

    @property
    def phase(self) -> np.ndarray:
        """(P,) common phase grid in [0, 1]."""
        return self.records[0].phase

    def tasks(self) -> np.ndarray:
        """(R, T) task matrix in the order of ``task_names``."""
        return np.vstack([r.task_vector(self.task_names) for r in self.records])

    def stack(self, channel: str) -> np.ndarray:
        """(R, P) mean curves of one channel."""
        return np.vstack([r.mean[channel] for r in self.records])

    def subset(self, keep: list[int] | np.ndarray) -> ReferenceSet:
        """A new set with only the records at the given indices (same provenance)."""
        return ReferenceSet(
            records=tuple(self.records[i] for i in keep),
            task_names=self.task_names,
            data_sha256=self.data_sha256,
            provenance=self.provenance,
        )


def data_dir() -> Path:
    """Directory holding the project's copy of the reference data."""
    return Path(__file__).resolve().parent / "data"


def sha256_of(*paths: Path) -> str:
    """SHA-256 over the bytes of the given files, in order."""
    h = hashlib.sha256()
    for p in paths:
        h.update(Path(p).read_bytes())
    return h.hexdigest()


def interp_rows(x: float, xs: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """Interpolate (R, P) rows sampled at non-decreasing xs linearly at x, clamped at the ends: column by column what
    ``np.interp`` gives (the same arithmetic and the same choice among equal xs, so the same bits; NaN at a NaN x), in
    one step instead of a call per column."""
    if math.isnan(x):
        return np.full(rows.shape[1], np.nan)
    if x < xs[0]:
        return rows[0].copy()
    if x >= xs[-1]:
        return rows[-1].copy()
    j = int(np.searchsorted(xs, x, side="right")) - 1
    if x == xs[j]:
        return rows[j].copy()
    slope = (rows[j + 1] - rows[j]) / (xs[j + 1] - xs[j])
    return slope * (x - xs[j]) + rows[j]


def load_npz(path: Path) -> dict[str, np.ndarray]:
    with np.load(path, allow_pickle=False) as d:
        return {k: d[k] for k in d.files}


def bovi_ankle_offset_deg(d: dict[str, np.ndarray]) -> float:
    """Offset (deg) that brings Bovi 2011 ankle angles onto the Winter 1987 neutral.

    Bovi's ankle angle sits about 20° below the other adult source over the whole cycle (a different
    neutral reference; the shared data README documents it and leaves it uncorrected). A prosthesis
    needs the anatomical neutral (foot perpendicular to shank ≈ 0°), so we add the mean difference
    Winter "Natural cadence" − Bovi "Natural (self-selected)" over the 101 phase points. The value is
    computed from the data, not typed in: about +19.2° (SD over the cycle ≈ 2.2°).
    """
    ds, cond = d["dataset"], d["condition"]
    winter = np.flatnonzero((ds == "winter1987") & (cond == "Natural cadence"))
    bovi = np.flatnonzero((ds == "bovi2011") & (cond == "Natural (self-selected)"))
    if winter.size != 1 or bovi.size != 1:
        raise ValueError("shipped data lack the Winter/Bovi natural records used for the ankle offset")
    diff = d["ankle_angle_deg"][winter[0]].astype(float) - d["ankle_angle_deg"][bovi[0]].astype(float)
    return float(diff.mean())


def load_shipped_reference(
    datasets: tuple[str, ...] = ("bovi2011",),
    tasks: tuple[str, ...] = ("level_walking",),
    populations: tuple[str, ...] = ("adult",),
    require_speed: bool = True,
    correct_bovi_ankle: bool = True,
) -> ReferenceSet:
    """Load the shipped published reference curves as a :class:`ReferenceSet`.

    The default selection (Bovi 2011 adult level walking at 0.84, 1.19, 1.20, 1.49 and 1.95 m/s) is what
    the default model is trained on: the only adult records with a walking speed in m/s. Winter 1987
    (adult, no speed) and Schwartz 2008 (children, dimensionless speed) can be selected with
    ``require_speed=False`` for comparisons.

    Args:
        datasets: source keys to keep.
        tasks: task labels to keep (``level_walking``, ``stair_ascent``, ``stair_descent``).
        populations: ``adult`` and/or ``children``.
        require_speed: drop records with no speed in m/s.
        correct_bovi_ankle: add :func:`bovi_ankle_offset_deg` to Bovi ankle angles.
    """
    path = data_dir() / SHIPPED_NPZ
    d = load_npz(path)
    phase = d["phase_pct"].astype(float) / 100.0
    offset = bovi_ankle_offset_deg(d) if correct_bovi_ankle else 0.0
    records: list[ReferenceRecord] = []
    for i in range(d["dataset"].shape[0]):
        ds = str(d["dataset"][i])
        if ds not in datasets or str(d["task"][i]) not in tasks or str(d["population"][i]) not in populations:
            continue
        speed = float(d["speed_mps"][i])
        if require_speed and not np.isfinite(speed):
            continue
        notes: list[str] = []
        ankle_shift = 0.0
        if ds == "bovi2011" and correct_bovi_ankle:
            ankle_shift = offset
            notes.append(f"ankle angle +{offset:.2f} deg (Bovi neutral aligned to Winter 1987)")
        mean: dict[str, np.ndarray] = {}
        sd: dict[str, np.ndarray] = {}
        for joint in JOINTS:
            ang = d[f"{joint}_angle_deg"][i].astype(float) + (ankle_shift if joint == "ankle" else 0.0)
            mean[f"{joint}_angle"] = np.deg2rad(ang)
            sd[f"{joint}_angle"] = np.deg2rad(d[f"{joint}_angle_deg_sd"][i].astype(float))
            mean[f"{joint}_moment"] = d[f"{joint}_moment_Nm_per_kg"][i].astype(float)
            sd[f"{joint}_moment"] = d[f"{joint}_moment_Nm_per_kg_sd"][i].astype(float)
        incline = float(d["incline_deg"][i])
        records.append(
            ReferenceRecord(
                name=f"{ds}/{d['condition'][i]}",
                dataset=ds,
                task={"speed_mps": speed, "incline_deg": incline},
                phase=phase,
                mean=mean,
                sd=sd,
                toe_off_phase=float(d["toe_off_pct"][i]) / 100.0,
                n=int(d["n_reported"][i]),
                population=str(d["population"][i]),
                notes=tuple(notes),
            )
        )
    meta = json.loads(str(d["metadata_json"]))
    provenance: dict[str, object] = {
        "source": f"controller_core/data/{SHIPPED_NPZ}",
        "citations": {k: v for k, v in CITATIONS.items() if k in datasets},
        "conventions": meta.get("conventions", {}),
        "bovi_ankle_offset_deg": offset if "bovi2011" in datasets else 0.0,
    }
    return ReferenceSet(
        records=tuple(records),
        task_names=DEFAULT_TASK_NAMES,
        data_sha256=sha256_of(path),
        provenance=provenance,
    )


def level_curves_at(reference: ReferenceSet, speed_mps: float,
                    channels: tuple[str, ...] = CHANNELS) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    """Mean and between-subject SD curves of the level records, linear in speed between them (the nearest record
    beyond their speeds): the population's level walking at a speed."""
    level = [r for r in reference.records if r.task.get("incline_deg", 0.0) == 0.0
             and np.isfinite(r.task.get("speed_mps", np.nan))]
    if not level:
        raise ValueError("the reference set has no level records with a speed")
    order = np.argsort([r.task["speed_mps"] for r in level])
    speeds = np.array([level[i].task["speed_mps"] for i in order])

    def at(curves: list[np.ndarray]) -> np.ndarray:
        return interp_rows(speed_mps, speeds, np.array([curves[i] for i in order]))

    return ({c: at([r.mean[c] for r in level]) for c in channels},
            {c: at([r.sd[c] for r in level]) for c in channels})
