"""Settings and limit messages in the words a prosthetist uses (the API's field keys stay in the structured fields).

The dashboard names fields the same way (``frontend/app/ui.js``); refusals the server writes for people (an envelope
edit's) use these words and no field keys or parameter names.
"""

from __future__ import annotations

import re

from controller_core.table import LimitViolation

ROW_WORDS = {
    "knee.stance_flexion": "knee stance flexion resistance (loading response)",
    "knee.stance_extension": "knee stance extension (mid and terminal stance)",
    "knee.swing_flexion": "knee swing flexion",
    "knee.swing_extension": "knee swing extension (terminal swing)",
    "ankle.stance_flexion": "ankle loading response (heel rocker)",
    "ankle.stance_extension": "ankle terminal stance and push-off",
    "ankle.swing_flexion": "ankle swing (toe clearance)",
    "ankle.swing_extension": "ankle late swing (ready for heel strike)",
}
PARAMETER_WORDS = {"k_Nm_per_rad": "stiffness", "theta_e_deg": "equilibrium angle", "b_Nm_s_per_rad": "damping"}
THRESHOLD_WORDS = {
    "sf_to_se_ankle_moment_Nm": "stance extension begins: ankle moment below",
    "se_to_wf_load_N": "toe-off: load below",
    "wf_to_we_knee_angle_deg": "swing extension begins: knee flexed beyond",
    "we_to_sf_load_N": "heel strike: load above",
    "min_state_time_s": "shortest time in a phase",
    "max_state_time_s": "longest time in a phase",
    "sf_to_se_knee_extension_deg_per_s": "stance extension also begins: loaded knee extending faster than",
    "stumble_knee_margin_deg": "stumble: swing knee stalled this far above its straightening angle",
    "stumble_knee_rate_deg_per_s": "stumble: stalled means extending slower than",
    "fold_knee_rate_deg_per_s": "stumble: loaded knee folding in early stance faster than",
    "fold_window_of_stance_pct": "stumble: early stance is the first part of stance, up to",
}
UNIT_WORDS = {"k_Nm_per_rad": "N·m/rad", "theta_e_deg": "°", "b_Nm_s_per_rad": "N·m·s/rad", "Nm": "N·m", "N": "N",
              "deg": "°", "s": "s", "deg_per_s": "deg/s", "pct": "%"}
_FIELD = re.compile(r"\b(?:(knee|ankle)\.(stance_flexion|stance_extension|swing_flexion|swing_extension)\."
                    r"(k_Nm_per_rad|theta_e_deg|b_Nm_s_per_rad)|thresholds\.(\w+))\b")


def field_words(field: str) -> str:
    """``knee.stance_flexion.k_Nm_per_rad`` → ``knee stance flexion resistance (loading response): stiffness``."""
    m = _FIELD.fullmatch(field)
    if m is None:
        return field
    if m.group(4):
        return THRESHOLD_WORDS.get(m.group(4), field)
    return f"{ROW_WORDS[f'{m.group(1)}.{m.group(2)}']}: {PARAMETER_WORDS[m.group(3)]}"


def unit_of(field: str) -> str:
    """The unit of a field, as shown (``N·m/rad``, ``°``, ``N`` …)."""
    name = field.rsplit(".", 1)[-1]
    if name in UNIT_WORDS:
        return UNIT_WORDS[name]
    for suffix in ("deg_per_s", "Nm", "N", "deg", "s", "pct"):
        if name.endswith("_" + suffix):
            return UNIT_WORDS[suffix]
    return ""


_NEIGHBOURS = re.compile(r"neighbours\[(.+) \| (.+)\]\.(.+)")
_NODE = re.compile(r"node\[(.+?)\]\.(.+)")


def violation_words(v: LimitViolation) -> str:
    """One limit or neighbour-rule violation in clinical words: where, which setting, the value and the allowed range."""
    m = _NEIGHBOURS.fullmatch(v.field)
    if m:
        here, there, field = m.groups()
        unit = unit_of(field)
        return (f"{field_words(field)} changes by {v.value:.3g} {unit} between the neighbouring tasks "
                f"{here.replace(' deg', '°')} and {there.replace(' deg', '°')}: at most {v.high:g} {unit} from one "
                "task to the next")
    where = ""
    field = v.field
    m = _NODE.fullmatch(field)
    if m:
        where, field = f"at {m.group(1).replace(' deg', '°')}: ", m.group(2)
    message = v.message
    if where and message.startswith("at "):
        message = message.split(": ", 1)[1]
    return where + _FIELD.sub(lambda f: field_words(f.group(0)), message).replace(" deg ", "° ")
