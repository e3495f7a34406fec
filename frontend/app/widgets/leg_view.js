// The leg as its sensors see it, drawn in the sagittal plane from the signed-in telemetry stream: knee and ankle
// angles as measured (flexion and dorsiflexion +), the foot coloured by pylon load. The device measures no hip
// angle, so the thigh is drawn upright. Segment lengths: the simulated leg's proportions of a 1.75 m body
// (device_bridge/sim/leg_model.py), for drawing only.
import { h } from "../ui.js";

const THIGH_M = 0.43, SHANK_M = 0.43, FOOT_M = 0.27, HEEL_FRACTION = 0.2;
const RAD = Math.PI / 180;

export function legView(el) {
  const canvas = h("canvas", { width: 260, height: 330, role: "img", "aria-label": "the leg, side view, from telemetry" });
  const caption = h("figcaption", { class: "muted small" }, "Side view from telemetry (thigh drawn upright: the device ",
    "measures knee and ankle only). Foot: grey unloaded → orange at body weight.");
  el.replaceChildren(canvas, caption);
  const ctx = canvas.getContext("2d");
  const scale = 280, hip = [110, 24];
  const at = ([x, y]) => [hip[0] + x * scale, hip[1] - y * scale];   // metres (x forward, y up) → pixels
  return {
    draw(m, weightN) {
      const knee = [0, -THIGH_M];
      const tk = m.knee_angle_deg * RAD, phi = (m.ankle_angle_deg - m.knee_angle_deg) * RAD;
      const ankle = [knee[0] - Math.sin(tk) * SHANK_M, knee[1] - Math.cos(tk) * SHANK_M];
      const f = [Math.cos(phi), Math.sin(phi)];
      const heel = [ankle[0] - f[0] * FOOT_M * HEEL_FRACTION, ankle[1] - f[1] * FOOT_M * HEEL_FRACTION];
      const toe = [ankle[0] + f[0] * FOOT_M * (1 - HEEL_FRACTION), ankle[1] + f[1] * FOOT_M * (1 - HEEL_FRACTION)];
      const load = weightN ? Math.min(Math.max(m.load_N / weightN, 0), 1) : 0;
      ctx.clearRect(0, 0, canvas.width, canvas.height);
      const seg = (a, b, colour, width) => {
        ctx.strokeStyle = colour; ctx.lineWidth = width; ctx.lineCap = "round";
        ctx.beginPath(); ctx.moveTo(...at(a)); ctx.lineTo(...at(b)); ctx.stroke();
      };
      seg([0, 0], knee, "#78829a", 10);
      seg(knee, ankle, "#3c6eb4", 8);
      seg(heel, toe, `rgb(${150 + 100 * load}, ${150 - 30 * load}, ${150 - 120 * load})`, 8);
      for (const [p, r] of [[[0, 0], 7], [knee, 6], [ankle, 5]]) {
        ctx.fillStyle = "#222"; ctx.beginPath(); ctx.arc(...at(p), r, 0, 2 * Math.PI); ctx.fill();
      }
      ctx.fillStyle = "#222"; ctx.font = "12px sans-serif";
      ctx.fillText(`knee ${m.knee_angle_deg.toFixed(0)}°  ankle ${m.ankle_angle_deg.toFixed(0)}°`, 8, canvas.height - 26);
      ctx.fillText(weightN ? `load ${(100 * m.load_N / weightN).toFixed(0)} % body weight` : `load ${m.load_N.toFixed(0)} N`,
        8, canvas.height - 10);
    },
  };
}
