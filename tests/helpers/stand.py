"""A leg in a stand, posed by hand, whose sensors are mounted reversed and off their zero: what guided calibration
from the clinic has to find (synthetic readings of a held pose, for the tests; the leg environment's tests calibrate
the MuJoCo bench behind the Open Source Leg SDK instead, tests/leg).

It is a leg to the device node (``sample``/``step``, and a real leg's ``leg_state``/``take_fault``), reading through
the calibration it runs with, and its :meth:`Stand.port` is the firmware's calibration port: the raw readings of the
pose held now, and a calibration kept in :attr:`Stand.kept` (or refused to be written: ``disk_full``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from controller_core.fsm import SensorSample
from device_bridge.osl.config import Calibration
from device_bridge.remote_calibration import CalibrationPort

DEG = math.pi / 180.0


@dataclass
class Stand:
    """Joint angles (rad, QuasiTune's convention) and the pylon's load (N) held now; the sensors' mounting."""

    knee_rad: float = 0.0
    ankle_rad: float = 0.0
    load_N: float = 0.0
    jitter_rad: float = 0.0       # a hand that does not hold still: readings alternate ± this
    knee_sign: int = -1
    knee_offset_rad: float = 0.52
    ankle_offset_rad: float = -0.11
    fz_sign: int = -1
    fz_offset_N: float = -140.0
    calibration: Calibration = field(default_factory=Calibration)
    kept: list[Calibration] = field(default_factory=list)
    disk_full: bool = False
    _reads: int = 0

    def pose(self, knee_deg: float, ankle_deg: float, load_N: float = 0.0) -> None:
        self.knee_rad, self.ankle_rad, self.load_N = knee_deg * DEG, ankle_deg * DEG, load_N

    def read(self) -> dict[str, float]:
        """The raw readings (the calibration port's): a shaky hand alternates from one reading to the next."""
        self._reads += 1
        return self._raw(self.jitter_rad * (1 if self._reads % 2 else -1))

    def _raw(self, wobble: float = 0.0) -> dict[str, float]:
        knee = self.knee_sign * (self.knee_rad + wobble) + self.knee_offset_rad
        ankle = self.ankle_rad + self.ankle_offset_rad
        return {"knee": knee, "knee_actuator": self.knee_rad, "ankle": ankle, "ankle_actuator": ankle,
                "fz": self.fz_sign * self.load_N + self.fz_offset_N, "my": 2.5}

    def keep(self, calibration: Calibration) -> None:
        if self.disk_full:
            raise OSError("no space left on device")
        self.kept.append(calibration)
        self.calibration = calibration

    def port(self, samples: int = 20) -> CalibrationPort:
        return CalibrationPort(self.read, self.keep, samples)

    # the device node's leg
    def sample(self) -> SensorSample:
        raw, cal = self._raw(), self.calibration
        return SensorSample(0.0, cal.knee.sign * (raw["knee"] - cal.knee.zero_rad), 0.0,
                            cal.ankle.sign * (raw["ankle"] - cal.ankle.zero_rad), 0.0,
                            cal.loadcell.fz_sign * (raw["fz"] - cal.loadcell.fz_zero_N), 0.0)

    def step(self, knee_torque_Nm: float, ankle_torque_Nm: float) -> None:
        self.torques = (knee_torque_Nm, ankle_torque_Nm)

    @property
    def drives(self) -> bool:
        """As a hardware leg: no torque until every sensor is calibrated."""
        c = self.calibration
        return c.knee.calibrated and c.ankle.calibrated and c.loadcell.calibrated

    def take_fault(self) -> None:
        return None

    def leg_state(self) -> dict[str, int]:
        c = self.calibration
        return {"hardware": 1, "calibrated": int(c.knee.calibrated) | int(c.ankle.calibrated) << 1
                | int(c.loadcell.calibrated) << 2, "torque_mode": 0, "derating": 255}
