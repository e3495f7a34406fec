"""The host's side of guided calibration from the clinic: send CALIBRATION_COMMAND, gather the leg's answer.

The leg answers each command with one CALIBRATION_RESULT frame per quantity it measured and one closing frame
(:mod:`device_bridge.remote_calibration`); :class:`CalibrationAnswer` is that answer with its words
(:func:`device_bridge.osl.calibration.measured_words`, :func:`~device_bridge.osl.calibration.refusal_words`: the same
words the leg's own prompts say). Each calibration has a session number (one byte, from the host), so a late answer
to an earlier one is never taken for this one's.
"""

from __future__ import annotations

import math
import queue
import threading
from collections.abc import Callable
from dataclasses import dataclass, field

import can

from device_bridge.clock import Clock
from device_bridge.osl.calibration import measured_words, refusal_words
from device_bridge.protocol import (
    CALIBRATION_QUANTITIES,
    CalibrationAction,
    CalibrationOutcome,
    CalibrationRefusal,
    CalibrationStep,
    CalibrationSubject,
    encode,
)
from device_bridge.remote_calibration import VALUE_SCALE

STEP_NAMES = {s: s.name.lower() for s in CalibrationStep}
SUBJECT_NAMES = {s: s.name.lower() for s in CalibrationSubject}
MAX_BODY_MASS_RAW = 0xFFFF


class CalibrationTimeoutError(TimeoutError):
    """The leg did not answer a calibration command in time (an older leg's firmware ignores them)."""


@dataclass(frozen=True)
class Measured:
    """What one step measured about one subject (``knee``, ``ankle``, ``loadcell``): values with their unit in the
    name, and in words."""

    subject: str
    values: dict[str, float]
    words: str


@dataclass(frozen=True)
class CalibrationAnswer:
    """The leg's answer to one calibration command.

    Attributes:
        step: the step it is about (``joint_zero``, ``direction``, ``loadcell_zero``, ``loadcell_sign``), None for the
            calibration as a whole (started, kept, cancelled).
        outcome: ``started``, ``accepted``, ``refused``, ``kept`` or ``cancelled``.
        measured: what the step measured, per subject (also for a refused step: what made it refuse).
        refused_reason, refused_subject, refused_words: why it was refused (None when it was not).
    """

    step: str | None
    outcome: str
    measured: list[Measured] = field(default_factory=list)
    refused_reason: str | None = None
    refused_subject: str | None = None
    refused_words: str | None = None


class CalibrationClient:
    """Sends a link's calibration commands and gathers their answers (fed by the link's receive path: :meth:`add`)."""

    def __init__(self, send: Callable[[can.Message], None], clock: Clock) -> None:
        self._send = send
        self._clock = clock
        self._answers: queue.Queue[dict[str, int]] = queue.Queue()
        self._lock = threading.Lock()      # one command at a time: its answer is the next closing frame
        self.session_ = 0

    def add(self, raw: dict[str, int]) -> None:
        self._answers.put(raw)

    def command(self, action: CalibrationAction, step: CalibrationStep | None = None, body_mass_kg: float = 0.0,
                timeout_s: float = 3.0) -> CalibrationAnswer:
        """Send one command (START opens a new session) and wait for the leg's whole answer (CalibrationTimeoutError
        after ``timeout_s``)."""
        if not math.isfinite(body_mass_kg) or body_mass_kg < 0:
            raise ValueError(f"body mass must be a finite number of kg ≥ 0, got {body_mass_kg!r}")
        with self._lock:
            return self._command(action, step, body_mass_kg, timeout_s)

    def _command(self, action: CalibrationAction, step: CalibrationStep | None, body_mass_kg: float,
                 timeout_s: float) -> CalibrationAnswer:
        if action == CalibrationAction.START:
            self.session_ = self.session_ % 255 + 1
        while not self._answers.empty():      # what came before this command is no answer to it
            self._answers.get_nowait()
        session = self.session_
        self._send(encode("CALIBRATION_COMMAND", {
            "session": session, "action": int(action), "step": int(step or 0),
            "body_mass": min(round(body_mass_kg * 10), MAX_BODY_MASS_RAW)}))
        until = self._clock.monotonic() + timeout_s
        measured: dict[str, dict[str, float]] = {}
        while True:
            left = until - self._clock.monotonic()
            try:
                raw = self._clock.get(self._answers, left) if left > 0 else None
            except queue.Empty:
                raw = None
            if raw is None:
                raise CalibrationTimeoutError(f"the leg did not answer the calibration command within {timeout_s:g} "
                                              "s (a leg whose firmware predates calibration from the clinic ignores "
                                              "it: use quasitune leg --calibrate on the leg)")
            if raw["session"] != session or raw["outcome"] not in set(CalibrationOutcome):
                continue                      # an earlier calibration's answer, or an outcome this link does not know
            subject = SUBJECT_NAMES.get(CalibrationSubject(raw["subject"]), "leg")
            outcome = CalibrationOutcome(raw["outcome"])
            if outcome == CalibrationOutcome.MEASURED:
                q = raw["quantity"]
                if 0 < q < len(CALIBRATION_QUANTITIES):
                    measured.setdefault(subject, {})[CALIBRATION_QUANTITIES[q]] = raw["value"] / VALUE_SCALE
                continue
            return _answer(raw, outcome, subject, measured)


def _answer(raw: dict[str, int], outcome: CalibrationOutcome, subject: str,
            measured: dict[str, dict[str, float]]) -> CalibrationAnswer:
    step = STEP_NAMES.get(CalibrationStep(raw["step"])) if raw["step"] in set(CalibrationStep) else None
    if outcome != CalibrationOutcome.REFUSED:
        return CalibrationAnswer(step, outcome.name.lower(), [Measured(s, v, measured_words(s, v))
                                                              for s, v in measured.items()])
    code = raw["reason"]
    reason = CalibrationRefusal(code) if code in set(CalibrationRefusal) else CalibrationRefusal.NONE
    words = refusal_words(reason, subject, measured.get(subject, {}))
    return CalibrationAnswer(step, "refused", [Measured(s, v, words) for s, v in measured.items()],
                             reason.name.lower(), subject, words)
