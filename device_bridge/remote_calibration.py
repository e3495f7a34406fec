"""Guided calibration driven from the clinic: the leg's side of CALIBRATION_COMMAND and CALIBRATION_RESULT.

The prosthetist follows the device page's prompts (the same as the leg's own,
:data:`device_bridge.osl.calibration.PROMPTS`) and the page asks the leg to measure each step; the leg measures from
its own raw readings over the next control periods and answers with what it measured (one frame per quantity, units
in :data:`~device_bridge.protocol.CALIBRATION_QUANTITIES`) and whether it accepted the step, or why it refused.

Safety: a calibration starts only while the leg runs no table (safe mode, or none yet): the leg gives no torque at all
while it calibrates (:attr:`~device_bridge.protocol.Mode.CALIBRATING`: its readings are not to be trusted until the
end), and ends in safe mode, kept or cancelled; a lost host, a hardware fault or ENTER_SAFE_MODE end it too. A kept
calibration is written by the leg (:class:`CalibrationPort`) before it is used: one that cannot be written changes
nothing. Only a leg that has sensors to calibrate has a port; any other answers NO_SENSORS.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass

import can

from device_bridge.osl.calibration import CalibrationRefusedError, StepResult
from device_bridge.osl.calibration_session import DEFAULT_SAMPLES, CalibrationSession
from device_bridge.osl.config import Calibration
from device_bridge.protocol import (
    CALIBRATION_QUANTITIES,
    CalibrationAction,
    CalibrationOutcome,
    CalibrationRefusal,
    CalibrationStep,
    CalibrationSubject,
    encode,
)

VALUE_SCALE = 1000          # CALIBRATION_RESULT.value: 0.001 of the quantity's unit


@dataclass(frozen=True)
class CalibrationPort:
    """What the firmware needs of a real leg to calibrate it.

    Attributes:
        read: the leg's raw readings now (:data:`device_bridge.osl.calibration_session.RAW_READINGS`).
        keep: run with a calibration from now on, once written where the leg keeps it (raises when it cannot).
        samples: readings per step (one per control period).
    """

    read: Callable[[], Mapping[str, float]]
    keep: Callable[[Calibration], None]
    samples: int = DEFAULT_SAMPLES


def result_frame(session: int, step: int, outcome: CalibrationOutcome, subject: str = "leg",
                 reason: CalibrationRefusal = CalibrationRefusal.NONE, quantity: str = "",
                 value: float = 0.0) -> can.Message:
    """One CALIBRATION_RESULT frame."""
    return encode("CALIBRATION_RESULT", {
        "session": session, "step": step, "outcome": int(outcome), "subject": int(CalibrationSubject[subject.upper()]),
        "reason": int(reason), "quantity": CALIBRATION_QUANTITIES.index(quantity),
        "value": max(min(round(value * VALUE_SCALE), 2**31 - 1), -(2**31))})


def _measured(session: int, step: int, subject: str, values: Mapping[str, float]) -> list[can.Message]:
    return [result_frame(session, step, CalibrationOutcome.MEASURED, subject, quantity=q, value=v)
            for q, v in values.items() if q in CALIBRATION_QUANTITIES and math.isfinite(v)]


class RemoteCalibration:
    """The firmware's calibration from the clinic (module docstring); ``port`` None: a leg with nothing to calibrate.

    Attributes:
        session_: the host's number of the calibration under way (None: none).
    """

    def __init__(self, port: CalibrationPort | None = None) -> None:
        self.port = port
        self.session_: int | None = None
        self._steps: CalibrationSession | None = None

    @property
    def active(self) -> bool:
        return self.session_ is not None

    def end(self) -> None:
        """The calibration ends unkept (the leg left it: safe mode, a lost host)."""
        self.session_, self._steps = None, None

    def command(self, raw: Mapping[str, int], may_start: bool) -> tuple[list[can.Message], bool]:
        """Handle one CALIBRATION_COMMAND (raw signals); ``may_start``: the leg runs no table. Returns the answer's
        frames and whether the leg is calibrating afterwards."""
        session, step = int(raw["session"]), int(raw["step"])
        action = raw["action"]

        def refuse(reason: CalibrationRefusal, subject: str = "leg") -> tuple[list[can.Message], bool]:
            return [result_frame(session, step, CalibrationOutcome.REFUSED, subject, reason)], self.active

        if action == CalibrationAction.START:
            if self.port is None:
                return refuse(CalibrationRefusal.NO_SENSORS)
            if not (may_start or self.active):
                return refuse(CalibrationRefusal.LEG_BUSY)
            self.session_, self._steps = session, CalibrationSession(self.port.samples)
            return [result_frame(session, 0, CalibrationOutcome.STARTED)], True
        steps = self._steps
        if steps is None or session != self.session_ or self.port is None:
            return refuse(CalibrationRefusal.NOT_STARTED)
        if action == CalibrationAction.MEASURE:
            if step not in set(CalibrationStep):
                return refuse(CalibrationRefusal.OUT_OF_ORDER)
            try:
                steps.begin(CalibrationStep(step), raw["body_mass"] / 10.0)
            except CalibrationRefusedError as exc:
                return self._refused(step, exc), True
            return [], True            # answered once the step has its readings (tick)
        if action == CalibrationAction.KEEP:
            try:
                calibration = steps.result()
            except CalibrationRefusedError as exc:
                return self._refused(step, exc), True
            try:
                self.port.keep(calibration)
            except Exception:
                return refuse(CalibrationRefusal.NOT_SAVED)
            self.end()
            return [result_frame(session, 0, CalibrationOutcome.KEPT)], False
        if action == CalibrationAction.CANCEL:
            self.end()
            return [result_frame(session, 0, CalibrationOutcome.CANCELLED)], False
        return refuse(CalibrationRefusal.OUT_OF_ORDER)

    def tick(self) -> list[can.Message]:
        """One control period while calibrating: the step being measured takes this period's reading; its answer
        once it has them all."""
        steps, port, session = self._steps, self.port, self.session_
        if steps is None or port is None or session is None or steps.step_ is None:
            return []
        step = int(steps.step_)
        try:
            results = steps.feed(port.read())
        except CalibrationRefusedError as exc:
            return self._refused(step, exc)
        return [] if results is None else self._accepted(session, step, results)

    @staticmethod
    def _accepted(session: int, step: int, results: tuple[StepResult, ...]) -> list[can.Message]:
        frames = [f for r in results for f in _measured(session, step, r.subject, r.values)]
        return [*frames, result_frame(session, step, CalibrationOutcome.ACCEPTED)]

    def _refused(self, step: int, exc: CalibrationRefusedError) -> list[can.Message]:
        session = self.session_ or 0
        return [*_measured(session, step, exc.subject, exc.values),
                result_frame(session, step, CalibrationOutcome.REFUSED, exc.subject, exc.reason)]
