"""Probe of the weight-bearing bench prototype (issue 34, work in progress on branch issue34): walk tables on a socket
whose vertical motion carries the body. Run: PYTHONPATH=. python lab/weight_bearing_probe.py [stiffness_bw_per_0.1m damping_ratio]."""
import math, sys, numpy as np
from controller_core.model_io import load_default_model
from controller_core.fsm import ImpedanceSchedule, StateMachineController
from controller_core.fsmic import fsmic_table
from controller_core.walking_reference import level_walking_reference
from controller_core.units import G_MPS2
from device_bridge.sim.plant import SimulatedLeg
from device_bridge.sim.bench_trajectory import plan_bench_trajectory

def walk(table, speed=1.2, mass=75.0, seconds=10.0, stab=(0.1, 0.5), hip=(6000.0, 150.0, 1e9), other=(20000.0, 1200.0)):
    ref = level_walking_reference(speed)
    leg = SimulatedLeg(body_mass_kg=mass, stabiliser=stab, hip_servo=hip, other_leg=other)
    traj = plan_bench_trajectory(ref, leg.geometry, mass, seconds, leg.timestep_s, own_leg=OWN)
    s0 = traj.phase[0]
    x = leg.reset(traj, float(np.interp(s0, ref.phase, ref.knee_angle_rad)), float(np.interp(s0, ref.phase, ref.ankle_angle_rad)))
    from controller_core.table import SafetyLimits
    ctrl = StateMachineController(ImpedanceSchedule.from_table(table, SafetyLimits(knee_stance_support_Nm_per_rad_per_kg=0.0))); ctrl.reset()
    n = traj.time_s.shape[0]
    sink, sup, knee, st, load, ht = (np.empty(n) for _ in range(6))
    for i in range(n):
        cmd = ctrl.step(x)
        hx, hz = leg.hip_position_m()
        sink[i] = hz - traj.z_m[i]; sup[i] = leg.support_N; knee[i] = x.knee_angle_rad; st[i] = cmd.state; load[i] = x.load_N; ht[i] = leg.hip_torque_Nm
        x = leg.step(cmd.knee_torque_Nm, cmd.ankle_torque_Nm)
    w = mass * G_MPS2
    k = slice(2000, None)
    stance = (st[k] == 0) & (load[k] > 0.2 * w)
    return {"hip_sink_max_mm": round(-1000 * sink[k].min(), 1), "hip_rise_max_mm": round(1000 * sink[k].max(), 1),
            "support_deficit_max_bw": round(sup[k].max() / w, 3), "support_mean_bw": round(sup[k].mean() / w, 3),
            "stance_knee_peak_deg": round(math.degrees(knee[k][stance].max()), 1) if stance.any() else None,
            "knee_max_deg": round(math.degrees(knee[k].max()), 1),
            "hip_torque_max_Nm": round(float(np.abs(ht[k]).max()), 0), "sf_time_frac": round(float(np.mean(st[k] == 0)), 3)}

import os
OWN = os.environ.get('OWN_LEG') == '1'
m = load_default_model()
t = m.propose(1.2, 0.0, 75.0).table
def with_knee(table, sub, k):
    return table.model_copy(update={"rows": [r.model_copy(update={"k_Nm_per_rad": k}) if (r.joint, r.subphase) == ("knee", sub) else r for r in table.rows]})
soft = with_knee(with_knee(t, "stance_flexion", -1.0), "stance_extension", -1.0)
stab = tuple(float(v) for v in sys.argv[1:3]) if len(sys.argv) > 2 else (0.1, 0.5)
hip = tuple(float(v) for v in sys.argv[3:6]) if len(sys.argv) > 5 else (6000.0, 150.0, 1e9)
other = tuple(float(v) for v in sys.argv[6:8]) if len(sys.argv) > 7 else (20000.0, 1200.0)
for name, tab in [("learned", t), ("fsmic", fsmic_table(75.0)), ("no knee support", soft),
                  ("knee SF k=-50", with_knee(t, "stance_flexion", -50.0)), ("knee SF k=-300", with_knee(t, "stance_flexion", -300.0))]:
    print(name, walk(tab, stab=stab, hip=hip, other=other), flush=True)
