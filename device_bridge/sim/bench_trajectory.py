"""What the bench does with the socket: a human hip trajectory for the task, and the body-weight load.

For a task the bench replays the able-bodied pattern of :class:`controller_core.walking_reference.WalkingReference`:

* **Thigh angle** φ(s) (rad, from vertical, flexion +) = hip flexion − c, where the constant c makes the
  reference foot flat on the (tilted) floor over mid-stance (15–40 % of the cycle): the foot's pitch is
  φ − knee + ankle, so c = mean(hip − knee + ankle) − incline. c absorbs the pelvic tilt the hip angle is
  measured from (about 5–7° in the shipped data).
* **Hip height** h(s) above the floor (m, along the floor normal) = the height at which the reference leg
  — this bench's segment lengths, the reference knee and ankle angles — touches the floor with its lowest
  contact, taken from whichever leg is in stance (the contralateral leg is the same pattern half a cycle
  later; in double support the lower of the two). The two legs disagree there, so a leg with the reference
  angles would not land or push off on time: :func:`hip_height_mismatch_mm` says by how much.
* **Forward motion**: the socket moves along the floor at the task speed (belt speed).
* **Load**: the bench pushes the socket down with the reference vertical ground reaction force
  (vgrf(s) × body weight) and carries the bench's own moving mass; a stiff servo holds the socket near
  h(s), standing in for the contralateral leg when the prosthesis yields.

Both periodic signals are smoothed by keeping their first harmonics (the data are 101-point means; the
stance-leg switch in h(s) has a corner), which also gives their velocities analytically.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from controller_core.units import G_MPS2
from controller_core.walking_reference import WalkingReference
from device_bridge.sim.leg_model import LegGeometry

MID_STANCE = (0.15, 0.40)
HARMONICS = 12   # harmonics kept when smoothing the periodic socket signals


def fourier_coefficients(values: np.ndarray, harmonics: int) -> tuple[np.ndarray, np.ndarray]:
    """Cosine/sine coefficients (a, b) of a periodic signal sampled on [0, 1) (last grid point dropped)."""
    y = values[:-1] if values.shape[0] == 101 else values
    n = y.shape[0]
    c = np.fft.rfft(y) / n
    a = 2.0 * c.real[: harmonics + 1]
    b = -2.0 * c.imag[: harmonics + 1]
    a[0] /= 2.0
    return a, b


def _eval_fourier(a: np.ndarray, b: np.ndarray, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Value and d/ds of the series at phases s."""
    k = np.arange(a.shape[0])
    ang = 2.0 * np.pi * np.outer(s, k)
    val = np.cos(ang) @ a + np.sin(ang) @ b
    der = (-np.sin(ang) * (2.0 * np.pi * k)) @ a + (np.cos(ang) * (2.0 * np.pi * k)) @ b
    return val, der


def thigh_angle_rad(ref: WalkingReference, incline_deg: float) -> np.ndarray:
    """Thigh angle from vertical (rad, flexion +) on the reference grid (see module docstring)."""
    s = ref.phase
    mid = (s >= MID_STANCE[0]) & (s <= MID_STANCE[1])
    c = float(np.mean((ref.hip_angle_rad - ref.knee_angle_rad + ref.ankle_angle_rad)[mid])) - math.radians(incline_deg)
    return ref.hip_angle_rad - c


def stance_hip_height_m(thigh: np.ndarray, knee: np.ndarray, ankle: np.ndarray, geometry: LegGeometry,
                        incline_deg: float) -> np.ndarray:
    """Hip height above the floor (m, along the normal) at which the leg's lowest contact touches it."""
    g = geometry
    alpha = math.radians(incline_deg)
    nx, nz = -math.sin(alpha), math.cos(alpha)
    shank = thigh - knee
    pitch = shank + ankle
    kx, kz = g.thigh_m * np.sin(thigh), -g.thigh_m * np.cos(thigh)
    ax, az = kx + g.shank_m * np.sin(shank), kz - g.shank_m * np.cos(shank)
    zc = -g.ankle_height_m + g.contact_radius_m
    lowest = None
    for xf in (-g.heel_back_m, g.toe_forward_m):
        px = ax + xf * np.cos(pitch) - zc * np.sin(pitch)
        pz = az + xf * np.sin(pitch) + zc * np.cos(pitch)
        d = px * nx + pz * nz
        lowest = d if lowest is None else np.minimum(lowest, d)
    return g.contact_radius_m - lowest


def grid_hip_heights_m(ref: WalkingReference, thigh: np.ndarray, geometry: LegGeometry) -> tuple[np.ndarray, np.ndarray]:
    """(hip height target, height at which the ipsilateral reference leg touches) on the reference grid (m)."""
    s_grid = ref.phase
    h_ipsi = stance_hip_height_m(thigh, ref.knee_angle_rad, ref.ankle_angle_rad, geometry, ref.incline_deg)
    stance = s_grid <= ref.toe_off_phase
    h_own = np.where(stance, h_ipsi, np.inf)
    contra_s = (s_grid - 0.5) % 1.0
    h_contra = np.where(contra_s <= ref.toe_off_phase, np.interp(contra_s, s_grid, h_ipsi), np.inf)
    height = np.minimum(h_own, h_contra)
    if not np.all(np.isfinite(height)):
        raise ValueError("the reference has a flight phase (no leg in stance): not a walking pattern")
    return height, h_ipsi


def hip_height_mismatch_mm(ref: WalkingReference, geometry: LegGeometry, harmonics: int = HARMONICS) -> dict[str, float]:
    """How far the bench's hip height target is from where the ipsilateral reference leg touches the floor (mm).

    The target comes from whichever reference leg is in stance, and on this bench (rigid foot, segment lengths,
    thigh-angle offset, sagittal plane only) the two legs disagree in double support. The bench then does not
    let a leg with the reference angles land and push off on time:

    * ``heel_strike``: target minus touching height at the reference heel strike (phase 0), after the same
      smoothing as the bench's path. Positive: the hip is that much too high, and the foot has to reach down
      (knee extending, ankle plantarflexing) to land.
    * ``pre_swing``: the most negative target minus touching height while the ipsilateral leg is in stance.
      Negative: the contralateral leg's loading response holds the hip that much lower, compressing the leg.

    Both are properties of the bench at the task, the same for every controller (``max_hip_sink_m`` in
    ``quasitune simulate --format json``).
    """
    thigh = thigh_angle_rad(ref, ref.incline_deg)
    height, h_ipsi = grid_hip_heights_m(ref, thigh, geometry)
    a, b = fourier_coefficients(height, harmonics)
    smooth, _ = _eval_fourier(a, b, ref.phase)
    excess = smooth - h_ipsi
    stance = ref.phase <= ref.toe_off_phase
    return {"heel_strike": float(1000.0 * excess[0]), "pre_swing": float(1000.0 * excess[stance].min())}


@dataclass(frozen=True)
class BenchTrajectory:
    """Sampled socket trajectory and load for a whole run (arrays of one length, one row per tick).

    Attributes:
        time_s: tick times (s).
        phase: bench gait phase in [0, 1) (0 = reference heel strike).
        x_m, z_m, hip_rad: socket targets in world coordinates (m, m, rad).
        xd_m_s, zd_m_s, hipd_rad_s: their velocities.
        load_N: downward push on the socket (N), the reference vertical GRF.
        height_m: target hip height above the floor along its normal (m).
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
    load_N: np.ndarray
    height_m: np.ndarray
    stride_time_s: float
    contralateral_N: np.ndarray | None = None


def own_leg_hip_heights_m(ref: WalkingReference, thigh: np.ndarray, geometry: LegGeometry) -> np.ndarray:
    """Hip height target (m) that the prosthesis's own reference leg defines: where it touches over its stance; over
    its swing the other leg's touching height, shifted by a correction that runs linearly from the gap at toe-off to
    the gap at the next heel strike, so the target is continuous and the foot meets the floor on time."""
    s = ref.phase
    h = stance_hip_height_m(thigh, ref.knee_angle_rad, ref.ankle_angle_rad, geometry, ref.incline_deg)
    to = ref.toe_off_phase
    contra = np.interp((s - 0.5) % 1.0, s, h)
    gap_off = float(np.interp(to, s, h) - np.interp((to - 0.5) % 1.0, s, h))
    gap_on = float(h[0] - np.interp(0.5, s, h))
    w = np.clip((s - to) / (1.0 - to), 0.0, 1.0)
    return np.where(s <= to, h, contra + (1 - w) * gap_off + w * gap_on)


def plan_bench_trajectory(ref: WalkingReference, geometry: LegGeometry, mass_kg: float, seconds: float,
                          timestep_s: float = 0.001, start_phase: float = 0.85, harmonics: int = HARMONICS,
                          t0_s: float = 0.0, own_leg: bool = False) -> BenchTrajectory:
    """Sample the socket targets and load for ``seconds`` of walking at the reference's task, from time ``t0_s``
    (a later chunk of the same walk continues the earlier one exactly)."""
    incline = ref.incline_deg
    s_grid = ref.phase
    thigh = thigh_angle_rad(ref, incline)
    height = own_leg_hip_heights_m(ref, thigh, geometry) if own_leg else grid_hip_heights_m(ref, thigh, geometry)[0]
    T = ref.stride_time_s
    n = round(seconds / timestep_s)
    t = t0_s + np.arange(n) * timestep_s
    s = (start_phase + t / T) % 1.0
    a_h, b_h = fourier_coefficients(height, harmonics)
    a_t, b_t = fourier_coefficients(thigh, harmonics)
    h, dh = _eval_fourier(a_h, b_h, s)
    th, dth = _eval_fourier(a_t, b_t, s)
    alpha = math.radians(incline)
    v = ref.speed_mps
    u = v * t
    x = u * math.cos(alpha) - h * math.sin(alpha)
    z = u * math.sin(alpha) + h * math.cos(alpha)
    hdot = dh / T
    xd = v * math.cos(alpha) - hdot * math.sin(alpha)
    zd = v * math.sin(alpha) + hdot * math.cos(alpha)
    load = np.interp(s, s_grid, ref.vgrf_bw) * mass_kg * G_MPS2
    share = 0.5 / float(np.mean(ref.vgrf_bw[:-1]))   # each leg carries half the weight over a stride, exactly
    other = np.interp((s + 0.5) % 1.0, s_grid, ref.vgrf_bw) * share * mass_kg * G_MPS2   # the other leg
    return BenchTrajectory(time_s=t, phase=s, x_m=x, z_m=z, hip_rad=th, xd_m_s=xd, zd_m_s=zd, hipd_rad_s=dth / T,
                           load_N=load, height_m=h, stride_time_s=T, contralateral_N=other)
