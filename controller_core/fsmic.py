"""The benchmark: a finite-state impedance controller (FSMIC) with a fixed, hand-tuned literature table.

Source of the numbers: the four-state walking controller shipped as an example with the Open Source Leg
software (Neurobionics Lab, University of Michigan; `opensourceleg` package examples, "FSM walking
controller"; device: Azocar AF, Mooney LM, Duval JF, Simon AM, Hargrove LJ, Rouse EJ, "Design and clinical
implementation of an open-source bionic leg", Nature Biomedical Engineering 4:941-953, 2020). It follows
the scheme of Sup F, Bohara A, Goldfarb M, "Design and control of a powered transfemoral prosthesis",
Int J Robotics Research 27(2):263-273, 2008 / Sup et al., IEEE/ASME Trans Mechatronics 14(6), 2009:
early stance, late stance, early swing, late swing, with τ = −K(θ − θe) − Bθ̇ per joint and state.

The example was tuned for a 60 kg user at self-selected level walking (about 1.2 m/s, our nominal task).
Conversion to QuasiTune's table:

* stiffness K (N·m/rad, restoring, positive in the source) → k = −K, scaled by patient mass / 60 kg,
  and damping B (N·m·s/rad) likewise scaled; angles stay in degrees (knee flexion +, ankle dorsiflexion +,
  the source's conventions);
* thresholds: toe-off at load < 15 % body weight and late swing at knee > 50° are taken as published;
  heel strike at load > 40 % of body weight as published (the source also accepts knee < 30°, which this
  machine does not have);
* the source moves from early to late stance when the ankle dorsiflexes past 6°; this machine moves on
  the sagittal moment, so the threshold is the moment that the source's own early-stance ankle impedance
  produces at 6°: −K_ankle,ES·(6° − θe,ankle,ES).

The table is fixed: it is never re-tuned per task (that is the point of the benchmark).
"""

from __future__ import annotations

import math

from controller_core.quasi_stiffness import SUBPHASES
from controller_core.table import ParameterRow, ParameterTable, Provenance, Thresholds, assert_safe
from controller_core.task import validate_task
from controller_core.units import G_MPS2

SOURCE_MASS_KG = 60.0
NOMINAL_SPEED_MPS = 1.2
FSMIC_VERSION = "fsmic-osl-example-2023"

# (K N·m/rad, B N·m·s/rad, θe deg) per state, as published for a 60 kg user; K is restoring (τ = −K(θ − θe)).
OSL_EXAMPLE_IMPEDANCE: dict[str, dict[str, tuple[float, float, float]]] = {
    "knee": {
        "stance_flexion": (99.372, 3.180, 5.0),
        "stance_extension": (99.372, 1.272, 8.0),
        "swing_flexion": (39.749, 0.063, 60.0),
        "swing_extension": (15.899, 3.816, 5.0),
    },
    "ankle": {
        "stance_flexion": (19.874, 0.0, -2.0),
        "stance_extension": (79.498, 0.063, -20.0),
        "swing_flexion": (7.949, 0.0, 25.0),
        "swing_extension": (7.949, 0.0, 15.0),
    },
}
OSL_TOE_OFF_LOAD_FRACTION = 0.15
OSL_HEEL_STRIKE_LOAD_FRACTION = 0.40
OSL_LATE_SWING_KNEE_DEG = 50.0
OSL_LATE_STANCE_ANKLE_DEG = 6.0


def fsmic_table(mass_kg: float = 75.0, min_state_time_s: float = 0.05, max_state_time_s: float = 1.5) -> ParameterTable:
    """The benchmark table for a patient of ``mass_kg`` (kg), in QuasiTune's units and sign convention.

    The state-time guards default to the same values as the learned tables, so the two controllers differ
    only in what the literature fixes: impedances and thresholds.
    """
    validate_task(NOMINAL_SPEED_MPS, 0.0, mass_kg)
    scale = mass_kg / SOURCE_MASS_KG
    rows = [ParameterRow(joint=joint, subphase=sub, k_Nm_per_rad=-K * scale, theta_e_deg=theta_e,
                         b_Nm_s_per_rad=B * scale)
            for joint, per_state in OSL_EXAMPLE_IMPEDANCE.items()
            for sub, (K, B, theta_e) in ((s, per_state[s]) for s in SUBPHASES)]
    k_es, _, theta_es = OSL_EXAMPLE_IMPEDANCE["ankle"]["stance_flexion"]
    moment = -k_es * scale * math.radians(OSL_LATE_STANCE_ANKLE_DEG - theta_es)
    weight_N = mass_kg * G_MPS2
    table = ParameterTable(
        rows=rows,
        thresholds=Thresholds(
            sf_to_se_ankle_moment_Nm=moment,
            se_to_wf_load_N=OSL_TOE_OFF_LOAD_FRACTION * weight_N,
            wf_to_we_knee_angle_deg=OSL_LATE_SWING_KNEE_DEG,
            we_to_sf_load_N=OSL_HEEL_STRIKE_LOAD_FRACTION * weight_N,
            min_state_time_s=min_state_time_s, max_state_time_s=max_state_time_s),
        provenance=Provenance(model_version=FSMIC_VERSION, data_sha256="", speed_mps=NOMINAL_SPEED_MPS,
                              incline_deg=0.0, patient_mass_kg=mass_kg, extrapolation=False, source="literature"))
    assert_safe(table)
    return table
