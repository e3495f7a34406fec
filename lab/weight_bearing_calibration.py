"""Calibration probe of the weight-bearing prototype (issue 34, WIP): knee and ankle position-controlled on the
reference at the task; how far the hip strays from its target height (mm) and how much the bench adds (BW).
Run: PYTHONPATH=. python lab/weight_bearing_calibration.py [own_leg 0/1] [speed] [incline]"""
import math
import sys

import numpy as np

from controller_core.units import G_MPS2
from device_bridge.bench.task_reference import task_reference
from device_bridge.sim.bench_trajectory import plan_bench_trajectory
from device_bridge.sim.plant import SimulatedLeg

own = len(sys.argv) > 1 and sys.argv[1] == "1"
speed = float(sys.argv[2]) if len(sys.argv) > 2 else 1.2
incline = float(sys.argv[3]) if len(sys.argv) > 3 else 0.0
mass = 75.0
ref = task_reference(speed, incline, None, mass)
leg = SimulatedLeg(incline_deg=incline, body_mass_kg=mass, stabiliser=(0.1, 0.5), hip_servo=(800, 40, 120))
traj = plan_bench_trajectory(ref, leg.geometry, mass, 8.0, leg.timestep_s, own_leg=own)
s0 = traj.phase[0]
x = leg.reset(traj, float(np.interp(s0, ref.phase, ref.knee_angle_rad)), float(np.interp(s0, ref.phase, ref.ankle_angle_rad)))
n = traj.time_s.shape[0]
dz, sup, other, grf = (np.empty(n) for _ in range(4))
kp, kd = 3000.0, 60.0
T = traj.stride_time_s
for i in range(n):
    s = traj.phase[i]
    qk, qa = np.interp(s, ref.phase, ref.knee_angle_rad), np.interp(s, ref.phase, ref.ankle_angle_rad)
    ds = 1e-3
    vk = (np.interp((s + ds) % 1, ref.phase, ref.knee_angle_rad) - qk) / ds / T
    va = (np.interp((s + ds) % 1, ref.phase, ref.ankle_angle_rad) - qa) / ds / T
    tk = kp * (qk - x.knee_angle_rad) + kd * (vk - x.knee_velocity_rad_s)
    ta = kp * (qa - x.ankle_angle_rad) + kd * (va - x.ankle_velocity_rad_s)
    hx, hz = leg.hip_position_m()
    dz[i] = hz - traj.z_m[i]
    sup[i] = leg.support_N
    other[i] = traj.contralateral_N[i]
    grf[i] = leg.foot_contact_force()
    x = leg.step(tk, ta)
w = mass * G_MPS2
k = slice(2000, None)
st = traj.phase[k] <= ref.toe_off_phase
print({"own_leg": own, "speed": speed, "incline": incline,
       "hip_error_stance_mm": [round(1000 * dz[k][st].min(), 1), round(1000 * dz[k][st].max(), 1)],
       "hip_error_all_mm": [round(1000 * dz[k].min(), 1), round(1000 * dz[k].max(), 1)],
       "hip_error_rms_mm": round(1000 * float(np.sqrt(np.mean(dz[k] ** 2))), 1),
       "support_max_bw": round(sup[k].max() / w, 3), "support_min_bw": round(sup[k].min() / w, 3),
       "support_mean_abs_bw": round(float(np.mean(np.abs(sup[k]))) / w, 3),
       "grf_peak_bw": round(grf[k].max() / w, 2), "grf_mean_bw": round(grf[k].mean() / w, 3)})
