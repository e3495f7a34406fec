"""Settings and limit messages in the words a prosthetist uses (the API's field keys stay in the structured fields).

The words are kept once, in ``clinical_words.json`` beside this module: the dashboard imports the same file (served at
``/clinical_words.json``, ``backend/frontend.py``), so a setting is named alike on the page and in the refusals the
server writes for people (an envelope edit's), which use these words and no field keys or parameter names.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

from controller_core.table import LimitViolation

WORDS_PATH = Path(__file__).with_name("clinical_words.json")   # the dashboard's copy too (/clinical_words.json)
_WORDS = json.loads(WORDS_PATH.read_text(encoding="utf-8"))
ROW_WORDS: dict[str, str] = _WORDS["rows"]
PARAMETER_WORDS: dict[str, str] = _WORDS["parameters"]
THRESHOLD_WORDS: dict[str, str] = _WORDS["thresholds"]
UNIT_WORDS: dict[str, str] = _WORDS["units"]
_FIELD = re.compile(r"\b(?:(knee|ankle)\.(stance_flexion|stance_extension|swing_flexion|swing_extension)\."
                    r"(k_Nm_per_rad|theta_e_deg|b_Nm_s_per_rad)|thresholds\.(\w+))\b")


def field_words(field: str) -> str:
    """``knee.stance_flexion.k_Nm_per_rad`` → ``knee stance flexion resistance (loading response): resistance K``."""
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
