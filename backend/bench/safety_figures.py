"""The safety figures of a bench walk, flagged for the prosthetist before any tracking error is shown.

A table can track the reference better than the FSMIC and still trip the patient or leave a loaded knee on the
weak swing impedance. These figures are not scores: each one is flagged on its own bound, whatever the RMSEs say, and
every flag gates approval and push as a fall does (:mod:`backend.services.bench_verdict`).

Bounds (and why):

* falls: any fall (the hip sank more than 150 mm below where a person's would be, or the knee buckled past 60° under
  more than half the body weight: ``device_bridge.sim.simulate``).
* toe catches: any foot contact in mid-swing (a stumble the patient would feel).
* heel strikes never reaching stance: the leg stayed on swing impedance through a whole loading response.
* loaded swing: more than 20 ms in any one stride on a swing row with more than ½ body weight on the leg (the
  bound of the heel-strike safety target). Previews stored before the longest stride was measured are judged on the
  mean per stride.
* the body carried (the walk goes on, but not as people's does): the hip sinking more than 50 mm below its
  path in stance (people's hips rise and fall about 40 mm over a stride, and the bench's own residual with the
  reference's angles is under 60 mm above, 20 mm below it); the person adding more than 1.5 body weights
  through their other leg (the bench's own residual is under 1.1); the knee flexing beyond 40° under the body in early
  stance (people: about 20°).
* foot contact → stance, longest: more than 50 ms (about a third of the loading response at 1.2 m/s), or more than
  20 ms later than the FSMIC's on the same walk.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Literal

Severity = Literal["bad"]      # every figure beyond its bound gates; one severity, kept in the API for its readers

LOADED_SWING_MAX_MS = 20.0
STANCE_ENTRY_MAX_MS = 50.0
STANCE_ENTRY_BEHIND_FSMIC_MS = 20.0
HIP_SINK_WARN_MM = 50.0
SUPPORT_DEFICIT_WARN_BW = 1.5
STANCE_KNEE_WARN_DEG = 40.0


def _flag(figure: str, severity: Severity, value: float | int, fsmic: float | int | None, unit: str,
          message: str) -> dict[str, object]:
    return {"figure": figure, "severity": severity, "value": value, "fsmic_value": fsmic, "unit": unit,
            "message": message}


def safety_flags(table: Mapping[str, object], fsmic: Mapping[str, object]) -> list[dict[str, object]]:
    """Flags on the safety figures of ``table``'s bench walk (summary of ``score_walk``), next to the FSMIC's.

    Returns one dict per figure beyond its bound (``figure``, ``severity`` "bad", ``value``, ``fsmic_value``,
    ``unit``, ``message`` in words a prosthetist reads, with the bound); empty when every figure is within bounds.
    Missing figures (a walk with no whole stride) are flagged: nothing measured is not safe.
    """
    flags: list[dict[str, object]] = []
    falls, toe = int(table.get("falls") or 0), int(table.get("toe_catches") or 0)
    if falls:
        flags.append(_flag("falls", "bad", falls, fsmic.get("falls"), "falls",
                           f"the leg gave way {falls} time(s) on the simulated bench"))
    if toe:
        flags.append(_flag("toe_catches", "bad", toe, fsmic.get("toe_catches"), "catches",
                           f"the toe caught the floor in mid-swing {toe} time(s): a trip risk"))
    missed = table.get("heel_strikes_without_stance")
    if missed is None:
        flags.append(_flag("strides", "bad", int(table.get("strides") or 0), fsmic.get("strides"), "strides",
                           "no whole stride was walked: the safety figures could not be measured"))
        return flags
    if int(missed):
        flags.append(_flag("heel_strikes_without_stance", "bad", int(missed), fsmic.get("heel_strikes_without_stance"),
                           "strides", f"on {int(missed)} stride(s) the leg never switched to stance after the foot "
                           "touched down"))
    key = "loaded_swing_ms_max_stride" if table.get("loaded_swing_ms_max_stride") is not None \
        else "loaded_swing_ms_per_stride"
    loaded = float(table.get(key) or 0.0)
    if loaded > LOADED_SWING_MAX_MS:
        which = "in one stride" if key == "loaded_swing_ms_max_stride" else "per stride on average"
        flags.append(_flag(key, "bad", loaded, fsmic.get(key), "ms",
                           f"up to {loaded:.0f} ms {which} on the weak swing settings with more than half the body "
                           f"weight on the leg (bound {LOADED_SWING_MAX_MS:.0f} ms)"))
    flags.extend(_carrying_flags(table, fsmic))
    entry = table.get("heel_strike_to_stance_ms_max")
    fsmic_entry = fsmic.get("heel_strike_to_stance_ms_max")
    if entry is not None:
        late = float(entry) > STANCE_ENTRY_MAX_MS
        behind = fsmic_entry is not None and float(entry) > float(fsmic_entry) + STANCE_ENTRY_BEHIND_FSMIC_MS
        if late or behind:
            versus = f" (FSMIC {float(fsmic_entry):.0f} ms)" if fsmic_entry is not None else ""
            bound = f"bound {STANCE_ENTRY_MAX_MS:.0f} ms" + (
                f", or {STANCE_ENTRY_BEHIND_FSMIC_MS:.0f} ms behind the FSMIC" if fsmic_entry is not None else "")
            flags.append(_flag("heel_strike_to_stance_ms_max", "bad", float(entry), fsmic_entry, "ms",
                               f"up to {float(entry):.0f} ms from foot contact to the stance settings{versus} "
                               f"({bound})"))
    return flags


def _carrying_flags(table: Mapping[str, object], fsmic: Mapping[str, object]) -> list[dict[str, object]]:
    """Flags on how well the leg carried the body (previews stored before the bench carried it have none)."""
    out = []
    sink = table.get("hip_sink_max_mm")
    if sink is not None and float(sink) > HIP_SINK_WARN_MM:
        out.append(_flag("hip_sink_max_mm", "bad", float(sink), fsmic.get("hip_sink_max_mm"), "mm",
                         f"the hip sank up to {float(sink):.0f} mm below where a person's would be in stance: the leg "
                         f"does not carry the body as people's does (bound {HIP_SINK_WARN_MM:.0f} mm)"))
    deficit = table.get("support_deficit_max_bw")
    if deficit is not None and float(deficit) > SUPPORT_DEFICIT_WARN_BW:
        out.append(_flag("support_deficit_max_bw", "bad", float(deficit), fsmic.get("support_deficit_max_bw"), "BW",
                         f"the person had to push up to {float(deficit):.2f} body weights through their other leg "
                         f"beyond its usual share (bound {SUPPORT_DEFICIT_WARN_BW:.1f})"))
    knee = table.get("stance_knee_flexion_peak_max_deg")
    if knee is not None and float(knee) > STANCE_KNEE_WARN_DEG:
        people = table.get("reference_stance_knee_flexion_peak_deg")
        said = f"; people: {float(people):.0f}°" if people is not None else ""
        out.append(_flag("stance_knee_flexion_peak_max_deg", "bad", float(knee),
                         fsmic.get("stance_knee_flexion_peak_max_deg"), "deg",
                         f"the knee flexed up to {float(knee):.0f}° under the body in early stance{said} "
                         f"(bound {STANCE_KNEE_WARN_DEG:.0f}°)"))
    return out


_FIGURES = (("falls", "falls", "falls"), ("toe_catches", "toe catches in mid-swing", "catches"),
            ("heel_strikes_without_stance", "strides that never reached stance", "strides"),
            ("loaded_swing_ms_max_stride", "loaded swing, longest in a stride", "ms"),
            ("heel_strike_to_stance_ms_max", "foot contact → stance settings, longest", "ms"),
            ("hip_sink_max_mm", "hip sink below a person's in stance, largest", "mm"),
            ("support_deficit_max_bw", "extra push from the other leg, largest", "BW"),
            ("stance_knee_flexion_peak_max_deg", "knee flexion under the body in early stance, largest", "deg"))


def safety_figures(table: Mapping[str, object], fsmic: Mapping[str, object]) -> list[dict[str, object]]:
    """Every safety figure of ``table``'s bench walk beside the FSMIC's, with its flag's severity (None: within its
    bound): what the decision shows next to Approve and Push, before any tracking error."""
    severity = {f["figure"]: f["severity"] for f in safety_flags(table, fsmic)}
    out = []
    for key, label, unit in _FIGURES:
        value = table.get(key)
        if key == "loaded_swing_ms_max_stride" and value is None:   # previews stored before the longest stride
            key, label, value = "loaded_swing_ms_per_stride", "loaded swing, per stride", table.get(
                "loaded_swing_ms_per_stride")
        out.append({"figure": key, "label": label, "unit": unit, "value": value, "fsmic_value": fsmic.get(key),
                    "severity": severity.get(key)})
    return out
