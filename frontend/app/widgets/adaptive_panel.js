// The live monitor's view of an adaptive leg: where in its envelope the leg thinks it walks (the estimated task as a
// moving point with a trail of its last strides), the values it runs now (the envelope blended at the task the leg
// runs, as the device blends them), and an unmistakable banner when it is clamped at the envelope's edge, fell back
// to its nominal task, or is in safe mode.
import { envelopeMap, nodeGrid } from "./envelope_map.js";
import { fmt, h, ROW_WORDS, SUBPHASE_LABEL, SUBPHASES, table } from "../ui.js";

const TRAIL = 12;   // strides: the estimate changes once per stride

const STATES = {
  adaptive: ["adaptive", "ADAPTING: rows follow the estimated speed and incline"],
  partial: ["partial", "ADAPTING IN PART: one of speed or incline is not confident; that one stays nominal"],
  nominal: ["nominal", "ON NOMINAL: the leg is not sure of its task and runs the nominal node"],
  clamped: ["clamped", "CLAMPED AT THE ENVELOPE'S EDGE: the task is outside the approved range; the leg holds the edge rows"],
};

// Bilinear blend of the envelope's node values at (v, g), clamped to the grid: what the device runs
function blend(axis, x) {
  const n = axis.length;
  if (x <= axis[0]) return [0, 0, 0];
  if (x >= axis[n - 1]) return [n - 1, n - 1, 0];
  let k = 0;
  while (axis[k + 1] < x) k++;
  return [k, k + 1, (x - axis[k]) / (axis[k + 1] - axis[k])];
}

export function blendedRows(e, v, g) {
  const [i0, i1, fv] = blend(e.speeds_mps, v), [j0, j1, fg] = blend(e.inclines_deg, g);
  const ni = e.inclines_deg.length;
  const node = (i, j) => e.nodes[i * ni + j];
  const w = [[i0, j0, (1 - fv) * (1 - fg)], [i1, j0, fv * (1 - fg)], [i0, j1, (1 - fv) * fg], [i1, j1, fv * fg]];
  return node(0, 0).table.map((row, r) => {
    const val = (q) => w.reduce((acc, [i, j, wt]) => acc + wt * node(i, j).table[r][q], 0);
    return { joint: row.joint, subphase: row.subphase, k_Nm_per_rad: val("k_Nm_per_rad"), theta_e_deg: val("theta_e_deg"),
      b_Nm_s_per_rad: val("b_Nm_s_per_rad") };
  });
}

export function adaptivePanel(box, envelope) {
  const rowPick = h("select", { id: "monitor-map-row", "aria-label": "Row shown on the map" },
    ["knee", "ankle"].flatMap((joint) => SUBPHASES.map((sp) => h("option", { value: `${joint}.${sp}` }, ROW_WORDS[`${joint}.${sp}`]))));
  const banner = h("div", { id: "adaptive-state", class: "state-banner nominal", role: "status", "aria-live": "assertive" },
    "waiting for the leg's first estimate (after two strides)…");
  const mapBox = h("figure", { class: "map", id: "monitor-map" });
  const facts = h("dl", { class: "facts", id: "adaptive-readout" });
  const values = h("div", { id: "active-values" });
  box.replaceChildren(h("h2", {}, `Adaptive leg · ${envelope.envelope_label}`), banner,
    h("div", { class: "readout-row" }, h("div", { class: "monitor-map-box" }, h("label", {}, "Map of ", rowPick), mapBox), facts),
    values,
    h("p", { class: "muted small" }, "Point: the leg's own estimate of its task (from its socket IMU and joint angles, once per stride); ",
      `line: its last ${TRAIL} estimates. Hatched nodes are outside the training data. Values: the envelope blended at the task `,
      "the leg runs (rate-limited and clamped), recomputed here from the approved envelope as the device blends it."));
  let map;
  const drawMap = () => {
    const [joint, sp] = rowPick.value.split(".");
    map = envelopeMap(mapBox, { title: `${joint} ${SUBPHASE_LABEL[sp]}: resistance K (N·m/rad)`, id: "live-map", speeds: envelope.speeds_mps,
      inclines: envelope.inclines_deg, unit: "N·m/rad", digits: 0, extrapolated: nodeGrid(envelope, (n) => n.extrapolation),
      darker: "high", keyWords: "darker = firmer",
      values: nodeGrid(envelope, (n) => -n.table.find((r) => r.joint === joint && r.subphase === sp).k_Nm_per_rad + 0) });
    map.setTrail(trail);
  };
  const trail = [];
  let shown = "", lastFacts = "";
  rowPick.addEventListener("change", drawMap);
  drawMap();
  return {
    // one telemetry sample (with the adaptive fields) and the device status; cheap enough for every frame
    update(m, status) {
      if (m.estimated_speed_mps !== undefined && m.estimated_speed_mps !== null) {
        const last = trail.at(-1);
        if (!last || last[0] !== m.estimated_speed_mps || last[1] !== m.estimated_incline_deg) {
          trail.push([m.estimated_speed_mps, m.estimated_incline_deg]);
          if (trail.length > TRAIL) trail.shift();
          map.setTrail(trail);
        }
      }
      const safe = status.safe_mode;
      const nominal = envelope.nominal;
      // on nominal because its estimate is the nominal task is not "unsure"; standing is neither
      const atNominal = Number.isFinite(m.estimated_speed_mps) && Math.abs(m.estimated_speed_mps - nominal.speed_mps) <= 0.05
        && Math.abs((m.estimated_incline_deg ?? 0) - nominal.incline_deg) <= 1.0;
      const [cls, words, state] = safe ? ["safe", "SAFE MODE: the leg is passive (it holds the loaded knee against bending); the envelope does not run", "safe"]
        : status.bench_state === "standing" ? ["nominal", "STANDING: the patient stands; the leg keeps its rows until walking resumes", "standing"]
          : m.adaptive_mode === "nominal" && atNominal ? ["nominal", `ON NOMINAL: the leg's estimate is its nominal task (${fmt(nominal.speed_mps, 2)} m/s, ${fmt(nominal.incline_deg, 1)}°)`, "nominal"]
            : m.adaptive_mode ? [...(STATES[m.adaptive_mode] || ["nominal", `mode ${m.adaptive_mode}`]), m.adaptive_mode]
              : ["nominal", "no adaptive telemetry yet", "nominal"];
      const key = `${cls}|${words}`;
      if (key !== shown) {
        shown = key;
        banner.className = `state-banner ${cls}`;
        banner.dataset.state = state;
        banner.textContent = words;
      }
      if (m.running_speed_mps === undefined) return;
      const bench = status.bench_task;
      const now = [m.estimated_speed_mps, m.estimated_incline_deg, m.running_speed_mps, m.running_incline_deg,
        bench ? `${fmt(bench.speed_mps, 2)} ${fmt(bench.incline_deg, 1)} ${bench.course}` : ""].join("|");
      if (now === lastFacts) return;   // the estimate and the rows change at heel strikes only
      lastFacts = now;
      const item = (label, value, id) => [h("dt", {}, label), h("dd", { id }, value)];
      facts.replaceChildren(
        ...item("Estimated task", m.estimated_speed_mps === null ? "none yet"
          : `${fmt(m.estimated_speed_mps, 2, "m/s")}, ${fmt(m.estimated_incline_deg, 1, "°")}`, "estimated-task"),
        ...item("Rows blended at", `${fmt(m.running_speed_mps, 2, "m/s")}, ${fmt(m.running_incline_deg, 1, "°")}`, "running-task"),
        ...item("Nominal", `${fmt(envelope.nominal.speed_mps, 2, "m/s")}, ${fmt(envelope.nominal.incline_deg, 1, "°")}`, "nominal-task"),
        ...(bench ? item("Bench (true task)", `${fmt(bench.speed_mps, 2, "m/s")}, ${fmt(bench.incline_deg, 1, "°")}`
          + (bench.course ? ` · course ${bench.course}` : ""), "bench-task") : []));
      const rows = blendedRows(envelope, m.running_speed_mps, m.running_incline_deg);
      values.replaceChildren(table(["Row", "Resistance K (N·m/rad)", "θe (deg)", "b (N·m·s/rad)"],
        rows.map((r) => h("tr", {}, h("td", {}, ROW_WORDS[`${r.joint}.${r.subphase}`]), h("td", { class: "num" }, fmt(-r.k_Nm_per_rad + 0, 0)),
          h("td", { class: "num" }, fmt(r.theta_e_deg, 1)), h("td", { class: "num" }, fmt(r.b_Nm_s_per_rad, 2)))), { id: "active-values-table" }));
    },
  };
}
