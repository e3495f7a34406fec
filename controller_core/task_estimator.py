"""Walking speed and incline, once per stride, from the leg's own sensors.

Signals: the thigh's angle from the vertical and its rate (an IMU on the socket), the knee and ankle encoders, and
whether the state machine is in stance. No camera, no treadmill, nothing off the leg.

Method. While the prosthetic foot is flat on the ground it is stationary (the zero-velocity interval that
foot-mounted inertial tracking relies on: Foxlin, "Pedestrian tracking with shoe-mounted inertial sensors", IEEE
Computer Graphics and Applications 25(6), 2005). The foot's pitch from the horizontal is thigh − knee + ankle (the
thigh angle is measured from gravity's vertical; knee flexion +, ankle dorsiflexion +), so:

* **incline** = the foot's pitch while it is flat, which is the slope under it (ground slope from the foot's
  orientation at foot-flat: Stolyarov, Burnett & Herr, "Translational motion tracking of leg joints for enhanced
  prediction of walking tasks", IEEE Trans Biomed Eng 65(4), 2018);
* **speed** = how fast the hip moves along that slope over the stationary ankle, from the leg's forward kinematics
  (thigh and shank lengths, thigh and knee angles): the slope of a straight line fitted to the hip's position
  against time over the flat-foot samples.

Foot-flat: in stance, the foot's pitch rate |thigh rate − knee rate + ankle rate| below ``flat_rate_rad_s``; the
window is the longest such run of the stance (gaps up to ``gap_tolerance_s`` bridged), because a foot can also rest
briefly on its heel at heel strike, where the pitch is steady but is not the slope. A stride whose flat-foot window
is shorter than ``min_flat_s``, or whose estimate is not a walking task, gives no estimate. A still foot on its toe
with the heel up is not flat either: given the forefoot rocker's distance ahead of the ankle (``forefoot_m``), a run
whose every sample has its centre of pressure (−ankle moment / load) beyond ``heel_off_fraction`` of it is left out.
It happened in mid-stance at 1.3 m/s (a still foot pitched 3° toe-down, read as a 3° downhill, every other stride) and
at the top of a ramp (−7° read on level ground): on the `frequent` course the incline from the second stride after a
change was within ±1.5° on 88 % of strides, 98 % without those runs.

The estimate is the mean of the last ``smoothing_strides`` strides' estimates, except across a change: where the
newest stride's reading differs from the one before by more than the estimate's resolution (0.1 m/s, 1.5°), the newest
alone (a mean across a change of task is wrong for both sides of it: from the second stride after a change the
incline was within ±1.5° on 79 % of strides on the `frequent` course with the plain mean, 88 % with this rule; speed
84 → 98 %). Speed and incline each have their own
confidence, the mean quality of those strides (0 for a stride without an estimate): for speed, the
window's length and how straight the hip's progress along the slope is (a foot that slides, e.g. a straight knee
slapping down on a ramp, bends it); for incline, the window's length and how steady the foot's pitch is. They are
separate because the foot's orientation gives the slope even when the foot slides, and the slope is the thing a
leg on the wrong table for a ramp most needs to know.

Caveat: people's hips move a little slower than their average speed in mid-stance (the inverted pendulum's
highest point), so on a person this reads a few percent low; on the simulated bench the socket moves at constant
speed along the floor. Units: SI in (rad, rad/s, s, m), m/s and deg out.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field

from controller_core.fsm import SensorSample
from controller_core.units import require_positive

RAD_TO_DEG = 180.0 / math.pi
# the estimate's resolution: the accuracy it holds on at least 90 % of strides on the bench's courses (±0.1 m/s,
# ±1.5°, `quasitune compare --course mixed`). Tasks closer than this cannot be told apart, so
# a task this close to an envelope's edge counts as inside it (not "clamped", not "beyond its edge").
SPEED_RESOLUTION_MPS = 0.1
INCLINE_RESOLUTION_DEG = 1.5
HEEL_OFF_MIN_LOAD_N = 50.0   # below this the centre of pressure is too uncertain to say where the foot rests


@dataclass(frozen=True, slots=True)
class StrideTask:
    """One stride's own estimate (before smoothing); ``valid`` False when the stride gave none."""

    time_s: float
    speed_mps: float
    incline_deg: float
    flat_s: float
    fit_rms_m: float
    pitch_sd_deg: float
    speed_quality: float
    incline_quality: float
    valid: bool


@dataclass(frozen=True, slots=True)
class TaskEstimate:
    """The smoothed task after a stride.

    Attributes:
        time_s: the heel strike at which it was made (s).
        speed_mps, incline_deg: the smoothed estimate (NaN before any stride gave one).
        speed_confidence, incline_confidence: 0–1 each (see the module docstring).
        speed_confident, incline_confident: that confidence at or above the estimator's threshold.
        stride: the last stride's own estimate.
    """

    time_s: float
    speed_mps: float
    incline_deg: float
    speed_confidence: float
    incline_confidence: float
    speed_confident: bool
    incline_confident: bool
    stride: StrideTask

    @property
    def confidence(self) -> float:
        """The lower of the two confidences."""
        return min(self.speed_confidence, self.incline_confidence)


@dataclass
class TaskEstimator:
    """Per-stride speed and incline from on-leg signals (see the module docstring).

    Args:
        thigh_length_m: hip to knee axis (m) of the patient's residual limb and socket.
        shank_length_m: knee to ankle axis (m) of the prosthesis.
        flat_rate_rad_s: foot-flat when the foot's pitch rate is below this (rad/s; 0.35 ≈ 20°/s).
        min_flat_s: shortest flat-foot window that gives an estimate (s).
        smoothing_strides: strides averaged.
        confidence_threshold: the estimate is ``confident`` at or above this.
        full_quality_flat_s: a flat-foot window this long (s) or longer counts fully.
        fit_scale_m: the straight-line fit's rms residual (m) at which a stride's speed quality halves.
        pitch_scale_deg: the foot pitch's SD over the window (deg) at which a stride's incline quality halves.
        gap_tolerance_s: non-flat samples for up to this long (s) do not end a flat-foot run.
        forefoot_m: the forefoot rocker's distance ahead of the ankle (m; the bench's foot: its toe contact); None
            (a load cell without a sagittal moment) leaves toe-only runs in.
        heel_off_fraction: a flat-foot sample whose centre of pressure lies beyond this fraction of ``forefoot_m``
            (with more than ``HEEL_OFF_MIN_LOAD_N`` on the leg) has the heel up; a run of only such samples is left out.
    """

    thigh_length_m: float
    shank_length_m: float
    flat_rate_rad_s: float = 0.35
    min_flat_s: float = 0.08
    smoothing_strides: int = 2
    confidence_threshold: float = 0.5
    full_quality_flat_s: float = 0.15
    fit_scale_m: float = 0.005
    pitch_scale_deg: float = 1.0
    gap_tolerance_s: float = 0.01
    forefoot_m: float | None = None
    heel_off_fraction: float = 0.8
    strides_: deque = field(init=False)
    last_: TaskEstimate | None = field(init=False, default=None)
    _in_stance: bool = field(init=False, default=False)
    _seen_stance: bool = field(init=False, default=False)
    _sums: list[float] = field(init=False)
    _best: list[float] = field(init=False)
    _t0: float | None = field(init=False, default=None)
    _last_flat_s: float = field(init=False, default=-math.inf)
    _heel_down: bool = field(init=False, default=False)    # the current run has a sample with the heel down

    def __post_init__(self) -> None:
        require_positive(self, ("thigh_length_m", "shank_length_m", "flat_rate_rad_s", "min_flat_s",
                                "full_quality_flat_s", "fit_scale_m", "pitch_scale_deg", "gap_tolerance_s"))
        if not (isinstance(self.smoothing_strides, int) and 1 <= self.smoothing_strides <= 10):
            raise ValueError(f"smoothing_strides must be an integer in [1, 10], got {self.smoothing_strides!r}")
        if not 0.0 < self.confidence_threshold <= 1.0:
            raise ValueError(f"confidence_threshold must be in (0, 1], got {self.confidence_threshold!r}")
        if self.forefoot_m is not None:
            require_positive(self, ("forefoot_m",))
        if not 0.0 < self.heel_off_fraction <= 1.0:
            raise ValueError(f"heel_off_fraction must be in (0, 1], got {self.heel_off_fraction!r}")
        self.strides_ = deque(maxlen=self.smoothing_strides)
        self._clear()

    def _clear(self) -> None:
        # the current run's n, Σt, Σt², Σx, Σtx, Σx², Σz, Σtz, Σz², Σpitch, first t, last t, Σxz, Σpitch² (t from the
        # stance's first flat sample); _best: the longest run closed so far in this stance
        self._sums = [0.0] * 14
        self._best = [0.0] * 14
        self._t0 = None
        self._last_flat_s = -math.inf
        self._heel_down = False

    def _run_beats_best(self) -> bool:
        """The run going now counts (it has a sample with the heel down) and is longer than the best closed one."""
        s, b = self._sums, self._best
        return bool(s[0]) and self._heel_down and (not b[0] or s[11] - s[10] > b[11] - b[10])

    def _end_run(self) -> None:
        if self._run_beats_best():
            self._best = self._sums
        self._sums = [0.0] * 14
        self._heel_down = False

    def reset(self) -> None:
        """Forget every stride (a new walk)."""
        self.strides_.clear()
        self.last_ = None
        self._in_stance = False
        self._seen_stance = False
        self._clear()

    def update(self, x: SensorSample, stance: bool) -> TaskEstimate | None:
        """Take one sample; at each heel strike (stance begins) return the new estimate, else None.

        Args:
            x: the sensor sample (needs the thigh angle and rate; NaN samples are ignored).
            stance: the state machine is in a stance state.
        """
        out = None
        if stance and not self._in_stance:
            if self._seen_stance:   # every heel strike after the first closes a stride, with or without data
                out = self._close_stride(x.time_s)
            self._seen_stance = True
            self._clear()
        self._in_stance = stance
        if stance:
            self._accumulate(x)
        return out

    def _accumulate(self, x: SensorSample) -> None:
        th, thd = x.thigh_angle_rad, x.thigh_velocity_rad_s
        if not (math.isfinite(th) and math.isfinite(thd)):
            return
        pitch_rate = thd - x.knee_velocity_rad_s + x.ankle_velocity_rad_s
        if x.time_s - self._last_flat_s > self.gap_tolerance_s + 1e-9 and self._sums[0]:
            self._end_run()
        if abs(pitch_rate) > self.flat_rate_rad_s:
            return
        self._last_flat_s = x.time_s
        if not self._heel_down:
            self._heel_down = not self._heel_up(x)
        shank = th - x.knee_angle_rad
        # the hip relative to the (stationary) ankle: minus the ankle's position from the hip
        hx = -(self.thigh_length_m * math.sin(th) + self.shank_length_m * math.sin(shank))
        hz = self.thigh_length_m * math.cos(th) + self.shank_length_m * math.cos(shank)
        if self._t0 is None:
            self._t0 = x.time_s
        t = x.time_s - self._t0
        s = self._sums
        s[0] += 1.0
        s[1] += t
        s[2] += t * t
        s[3] += hx
        s[4] += t * hx
        s[5] += hx * hx
        s[6] += hz
        s[7] += t * hz
        s[8] += hz * hz
        pitch = shank + x.ankle_angle_rad
        s[9] += pitch
        s[12] += hx * hz
        s[13] += pitch * pitch
        if s[0] == 1.0:
            s[10] = t
        s[11] = t

    def _heel_up(self, x: SensorSample) -> bool:
        """The sample's centre of pressure lies at the forefoot (module docstring): the heel is up."""
        if self.forefoot_m is None or not (x.load_N > HEEL_OFF_MIN_LOAD_N and math.isfinite(x.ankle_moment_Nm)):
            return False
        return -x.ankle_moment_Nm / x.load_N > self.heel_off_fraction * self.forefoot_m

    def provisional(self, now_s: float) -> StrideTask | None:
        """This stance's own estimate so far, once its flat-foot window has lasted ``full_quality_flat_s`` (the
        longest run yet, the one still going included), else None: the slope and speed of the stride under way,
        before its push-off and swing (not smoothed with earlier strides, and not kept: the stride's estimate is made
        again when it closes)."""
        if not self._in_stance:
            return None
        s = self._sums if self._run_beats_best() else self._best
        if not s[0] or s[11] - s[10] < self.full_quality_flat_s:
            return None
        return self._stride_task(s, now_s)

    def _close_stride(self, now_s: float) -> TaskEstimate:
        self._end_run()
        stride = self._stride_task(self._best, now_s)
        self.strides_.append(stride)
        valid = [st for st in self.strides_ if st.valid]
        span = self.strides_.maxlen or 1
        speed_conf = sum(st.speed_quality for st in self.strides_) / span
        incline_conf = sum(st.incline_quality for st in self.strides_) / span
        speed = _mean_since_change([st.speed_mps for st in valid], SPEED_RESOLUTION_MPS)
        incline = _mean_since_change([st.incline_deg for st in valid], INCLINE_RESOLUTION_DEG)
        threshold = self.confidence_threshold
        self.last_ = TaskEstimate(now_s, speed, incline, speed_conf, incline_conf,
                                  bool(valid) and speed_conf >= threshold, bool(valid) and incline_conf >= threshold,
                                  stride)
        return self.last_

    def _stride_task(self, s: list[float], now_s: float) -> StrideTask:
        """The estimate of one flat-foot run's sums (see the module docstring); ``valid`` False when it gives none."""
        n = s[0]
        flat_s = s[11] - s[10] if n else 0.0
        stride = StrideTask(now_s, math.nan, math.nan, flat_s, math.nan, math.nan, 0.0, 0.0, False)
        if n >= 3 and flat_s >= self.min_flat_s:
            stt = s[2] - s[1] * s[1] / n
            if stt > 0.0:
                slope_x = (s[4] - s[1] * s[3] / n) / stt
                slope_z = (s[7] - s[1] * s[6] / n) / stt
                pitch = s[9] / n
                pitch_sd_deg = math.sqrt(max(s[13] / n - pitch * pitch, 0.0)) * RAD_TO_DEG
                speed = slope_x * math.cos(pitch) + slope_z * math.sin(pitch)
                # rms residual of the hip's progress along the slope about its straight line, from the sums
                c, si = math.cos(pitch), math.sin(pitch)
                rxx = s[5] - s[3] * s[3] / n - slope_x * (s[4] - s[1] * s[3] / n)
                rzz = s[8] - s[6] * s[6] / n - slope_z * (s[7] - s[1] * s[6] / n)
                rxz = s[12] - s[3] * s[6] / n - slope_x * (s[7] - s[1] * s[6] / n)
                rms = math.sqrt(max(c * c * rxx + si * si * rzz + 2.0 * c * si * rxz, 0.0) / n)
                incline = pitch * RAD_TO_DEG
                if 0.1 <= speed <= 3.0 and abs(incline) <= 20.0:
                    length = min(1.0, flat_s / self.full_quality_flat_s)
                    stride = StrideTask(now_s, speed, incline, flat_s, rms, pitch_sd_deg,
                                        length / (1.0 + (rms / self.fit_scale_m) ** 2),
                                        length / (1.0 + (pitch_sd_deg / self.pitch_scale_deg) ** 2), True)
        return stride


def _mean_since_change(values: list[float], resolution: float) -> float:
    """The mean of the strides' readings (oldest first), or the newest alone when it differs from the one before by
    more than the estimate's resolution: a change of task, which a mean across it would put half-way (NaN: none)."""
    if not values:
        return math.nan
    if len(values) >= 2 and abs(values[-1] - values[-2]) > resolution:
        return values[-1]
    return sum(values) / len(values)

