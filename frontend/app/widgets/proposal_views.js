// The views a table's review shares with an envelope node's: the torque-angle loops, the curves over the gait cycle,
// the via-points explained, the GPR features, and the bench's safety figures (one place, used by both pages).
import { get } from "../api.js";
import { loopChart, phaseChart } from "./charts.js";
import { chip, fmt, h, interp, momentScale, momentUnit, momentView, pm, SUBPHASE_COLOUR, SUBPHASE_LABEL, SUBPHASES, table } from "../ui.js";

const RAD = Math.PI / 180;

// which leg the bench walked (``walked``: the preview's leg name) and why: the leg the version was made for
// (``madeFor``: the version's leg), the patient's as described, or the server's bench leg for want of a description
export function benchLegNote(walked, madeFor) {
  if (madeFor && !madeFor.nominal) {
    return h("p", { class: "small", id: "preview-leg" }, "Walked on “", walked, "”, the leg this version was made for ",
      "(its swing rows are proposed for its inertia): the patient's leg as their page describes it, or the server's ",
      "bench leg where none was described.");
  }
  return h("p", { class: "small", id: "preview-leg" }, "Walked on the server's bench leg, “", walked || "nominal",
    "”: this patient's own leg (their height, segment and unit masses, drive friction) is not described to the server ",
    "(their patient page can), so the walk and its safety figures are for that leg, not necessarily theirs.");
}

// the measured conditions behind the model, and the reference at this task with what it really is
export function reference(task) {
  return get(`/api/reference?speed_mps=${task.speed_mps}&incline_deg=${task.incline_deg}`);
}

function moments(p, joint) {
  return p.curves[`${joint}_moment_Nm_per_kg`].map((m) => m * momentScale(p.task.body_mass_kg));
}

function subphaseOf(phase, b) {
  const edges = [0, b.stance_flexion_to_stance_extension, b.stance_extension_to_swing_flexion,
    b.swing_flexion_to_swing_extension, 1];
  return SUBPHASES.filter((_, i) => phase >= edges[i] - 1e-9 && phase <= edges[i + 1] + 1e-9);
}

export function drawLoops(p, ref, atTask) {
  const mass = momentScale(p.task.body_mass_kg), mu = momentUnit();   // "mass": N·m/kg → the page's moment unit
  for (const joint of ["knee", "ankle"]) {
    const ang = p.curves[`${joint}_angle_deg`];
    const mom = moments(p, joint);
    const sd = p.curves[`${joint}_moment_Nm_per_kg_std`].map((x) => x * mass);
    const lines = [];
    for (const row of p.table.filter((r) => r.joint === joint)) {
      const inPhase = ang.filter((_, i) => subphaseOf(p.curves.phase[i], p.subphase_boundaries_phase).includes(row.subphase));
      if (!inPhase.length) continue;
      const lo = Math.min(...inPhase), hi = Math.max(...inPhase);
      const toUnit = momentView.unit === "Nm" ? 1 : 1 / p.task.body_mass_kg;   // the line's torque is in N·m
      lines.push({ color: SUBPHASE_COLOUR[row.subphase], points: [lo, hi].map((th) => [th, row.k_Nm_per_rad * (th - row.theta_e_deg) * RAD * toUnit]),
        label: `${SUBPHASE_LABEL[row.subphase]}: k = ${fmt(row.k_Nm_per_rad, 0)} N·m/rad, θe = ${fmt(row.theta_e_deg, 1)}°, R² = ${fmt(row.r2, 2)}` });
    }
    loopChart(document.getElementById(`loop-${joint}`), {
      title: `${joint === "knee" ? "Knee" : "Ankle"} torque-angle loop`,
      xLabel: `${joint} angle (deg, ${joint === "knee" ? "flexion" : "dorsiflexion"} +)`,
      yLabel: `${joint} moment (${mu})`,
      reference: [...ref.conditions.map((c) => ({ nearest: false, label: `measured: ${c.name} (${fmt(c.speed_mps, 2)} m/s, level)`,
        points: c[`${joint}_angle_deg`].map((a, i) => [a, c[`${joint}_moment_Nm_per_kg`][i] * mass]) })),
      ...(atTask ? [{ nearest: true, label: `reference at this task: ${atTask.label}`,
        points: atTask[`${joint}_angle_deg`].map((a, i) => [a, atTask[`${joint}_moment_Nm_per_kg`][i] * mass]) }] : [])],
      mean: ang.map((a, i) => [a, mom[i]]),
      band: { upper: ang.map((a, i) => [a, mom[i] + sd[i]]), lower: ang.map((a, i) => [a, mom[i] - sd[i]]) },
      vias: p.via_points.filter((v) => v.joint === joint).map((v) => ({ point: [v.angle_deg, v.moment_Nm_per_kg * mass],
        label: `via-point at ${fmt(v.phase * 100, 0)} % of the cycle: ${fmt(v.angle_deg, 1)}°, ${fmt(v.moment_Nm_per_kg * mass, mu === "N·m" ? 1 : 3)} ${mu}` })),
      lines,
    });
  }
}

// Where a via-point sits off the proposal loop, say why: the KMP weighs each via-point by how sure the GPR is, so it
// passes an uncertain one (typically outside the training data) only approximately, by design.
export function explainVias(p, el) {
  const mass = p.task.body_mass_kg, scale = momentScale(mass), mu = momentUnit();
  const at = (key, phase) => interp(phase * 100, p.curves.phase.map((x) => x * 100), p.curves[key]);
  const off = p.via_points.map((v) => {
    const dAngle = v.angle_deg - at(`${v.joint}_angle_deg`, v.phase);
    const dMoment = (v.moment_Nm_per_kg - at(`${v.joint}_moment_Nm_per_kg`, v.phase)) * mass;
    const sdAngle = at(`${v.joint}_angle_deg_std`, v.phase), sdMoment = at(`${v.joint}_moment_Nm_per_kg_std`, v.phase) * mass;
    const far = Math.abs(dAngle) > Math.max(2, sdAngle) || Math.abs(dMoment) > Math.max(0.05 * mass, sdMoment);
    return { ...v, dAngle, dMoment, far };
  }).filter((v) => v.far);
  if (!off.length) {
    el.className = "muted small";
    el.textContent = "Every via-point lies on the proposal loop (within its ±1 SD band).";
    return;
  }
  const worst = off.reduce((a, b) => (Math.abs(b.dAngle) > Math.abs(a.dAngle) ? b : a));
  el.className = "notice-inline warn small";
  el.textContent = `${off.length} via-point(s) lie off the proposal loop (largest: ${worst.joint} at ${fmt(worst.phase * 100, 0)} % `
    + `of the cycle, ${fmt(worst.dAngle, 1)}° and ${fmt(worst.dMoment * scale / mass, mu === "N·m" ? 1 : 3)} ${mu} from the loop). `
    + (p.extrapolation ? "This task is outside the walking data, so the GPR is unsure of these peaks (see the ± SD in the features). "
      : "The GPR is less sure of these peaks (see the ± SD in the features). ")
    + "By design the KMP passes an uncertain via-point only approximately: the loop keeps the measured shape where the "
    + "prediction is unsure. Treat the stars as the model's guess, not a target the table meets.";
}

export function drawCurves(p, atTask, box, what = "proposal") {
  const x = p.curves.phase.map((s) => s * 100);
  const b = p.subphase_boundaries_phase;
  const markers = [b.stance_flexion_to_stance_extension, b.stance_extension_to_swing_flexion,
    b.swing_flexion_to_swing_extension].map((v) => v * 100);
  const refX = atTask ? atTask.phase.map((s) => s * 100) : null;
  const mu = momentUnit(), scale = momentScale(p.task.body_mass_kg);
  for (const [key, label] of [["knee_angle_deg", "knee angle (deg)"], ["knee_moment_Nm_per_kg", `knee moment (${mu})`],
    ["ankle_angle_deg", "ankle angle (deg)"], ["ankle_moment_Nm_per_kg", `ankle moment (${mu})`]]) {
    const el = h("figure", { class: "chart", dataset: { channel: key } });
    box.append(el);
    const k = key.endsWith("_Nm_per_kg") ? scale : 1;
    const mean = p.curves[key].map((v) => v * k), sd = p.curves[`${key}_std`].map((v) => v * k);
    const lines = [{ label: what, values: mean, color: "#1f4e99" }];
    if (atTask) {
      lines.push({ label: atTask.kind === "measured" ? "measured level walking at this speed"
        : "measured level walking + measured ramp change", values: x.map((xx) => interp(xx, refX, atTask[key]) * k),
      color: "#888888", dash: [6, 4], width: 1.5 });
    }
    phaseChart(el, { title: label, yLabel: label.match(/\((.*)\)/)[1], x, markers,
      bands: [{ label: what, mean, sd, color: "#1f4e99" }], lines });
  }
}

export function featureTable(p) {
  const shown = (f) => (f.unit === "N·m/kg" ? { k: momentScale(p.task.body_mass_kg), unit: momentUnit() } : { k: 1, unit: f.unit });
  const rows = p.features.map((f) => h("tr", { class: f.extrapolation ? "warn-row" : "" },
    h("td", {}, f.label), h("td", {}, f.joint), h("td", { class: "num" }, pm(f.value * shown(f).k, f.std * shown(f).k,
      f.unit === "deg" ? 1 : shown(f).unit === "N·m" ? 1 : 3, shown(f).unit)),
    h("td", { class: "num" }, pm(f.phase * 100, f.phase_std * 100, 1, "% cycle")),
    h("td", {}, f.extrapolation ? chip("outside data", "warn") : "")));
  return table(["Feature", "Joint", "Value ± SD", "Phase ± SD", ""], rows, { id: "features" });
}

// The bench's safety figures, before any tracking error: each flagged on its own bound by the server
// (backend/bench/safety_figures.py), whatever the RMSEs say.
export function safetyFigures(flags, t, f, what = "This table") {
  const flagOf = Object.fromEntries(flags.map((x) => [x.figure, x]));
  const row = (label, figure, shown, bound) => {
    const flag = flagOf[figure];
    return h("tr", { class: flag ? `flag-${flag.severity}` : "", dataset: { figure } }, h("td", {}, label),
      h("td", { class: `num${flag ? ` ${flag.severity}` : ""}`, title: flag ? flag.message : "" }, shown(t)),
      h("td", { class: "num" }, shown(f)), h("td", { class: "muted" }, bound));
  };
  const n = (key) => (run) => fmt(run[key], 0);
  const entry = (run) => run.heel_strike_to_stance_ms_median === undefined || run.heel_strike_to_stance_ms_median === null ? "—"
    : `${fmt(run.heel_strike_to_stance_ms_median, 0)} / ${fmt(run.heel_strike_to_stance_ms_max, 0)} ms`;
  const bad = flags.filter((x) => x.severity === "bad");
  return h("div", { id: "preview-safety" },
    h("h3", {}, "Safety on the bench (read first)"),
    flags.length ? h("div", { class: `banner ${bad.length ? "bad" : "warn"}`, role: "alert", id: "preview-safety-flags" },
      h("strong", {}, bad.length ? `Safety: do not push ${what.toLowerCase()} without understanding why. ` : "Safety: review before pushing. "),
      h("ul", {}, flags.map((x) => h("li", { class: x.severity }, x.message))))
      : h("p", { class: "notice-inline ok", id: "preview-safety-flags" }, "No safety figure outside its bound on this walk."),
    table(["Safety figure", what, "FSMIC", "Bound"], [
      row("falls", "falls", n("falls"), "none"),
      row("toe catches in mid-swing", "toe_catches", n("toe_catches"), "none"),
      row("heel strikes never reaching stance", "heel_strikes_without_stance", n("heel_strikes_without_stance"), "none"),
      row("on swing settings with > ½ body weight: mean / longest stride",
        t.loaded_swing_ms_max_stride === undefined ? "loaded_swing_ms_per_stride" : "loaded_swing_ms_max_stride",
        (run) => `${fmt(run.loaded_swing_ms_per_stride, 0)} / ${fmt(run.loaded_swing_ms_max_stride, 0)} ms`,
        "longest ≤ 20 ms"),
      row("foot contact → stance settings, median / longest", "heel_strike_to_stance_ms_max", entry,
        "longest ≤ 50 ms, not 20 ms behind the FSMIC"),
      row("hip sink below a person's in stance, largest", "hip_sink_max_mm", (run) => fmt(run.hip_sink_max_mm, 0, "mm"),
        "≤ 50 mm"),
      row("extra push from the other leg, largest", "support_deficit_max_bw",
        (run) => fmt(run.support_deficit_max_bw, 2, "body weights"), "≤ 1.5 body weights"),
      row("knee flexion under the body in early stance: mean / largest stride", "stance_knee_flexion_peak_max_deg",
        (run) => (run.stance_knee_flexion_peak_deg === undefined || run.stance_knee_flexion_peak_deg === null ? "—"
          : `${fmt(run.stance_knee_flexion_peak_deg, 0)} / ${fmt(run.stance_knee_flexion_peak_max_deg, 0)}°`),
        t.reference_stance_knee_flexion_peak_deg === undefined ? "largest ≤ 40°"
          : `largest ≤ 40° (people: ${fmt(t.reference_stance_knee_flexion_peak_deg, 0)}°)`)],
    { id: "preview-safety-table" }),
    h("p", { class: "muted small" }, "Safety figures are not scores: how often the foot caught or the leg gave way, how ",
      "long a loaded leg stayed on the weak swing settings after the foot touched down, and how well the leg carried the ",
      "body (the bench's body rides on the leg; the person's other leg and hip add what it does not carry)."));
}
