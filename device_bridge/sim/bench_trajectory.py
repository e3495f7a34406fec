"""What the bench does at a task: the person's thigh angle, the path their hip would take, and their other leg's push.

For a task the bench replays the able-bodied pattern of :class:`controller_core.walking_reference.WalkingReference`.
The socket's forward position and thigh angle are driven (the person walks); its height is free and carries the body
(:mod:`device_bridge.sim.plant`, :mod:`device_bridge.sim.person`). The path below is where the hip *would* be if the
prosthesis did what the reference leg does: the height the body sinks below it is what the prosthesis failed to carry.

* **Thigh angle** φ(s) (rad, from vertical, flexion +) = hip flexion − c, where the constant c makes the
  reference foot flat on the (tilted) floor over mid-stance (15–40 % of the cycle): the foot's pitch is
  φ − knee + ankle, so c = mean(hip − knee + ankle) − incline. c absorbs the pelvic tilt the hip angle is
  measured from (about 5–7° in the shipped data).
* **Forward progression**: the hip moves along the floor at the task speed (belt speed), as on a treadmill.
* **The hip's height over the prosthesis's stance** is the prosthesis's own reference leg's: the height at which the
  reference leg, with the reference angles, touches the floor with its lowest contact, so a leg that does what
  people's does lands on time and carries the body at the height people's does (:func:`hip_path_m`).
* **Over its swing** the body rides on the other leg, whose push is the reference's: the height follows what the
  reference vertical forces do to the body (integrated twice), shifted by a straight line to meet the stance path at
  toe-off and at the next heel strike; where the reference leg would pass closer than :data:`SWING_CLEARANCE_M` to the
  floor (a sagittal bench has no pelvic list) the hip rises by a smooth hike.
* **The other leg's push**: the reference's contralateral vertical ground force (the ipsilateral one half a cycle on),
  each leg's share scaled so that it carries exactly half the weight over a stride; over the prosthesis's swing,
  whatever keeps the body on its path (the prosthesis carries nothing then, so this is the reference force plus any
  hike).

The periodic signals are smoothed by keeping their first :data:`HARMONICS` harmonics (the data are 101-point means and
the stance-to-swing joins have corners), which also gives their derivatives analytically.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from controller_core.units import G_MPS2
from controller_core.walking_reference import WalkingReference
from device_bridge.sim.leg_model import LegGeometry

MID_STANCE = (0.15, 0.40)
HARMONICS = 12              # harmonics kept when smoothing the periodic socket signals
SWING_CLEARANCE_M = 0.015   # least swing-foot clearance of a leg with the reference angles (people: 1-2 cm)
CLEARANCE_BLEND = 0.06      # phase over which that clearance is blended in after toe-off and out before heel strike
HIKE_HALF_WIDTH = 0.12      # phase from a hike's top to where it has blended out


def fourier_coefficients(values: np.ndarray, harmonics: int) -> tuple[np.ndarray, np.ndarray]:
    """Cosine/sine coefficients (a, b) of a periodic signal sampled on [0, 1) (last grid point dropped)."""
    y = values[:-1] if values.shape[0] == 101 else values
    n = y.shape[0]
    c = np.fft.rfft(y) / n
    a = 2.0 * c.real[: harmonics + 1]
    b = -2.0 * c.imag[: harmonics + 1]
    a[0] /= 2.0
    return a, b


def eval_fourier(a: np.ndarray, b: np.ndarray, s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Value, d/ds and d²/ds² of the series at phases s."""
    k = np.arange(a.shape[0])
    w = 2.0 * np.pi * k
    ang = np.outer(s, w)
    c, sn = np.cos(ang), np.sin(ang)
    return c @ a + sn @ b, (-sn * w) @ a + (c * w) @ b, -(c * w * w) @ a - (sn * w * w) @ b


def thigh_angle_rad(ref: WalkingReference, incline_deg: float) -> np.ndarray:
    """Thigh angle from vertical (rad, flexion +) on the reference grid (see module docstring)."""
    s = ref.phase
    mid = (s >= MID_STANCE[0]) & (s <= MID_STANCE[1])
    c = float(np.mean((ref.hip_angle_rad - ref.knee_angle_rad + ref.ankle_angle_rad)[mid])) - math.radians(incline_deg)
    return ref.hip_angle_rad - c


def touching_hip_height_m(thigh: np.ndarray | float, knee: np.ndarray | float, ankle: np.ndarray | float,
                          geometry: LegGeometry, incline_deg: float) -> np.ndarray:
    """Hip height above the floor (m, along the normal) at which the leg's lowest contact (heel or forefoot sphere)
    touches it (per phase for arrays; one pose for plain angles)."""
    g = geometry
    alpha = math.radians(incline_deg)
    shank = thigh - knee
    pitch = shank + ankle
    kx, kz = g.thigh_m * np.sin(thigh), -g.thigh_m * np.cos(thigh)
    ax, az = kx + g.shank_m * np.sin(shank), kz - g.shank_m * np.cos(shank)
    zc = -g.ankle_height_m + g.contact_radius_m
    lowest = None
    for xf in (-g.heel_back_m, g.toe_forward_m):
        px = ax + xf * np.cos(pitch) - zc * np.sin(pitch)
        pz = az + xf * np.sin(pitch) + zc * np.cos(pitch)
        normal = -px * math.sin(alpha) + pz * math.cos(alpha)
        lowest = normal if lowest is None else np.minimum(lowest, normal)
    return g.contact_radius_m - lowest


def _leg_share(ref: WalkingReference) -> float:
    """The factor that makes one leg's reference force carry exactly half the weight over a stride (the shipped
    means are 0.516-0.523 body weights)."""
    return 0.5 / float(np.mean(ref.vgrf_bw[:-1]))


def other_leg_share_bw(ref: WalkingReference) -> np.ndarray:
    """The other leg's vertical force on the reference grid (body weights): the reference force half a cycle on,
    scaled so each leg carries exactly half the weight over a stride."""
    return _leg_share(ref) * np.interp((ref.phase + 0.5) % 1.0, ref.phase, ref.vgrf_bw)


def _swing_height_m(ref: WalkingReference, touch: np.ndarray) -> np.ndarray:
    """The hip height over the whole stride: ``touch`` over the stance, over the swing what the reference forces do
    to the body, joined by a straight line and lifted where the reference foot would pass too close (module
    docstring)."""
    s, to, T = ref.phase, ref.toe_off_phase, ref.stride_time_s
    both = _leg_share(ref) * ref.vgrf_bw + other_leg_share_bw(ref)
    acc = T * T * G_MPS2 * (both - 1.0)                     # d²z/ds² of the body under both legs' forces (m)
    ds = np.diff(s)
    vel = np.concatenate([[0.0], np.cumsum(0.5 * (acc[1:] + acc[:-1]) * ds)])
    free = np.concatenate([[0.0], np.cumsum(0.5 * (vel[1:] + vel[:-1]) * ds)])
    swing = s > to
    z_to, z_hs = float(np.interp(to, s, touch)), float(touch[0])
    free = free - float(np.interp(to, s, free))
    base = free + z_to + (s - to) * (z_hs - free[-1] - z_to) / (1.0 - to)
    ramp = np.clip(np.minimum(s - to, 1.0 - s) / CLEARANCE_BLEND, 0.0, 1.0)
    short = np.where(swing, np.maximum(touch + SWING_CLEARANCE_M * ramp - base, 0.0), 0.0)
    lift = np.zeros_like(s)
    for i in np.flatnonzero(short > 0.0):   # a raised-cosine hike over each shortfall, as high as the shortfall
        lift = np.maximum(lift, short[i] * 0.5 * (1.0 + np.cos(np.pi * np.clip((s - s[i]) / HIKE_HALF_WIDTH, -1, 1))))
    return np.where(swing, base + lift * ramp, touch)   # no hike at toe-off and heel strike: the path joins there


def hip_path_m(ref: WalkingReference, geometry: LegGeometry) -> tuple[np.ndarray, np.ndarray]:
    """The hip path at the reference's task on its grid: (thigh angle rad, height above the floor along its normal
    m), see the module docstring."""
    thigh = thigh_angle_rad(ref, ref.incline_deg)
    touch = touching_hip_height_m(thigh, ref.knee_angle_rad, ref.ankle_angle_rad, geometry, ref.incline_deg)
    return thigh, _swing_height_m(ref, touch)


@dataclass(frozen=True)
class TaskPattern:
    """What the bench replays at one task: Fourier coefficients (a then b) of the thigh angle (rad) and the hip height
    (m) on the phase, the other leg's share on the reference grid (body weights), toe-off (phase) and the stride time
    (s)."""

    thigh: np.ndarray
    height: np.ndarray
    other_bw: np.ndarray
    toe_off_phase: float
    stride_time_s: float


def task_pattern_series(ref: WalkingReference, geometry: LegGeometry, harmonics: int = HARMONICS) -> TaskPattern:
    """The bench's pattern at the reference's task (see :class:`TaskPattern`)."""
    thigh, height = hip_path_m(ref, geometry)
    return TaskPattern(thigh=np.concatenate(fourier_coefficients(thigh, harmonics)),
                       height=np.concatenate(fourier_coefficients(height, harmonics)),
                       other_bw=other_leg_share_bw(ref), toe_off_phase=ref.toe_off_phase,
                       stride_time_s=ref.stride_time_s)


def other_leg_push_N(phase: np.ndarray, toe_off: np.ndarray | float, share_bw: np.ndarray,
                     height_accel_m_s2: np.ndarray, slope_rad: np.ndarray | float, mass_kg: float
                     ) -> tuple[np.ndarray, np.ndarray]:
    """The other leg per tick: its vertical push (N) and whether its foot is down. The push is its reference share
    (``share_bw``, body weights per tick) over the prosthesis's stance; over its swing, when the other foot carries
    the body, what keeps the body on its path (weight plus mass × the path's vertical acceleration, from the height's
    acceleration along the floor normal)."""
    swing = phase > toe_off
    carry = mass_kg * (G_MPS2 + height_accel_m_s2 * np.cos(slope_rad))
    return np.where(swing, np.maximum(carry, 0.0), share_bw * mass_kg * G_MPS2), (share_bw > 0.0) | swing


@dataclass(frozen=True)
class BenchTrajectory:
    """Sampled socket trajectory and the other leg's push for a whole run (arrays of one length, one row per tick).

    Attributes:
        time_s: tick times (s).
        phase: bench gait phase in [0, 1) (0 = reference heel strike).
        x_m, z_m, hip_rad: the hip's path and the thigh angle in world coordinates (m, m, rad).
        xd_m_s, zd_m_s, hipd_rad_s: their velocities.
        height_m: the path's height above the floor along its normal (m).
        other_leg_N: the other leg's reference push (N, up).
        other_foot_down: whether the other foot is on the floor (its reference force is positive).
        stance: whether the prosthesis is in its reference stance (phase up to toe-off).
        stride_time_s: bench cycle time (s).
    """

    time_s: np.ndarray
    phase: np.ndarray
    x_m: np.ndarray
    z_m: np.ndarray
    hip_rad: np.ndarray
    xd_m_s: np.ndarray
    zd_m_s: np.ndarray
    hipd_rad_s: np.ndarray
    height_m: np.ndarray
    other_leg_N: np.ndarray
    other_foot_down: np.ndarray
    stance: np.ndarray
    stride_time_s: float


def plan_bench_trajectory(ref: WalkingReference, geometry: LegGeometry, mass_kg: float, seconds: float,
                          timestep_s: float = 0.001, start_phase: float = 0.85, harmonics: int = HARMONICS,
                          t0_s: float = 0.0) -> BenchTrajectory:
    """Sample the socket's path and the other leg's push for ``seconds`` of walking at the reference's task, from
    time ``t0_s`` (a later chunk of the same walk continues the earlier one exactly)."""
    pattern = task_pattern_series(ref, geometry, harmonics)
    h2 = pattern.thigh.shape[0] // 2
    T = ref.stride_time_s
    n = round(seconds / timestep_s)
    t = t0_s + np.arange(n) * timestep_s
    s = (start_phase + t / T) % 1.0
    th, dth, _ = eval_fourier(pattern.thigh[:h2], pattern.thigh[h2:], s)
    h, dh, ddh = eval_fourier(pattern.height[:h2], pattern.height[h2:], s)
    alpha = math.radians(ref.incline_deg)
    v = ref.speed_mps
    u = v * t
    x = u * math.cos(alpha) - h * math.sin(alpha)
    z = u * math.sin(alpha) + h * math.cos(alpha)
    hd = dh / T
    xd = v * math.cos(alpha) - hd * math.sin(alpha)
    zd = v * math.sin(alpha) + hd * math.cos(alpha)
    share = np.interp(s, ref.phase, pattern.other_bw)
    other, foot_down = other_leg_push_N(s, ref.toe_off_phase, share, ddh / (T * T), alpha, mass_kg)
    return BenchTrajectory(time_s=t, phase=s, x_m=x, z_m=z, hip_rad=th, xd_m_s=xd, zd_m_s=zd, hipd_rad_s=dth / T,
                           height_m=h, other_leg_N=other, other_foot_down=foot_down,
                           stance=s <= ref.toe_off_phase, stride_time_s=T)


# a start from quiet standing (issue 53): the bench used to start every walk in late swing at belt speed with the
# joints' velocities zero, so the foot landed ~90 ms early on a knee bent ~30° and downhill every controller fell.
# The walk begins at the prosthesis's heel strike: the walking pattern's double support, which standing's two loaded
# feet become; the other leg lifts at its toe-off (prosthesis phase ~0.1) and takes the first step. The ramp ends
# before that leg lands again (phase 0.5), so the prosthesis's unloading and toe-off are the walking pattern's: begun
# at 0.1, the ramp ran past the other leg's landing, the prosthesis stayed loaded late (toe-off at 0.62 against
# 0.56 at 1.4 m/s −10°), its first swing was short, it landed early on a 22° knee and folded.
STANDING_START_PHASE = 0.0
INITIATION_STRIDES = 0.45       # the ramp into walking: done before the other leg's first landing (phase 0.5)
STANDING_KNEE_RAD = math.radians(3.0)
STANDING_SHARE_BW = 0.5         # the prosthesis's share of the weight while standing
STAND_S = 1.0                   # quiet standing before the first step (s)


def standing_pose_rad(incline_deg: float) -> tuple[float, float, float]:
    """(thigh, knee, ankle) of quiet standing on a floor of ``incline_deg``: thigh vertical, knee at 3°, the foot
    flat on the floor (thigh − knee + ankle = incline)."""
    thigh = 0.0
    return thigh, STANDING_KNEE_RAD, math.radians(incline_deg) - thigh + STANDING_KNEE_RAD


def held_until(walk: BenchTrajectory, n: int) -> BenchTrajectory:
    """``walk`` preceded by ``n`` ticks of its first row (the times re-counted from 0): the walk's pattern held
    still while the person stands (:func:`lead_in_from_standing` replaces those rows)."""
    dt = float(walk.time_s[1] - walk.time_s[0])
    held = {name: np.concatenate([np.repeat(getattr(walk, name)[:1], n), getattr(walk, name)])
            for name in ("phase", "x_m", "z_m", "hip_rad", "xd_m_s", "zd_m_s", "hipd_rad_s", "height_m",
                         "other_leg_N", "other_foot_down", "stance")}
    return BenchTrajectory(time_s=np.arange(n + walk.time_s.shape[0]) * dt, stride_time_s=walk.stride_time_s, **held)


class _Blended(NamedTuple):
    """The walk's thigh (rad, rad/s), hip height along the floor's normal (m, m/s) and the other leg's push (N, foot
    down) blended with quiet standing's."""

    thigh: np.ndarray
    thigh_rate: np.ndarray
    height: np.ndarray
    height_rate: np.ndarray
    other_leg_N: np.ndarray
    other_foot_down: np.ndarray


def _with_standing(walk: BenchTrajectory, w: np.ndarray, dw: np.ndarray, normal: tuple[float, float],
                   incline_deg: float, geometry: LegGeometry, mass_kg: float) -> _Blended:
    """``walk`` weighted ``w`` (0: quiet standing, 1: the walk; ``dw`` its rate, 1/s) against standing on a floor of
    ``incline_deg`` whose normal is ``normal``: the start's lead-in and the stop's last step blend alike."""
    thigh0, knee0, ankle0 = standing_pose_rad(incline_deg)
    h0 = float(touching_hip_height_m(thigh0, knee0, ankle0, geometry, incline_deg))
    h_w = walk.height_m
    hd_w = walk.xd_m_s * normal[0] + walk.zd_m_s * normal[1]       # the walk's height rate along the normal
    stand_push = (1.0 - STANDING_SHARE_BW) * mass_kg * G_MPS2
    return _Blended(thigh=(1 - w) * thigh0 + w * walk.hip_rad, thigh_rate=w * walk.hipd_rad_s + dw * (walk.hip_rad - thigh0),
                    height=(1 - w) * h0 + w * h_w, height_rate=w * hd_w + dw * (h_w - h0),
                    other_leg_N=(1 - w) * stand_push + w * walk.other_leg_N,
                    other_foot_down=np.where(w < 1.0, True, walk.other_foot_down))


def lead_in_from_standing(walk: BenchTrajectory, walk_from_s: float, speed_mps: float, incline_deg: float,
                          stride_time_s: float, geometry: LegGeometry, mass_kg: float) -> BenchTrajectory:
    """Quiet standing until ``walk_from_s``, then gait initiation into ``walk``, a walk that begins at its phase
    :data:`STANDING_START_PHASE` at ``walk_from_s`` (held still before it: :func:`held_until`) at the task
    (``speed_mps``, ``incline_deg``, ``stride_time_s``) it keeps at least for the ramp.

    Over :data:`INITIATION_STRIDES` of a stride (a cosine ramp ``w`` from 0 to 1) the body accelerates to the walk's
    speed and the thigh, the hip's height and the other leg's push go over from standing's to the walk's. The person
    stands ahead of the walk's start by the distance the ramp loses, so from the ramp's end the trajectory *is*
    ``walk`` (the same positions on the same floor, at the same times)."""
    t = walk.time_s
    alpha, v = math.radians(incline_deg), speed_mps
    tangent, normal = (math.cos(alpha), math.sin(alpha)), (-math.sin(alpha), math.cos(alpha))
    ramp = INITIATION_STRIDES * stride_time_s
    tau = t - walk_from_s
    ramp_tau = np.clip(tau, 0.0, ramp)
    w = np.where(tau <= 0, 0.0, np.where(tau >= ramp, 1.0, 0.5 * (1.0 - np.cos(np.pi * ramp_tau / ramp))))
    dw = np.where((tau > 0) & (tau < ramp), 0.5 * np.pi / ramp * np.sin(np.pi * ramp_tau / ramp), 0.0)
    # the distance still to make up: v·ramp/2 while standing (∫(1 − w)·v over the ramp), 0 from the ramp's end
    lost = ramp_tau - (ramp_tau / 2 - ramp / (2 * np.pi) * np.sin(np.pi * ramp_tau / ramp))
    ahead = v * (ramp / 2 - lost)
    b = _with_standing(walk, w, dw, normal, incline_deg, geometry, mass_kg)
    floor_x, floor_z = walk.x_m - walk.height_m * normal[0], walk.z_m - walk.height_m * normal[1]
    ramping = tau < ramp
    x = floor_x + ahead * tangent[0] + b.height * normal[0]
    z = floor_z + ahead * tangent[1] + b.height * normal[1]
    xd = np.where(ramping, w * v * tangent[0] + b.height_rate * normal[0], walk.xd_m_s)
    zd = np.where(ramping, w * v * tangent[1] + b.height_rate * normal[1], walk.zd_m_s)
    return BenchTrajectory(
        time_s=t, phase=walk.phase, x_m=x, z_m=z, hip_rad=b.thigh, xd_m_s=xd, zd_m_s=zd, hipd_rad_s=b.thigh_rate,
        height_m=b.height, other_leg_N=b.other_leg_N, other_foot_down=b.other_foot_down,
        stance=np.where(tau <= 0, True, walk.stance), stride_time_s=walk.stride_time_s)


def plan_standing_start(ref: WalkingReference, geometry: LegGeometry, mass_kg: float, seconds: float,
                        timestep_s: float = 0.001, stand_s: float = STAND_S, harmonics: int = HARMONICS
                        ) -> BenchTrajectory:
    """``seconds`` in all: quiet standing for ``stand_s``, then gait initiation into the walk of
    :func:`plan_bench_trajectory` at the reference's task from the prosthesis's heel strike
    (:func:`lead_in_from_standing`)."""
    n_stand = round(stand_s / timestep_s)
    walk = plan_bench_trajectory(ref, geometry, mass_kg, seconds - n_stand * timestep_s, timestep_s,
                                 start_phase=STANDING_START_PHASE, harmonics=harmonics)
    return lead_in_from_standing(held_until(walk, n_stand), n_stand * timestep_s, ref.speed_mps, ref.incline_deg,
                                 ref.stride_time_s, geometry, mass_kg)


STOPPING_STRIDES = 0.45   # the last step: begun at a prosthesis heel strike, done as the other leg lands beside it


def plan_walk_and_stop(ref: WalkingReference, geometry: LegGeometry, mass_kg: float, seconds: float, stop_s: float,
                       timestep_s: float = 0.001, stand_s: float = STAND_S) -> BenchTrajectory:
    """``seconds`` in all: from standing (:func:`plan_standing_start`), walking, and from the prosthesis's first heel
    strike at or after ``stop_s`` the last step: over :data:`STOPPING_STRIDES` of a stride (a cosine ramp ``u`` from
    1 to 0) the body slows to a halt and the thigh, the hip's height and the other leg's push go over from the walk's
    to standing's, ending as the other leg lands beside the prosthesis (its landing is at phase 0.5); then quiet
    standing to the end.

    Raises:
        ValueError: no heel strike between ``stop_s`` and the end leaves time for the last step.
    """
    walk = plan_standing_start(ref, geometry, mass_kg, seconds, timestep_s, stand_s)
    t, s = walk.time_s, walk.phase
    ramp = STOPPING_STRIDES * ref.stride_time_s
    strikes = np.flatnonzero((np.diff(s) < -0.5) & (t[1:] >= stop_s) & (t[1:] + ramp <= t[-1])) + 1
    if not strikes.size:
        raise ValueError(f"no heel strike after stop_s={stop_s:g} s leaves {ramp:.2f} s for the last step before "
                         f"the walk's end ({seconds:g} s)")
    i0 = int(strikes[0])
    tau = np.clip(t - t[i0], 0.0, ramp)
    u = np.where(t < t[i0], 1.0, 0.5 * (1.0 + np.cos(np.pi * tau / ramp)))
    du = np.where((t > t[i0]) & (tau < ramp), -0.5 * np.pi / ramp * np.sin(np.pi * tau / ramp), 0.0)
    alpha, v = math.radians(ref.incline_deg), ref.speed_mps
    tangent, normal = (math.cos(alpha), math.sin(alpha)), (-math.sin(alpha), math.cos(alpha))
    b = _with_standing(walk, u, du, normal, ref.incline_deg, geometry, mass_kg)
    # progress along the floor from the stop's heel strike: v·∫u dt (the walk's own from there is v·τ)
    slowed = v * (tau / 2 + ramp / (2 * np.pi) * np.sin(np.pi * tau / ramp))
    floor0 = (walk.x_m[i0] - walk.height_m[i0] * normal[0], walk.z_m[i0] - walk.height_m[i0] * normal[1])
    after = t >= t[i0]
    x = np.where(after, floor0[0] + slowed * tangent[0] + b.height * normal[0], walk.x_m)
    z = np.where(after, floor0[1] + slowed * tangent[1] + b.height * normal[1], walk.z_m)
    xd = np.where(after, u * v * tangent[0] + b.height_rate * normal[0], walk.xd_m_s)
    zd = np.where(after, u * v * tangent[1] + b.height_rate * normal[1], walk.zd_m_s)
    stopped = t >= t[i0] + ramp
    return BenchTrajectory(
        time_s=t, phase=np.where(stopped, s[min(i0 + round(ramp / timestep_s), s.shape[0] - 1)], s), x_m=x, z_m=z,
        hip_rad=b.thigh, xd_m_s=xd, zd_m_s=zd, hipd_rad_s=b.thigh_rate, height_m=b.height,
        other_leg_N=b.other_leg_N, other_foot_down=b.other_foot_down,
        stance=np.where(after, True, walk.stance), stride_time_s=walk.stride_time_s)
