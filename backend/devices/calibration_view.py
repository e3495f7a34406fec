"""A leg's answer to a calibration command as the API gives it: what it measured and why it refused, with the
prompt of the step it answered and of the next (the leg's own prompts, :data:`device_bridge.osl.calibration.PROMPTS`)."""

from __future__ import annotations

import dataclasses

from device_bridge.host_calibration import STEP_NAMES, CalibrationAnswer
from device_bridge.osl.calibration import PROMPTS
from device_bridge.protocol import CalibrationStep


def calibration_view(device_id: str, answer: CalibrationAnswer, asked: CalibrationStep | None,
                     body_mass_kg: float | None) -> dict:
    """``answer`` to a command about step ``asked`` (None: start, keep, cancel), for CalibrationOut."""
    step = CalibrationStep[answer.step.upper()] if answer.step is not None else asked
    if answer.outcome == "started":
        after = CalibrationStep.JOINT_ZERO
    elif answer.outcome == "accepted" and step is not None and step < max(CalibrationStep):
        after = CalibrationStep(step + 1)
    else:
        after = None
    return {"device_id": device_id, "step": None if step is None else STEP_NAMES[step], "outcome": answer.outcome,
            "measured": [dataclasses.asdict(m) for m in answer.measured],
            "refused_reason": answer.refused_reason, "refused_subject": answer.refused_subject,
            "refused_words": answer.refused_words, "prompt": None if step is None else PROMPTS[step],
            "next_step": None if after is None else STEP_NAMES[after],
            "next_prompt": None if after is None else PROMPTS[after], "body_mass_kg": body_mass_kg}
