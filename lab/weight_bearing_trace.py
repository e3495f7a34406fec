"""Trace one stride of the weight-bearing prototype (issue 34, WIP): state, knee, torques, load, hip height error,
hip torque, thigh error, the other leg's force, every 20 ms. Run: PYTHONPATH=. python lab/weight_bearing_trace.py"""
import math, sys, numpy as np
sys.argv = ["x"]
exec(open("lab/weight_bearing_probe.py").read().split("m = load_default_model()")[0])
from controller_core.model_io import load_default_model
m = load_default_model()
t = m.propose(1.2, 0.0, 75.0).table
for r in t.rows: print(r.joint, r.subphase, round(r.k_Nm_per_rad,1), round(math.degrees(r.theta_e_rad) if hasattr(r,'theta_e_rad') else r.theta_e_deg,1))
print(t.thresholds if hasattr(t,'thresholds') else '')
def with_knee(table, sub, k):
    return table.model_copy(update={"rows": [r.model_copy(update={"k_Nm_per_rad": k}) if (r.joint, r.subphase) == ("knee", sub) else r for r in table.rows]})
tab = t if len(sys.argv) < 2 else None
ref = level_walking_reference(1.2); mass = 75.0
leg = SimulatedLeg(body_mass_kg=mass, stabiliser=(0.1, 0.5), hip_servo=(800, 40, 120))
traj = plan_bench_trajectory(ref, leg.geometry, mass, 6.0, leg.timestep_s, own_leg=True)
s0 = traj.phase[0]
x = leg.reset(traj, float(np.interp(s0, ref.phase, ref.knee_angle_rad)), float(np.interp(s0, ref.phase, ref.ankle_angle_rad)))
from controller_core.table import SafetyLimits
ctrl = StateMachineController(ImpedanceSchedule.from_table(t, SafetyLimits(knee_stance_support_Nm_per_rad_per_kg=0.0))); ctrl.reset()
for i in range(traj.time_s.shape[0]):
    cmd = ctrl.step(x)
    if i >= 3500 and i < 4700 and i % 20 == 0:
        hx, hz = leg.hip_position_m()
        print(f"s={traj.phase[i]:.2f} st={int(cmd.state)} knee={math.degrees(x.knee_angle_rad):5.1f} ref={math.degrees(np.interp(traj.phase[i], ref.phase, ref.knee_angle_rad)):5.1f} ank={math.degrees(x.ankle_angle_rad):5.1f} tk={cmd.knee_torque_Nm:6.1f} ta={cmd.ankle_torque_Nm:6.1f} load={x.load_N:6.0f} dz={1000*(hz-traj.z_m[i]):6.1f} hipT={leg.hip_torque_Nm:6.1f} thigh_err={math.degrees(traj.hip_rad[i]-x.thigh_angle_rad):5.1f} other={traj.contralateral_N[i]:5.0f}")
    x = leg.step(cmd.knee_torque_Nm, cmd.ankle_torque_Nm)
