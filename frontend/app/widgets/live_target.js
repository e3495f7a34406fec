// The target beside the measured angles on the live chart: the reference at the task the leg runs (its table's task,
// or with an envelope the task it blends at), read at each sample's place in the stride. The place in the stride is
// the time since the last heel strike (the leg's state going from swing extension to stance flexion) over the last
// stride's duration; none before the first full stride, nor while standing (more than 1.3 strides since a heel strike).
import { get } from "../api.js";
import { interp } from "../ui.js";

const SWING_EXTENSION = 3, STANCE_FLEXION = 0;
const LONGEST_STRIDE_FRACTION = 1.3;

export function liveTarget() {
  let ref = null, refKey = null, fetching = false;
  let lastState = null, lastStrike = null, strideS = null;
  const state = { task: null, label: null };
  const want = async (speed, incline) => {
    const key = `${Math.round(speed / 0.05) * 0.05}|${Math.round(incline * 2) / 2}`;
    if (key === refKey || fetching) return;
    fetching = true;
    try {
      const r = await get(`/api/reference?speed_mps=${speed.toFixed(2)}&incline_deg=${incline.toFixed(1)}`);
      ref = r.at_task;               // null: nothing measured that steep, no target shown
      refKey = key;
      state.task = { speed_mps: speed, incline_deg: incline };
      state.label = ref?.label ?? null;
    } catch {
      ref = null;
    } finally {
      fetching = false;
    }
  };
  return {
    state,
    // the task the leg runs: its table's task, or an envelope's running task from the sample
    follow(status, m) {
      const t = status?.active_table;
      if (!t) return;
      if (t.kind === "envelope" && Number.isFinite(m?.running_speed_mps)) want(m.running_speed_mps, m.running_incline_deg ?? 0);
      else if (t.task && Number.isFinite(t.task.speed_mps)) want(t.task.speed_mps, t.task.incline_deg ?? 0);
    },
    // [knee, ankle] target (deg) for a sample at time t (s) in FSM state s; nulls where there is none
    at(t, s) {
      if (lastState === SWING_EXTENSION && s === STANCE_FLEXION) {
        if (lastStrike !== null) strideS = t - lastStrike;
        lastStrike = t;
      }
      lastState = s;
      if (!ref || lastStrike === null || !strideS) return [null, null];
      const phase = (t - lastStrike) / strideS;
      if (phase > LONGEST_STRIDE_FRACTION) return [null, null];
      const p = Math.min(phase, 1);
      return [interp(p, ref.phase, ref.knee_angle_deg), interp(p, ref.phase, ref.ankle_angle_deg)];
    },
  };
}
