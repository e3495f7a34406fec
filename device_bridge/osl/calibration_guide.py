"""The guided calibration on the leg: prompts the prosthetist through each step of :mod:`device_bridge.osl.calibration`,
reads the leg's sensors while they hold each pose, says what every step measured, repeats a step it refused, and
returns the leg's :class:`~device_bridge.osl.config.Calibration` (``quasitune leg --calibrate`` keeps it beside the
leg file, :func:`device_bridge.osl.config.save_calibration`). The steps are those the clinic's device page drives
(:class:`~device_bridge.osl.calibration_session.CalibrationSession`), with the same prompts and words.

The prompts are the leg's; ``ask`` shows one and waits until the pose is held (the terminal's Enter), ``say`` reports.
"""

from __future__ import annotations

import time
from collections.abc import Callable

from device_bridge.osl.calibration import PROMPTS, CalibrationRefusedError, StepResult
from device_bridge.osl.calibration_session import DEFAULT_SAMPLES, CalibrationSession
from device_bridge.osl.config import Calibration
from device_bridge.osl.leg import OSLLeg
from device_bridge.protocol import CalibrationStep

ATTEMPTS = 3


def guided_calibration(leg: OSLLeg, body_mass_kg: float, ask: Callable[[str], None], say: Callable[[str], None],
                       samples: int = DEFAULT_SAMPLES, sleep: Callable[[float], None] = time.sleep) -> Calibration:
    """Walk the prosthetist through the four steps (module docstring); a refused step is said and asked again, up to
    :data:`ATTEMPTS` times (then CalibrationRefusedError)."""
    session = CalibrationSession(samples)
    for step in CalibrationStep:
        for attempt in range(1, ATTEMPTS + 1):
            ask(PROMPTS[step])
            session.begin(step, body_mass_kg)
            try:
                results: tuple[StepResult, ...] | None = None
                while results is None:
                    leg.sample()                    # every device read once (its faults kept as in walking)
                    results = session.feed(leg.raw_readings())
                    sleep(leg.config.period_s)
            except CalibrationRefusedError as exc:
                say(f"refused: {exc}" + ("" if attempt < ATTEMPTS else " (no attempts left)"))
                if attempt == ATTEMPTS:
                    raise
                continue
            for r in results:
                say(r.measured)
            break
    return session.result()
