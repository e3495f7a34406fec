"""How far the loaded knee answers its stance-flexion stiffness on the bench, and how much of that the person decides.

A bench study (``quasitune stance-response``), not a verdict on a table: at 1.2 m/s level, 75 kg, the learned table and
the FSMIC's are walked with the knee's stance-flexion stiffness k set to −50 and to −300 N·m/rad, and the learned table
with both knee stance rows at −1 N·m/rad (no knee support), under the bench's stated person
(:class:`device_bridge.sim.person.Person`) and under weaker ones: a weaker hip with the foot down, a softer forward
progression. Per walk it reports the stance knee's peak (mean over strides), the hip's sink, the person's extra push,
the falls, how long the machine stayed in stance flexion (median over strides, ms) and the knee torque as it left
(mean, N·m). The response is the −50 walk's stance knee peak minus the −300 walk's (deg; + is the physiological way).

Why it exists: whether the stance knee's small response on the learned table is the person (whose strengths are
stated choices that could hide a soft knee) or the table (whose stance-flexion row lasts only the loading response).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from controller_core.fsm import GaitState
from controller_core.fsmic import fsmic_table
from controller_core.model import QuasiStiffnessModel
from controller_core.table import ImpedanceTable
from device_bridge.bench.controllers import make_controller
from device_bridge.bench.task_reference import task_reference
from device_bridge.sim.person import Person
from device_bridge.sim.simulate import WalkLog, run_walk, score_walk

STUDY_TASK = (1.2, 0.0)                 # speed m/s, incline deg: the figures
STUDY_K_NM_PER_RAD = (-50.0, -300.0)    # knee stance-flexion stiffness, soft and stiff
LIMP_K_NM_PER_RAD = -1.0                # both knee stance rows: no knee support
SETTLE_S = 2.0                          # strides before this are the start, not the walk

# the person variants walked: label → Person fields changed from the bench's stated person
PERSONS: dict[str, dict[str, float]] = {
    "the bench's person": {},
    "weaker hip with the foot down (0.6 N·m/kg)": {"hip_strength_Nm_per_kg": 0.6},
    "weak hip with the foot down (0.4 N·m/kg)": {"hip_strength_Nm_per_kg": 0.4},
    "softer progression (5 kN/m)": {"progression_stiffness_N_per_m": 5000.0},
    "soft progression (2 kN/m)": {"progression_stiffness_N_per_m": 2000.0},
}


def person_variant(mass_kg: float, **fields: float) -> Person:
    """The bench's person with ``fields`` changed; a changed progression stiffness keeps its drive critically damped
    for the body's mass, as the stated one is."""
    stated = Person(mass_kg)
    person = replace(stated, **fields)
    if "progression_stiffness_N_per_m" in fields and "progression_damping_N_s_per_m" not in fields:
        body_kg = stated.progression_damping_N_s_per_m ** 2 / (4.0 * stated.progression_stiffness_N_per_m)
        person = replace(person, progression_damping_N_s_per_m=2.0 * float(
            np.sqrt(person.progression_stiffness_N_per_m * body_kg)))
    return person


def with_knee_stance_k(table: ImpedanceTable, **k_by_subphase: float) -> ImpedanceTable:
    """``table`` with the knee's stiffness set per stance sub-phase (N·m/rad): a bench study's table, unchecked."""
    return table.model_copy(update={"rows": [
        r.model_copy(update={"k_Nm_per_rad": k_by_subphase[r.subphase]})
        if r.joint == "knee" and r.subphase in k_by_subphase else r for r in table.rows]})


def stance_flexion_stays(log: WalkLog, settle_s: float = SETTLE_S) -> tuple[float | None, float | None]:
    """(median time in stance flexion per visit, ms; mean knee torque on its last tick, N·m) after ``settle_s``."""
    c = log.channels
    in_sf = c["state"] == int(GaitState.STANCE_FLEXION)
    edges = np.diff(in_sf.astype(int))
    starts, ends = np.flatnonzero(edges == 1) + 1, np.flatnonzero(edges == -1)
    stays, torques = [], []
    for a in starts[c["time_s"][starts] >= settle_s]:
        later = ends[ends >= a]
        if later.size:
            stays.append((later[0] - a + 1) * log.timestep_s * 1000.0)
            torques.append(float(c["knee_torque_Nm"][later[0]]))
    if not stays:
        return None, None
    return round(float(np.median(stays)), 1), round(float(np.mean(torques)), 1)


def walk_study_table(table: ImpedanceTable, person: Person, model: QuasiStiffnessModel, seconds: float
                     ) -> dict[str, object]:
    """One bench-study walk of ``table`` at the study task under ``person``: the figures the study reports."""
    speed, incline = STUDY_TASK
    ref = task_reference(speed, incline, model, person.mass_kg)
    log = run_walk(make_controller("table", person.mass_kg, table=table, skip_limits=True), ref, person.mass_kg,
                   seconds, person=person)
    summary = score_walk(log, ref).summary
    stay_ms, torque_Nm = stance_flexion_stays(log)
    return {"falls": summary["falls"], "hip_sink_max_mm": summary["hip_sink_max_mm"],
            "support_deficit_max_bw": summary["support_deficit_max_bw"],
            "stance_knee_flexion_peak_deg": summary["stance_knee_flexion_peak_deg"],
            "stance_flexion_stay_ms": stay_ms, "knee_torque_leaving_stance_flexion_Nm": torque_Nm}


def stance_response(model: QuasiStiffnessModel, mass_kg: float = 75.0, seconds: float = 16.0,
                    persons: dict[str, dict[str, float]] | None = None) -> list[dict[str, object]]:
    """The study: per person variant (``persons``, default :data:`PERSONS`) and table (``learned``, ``FSMIC``), the
    walks at each stance-flexion k, the response (deg) and, for the learned table, the walk with no knee support."""
    speed, incline = STUDY_TASK
    bases = {"learned": model.propose(speed, incline, mass_kg).table, "FSMIC": fsmic_table(mass_kg)}
    rows: list[dict[str, object]] = []
    for label, fields in (persons if persons is not None else PERSONS).items():
        person = person_variant(mass_kg, **fields)
        for name, base in bases.items():
            walks = {f"{k:g}": walk_study_table(with_knee_stance_k(base, stance_flexion=k), person, model, seconds)
                     for k in STUDY_K_NM_PER_RAD}
            soft, stiff = (walks[f"{k:g}"]["stance_knee_flexion_peak_deg"] for k in STUDY_K_NM_PER_RAD)
            row: dict[str, object] = {
                "person": label, "person_fields": fields, "table": name, "speed_mps": speed, "incline_deg": incline,
                "mass_kg": mass_kg, "seconds": seconds, "by_stance_flexion_k_Nm_per_rad": walks,
                "response_deg": None if soft is None or stiff is None else round(float(soft) - float(stiff), 2)}
            if name == "learned":
                row["no_knee_support"] = walk_study_table(
                    with_knee_stance_k(base, stance_flexion=LIMP_K_NM_PER_RAD, stance_extension=LIMP_K_NM_PER_RAD),
                    person, model, seconds)
            rows.append(row)
    return rows
