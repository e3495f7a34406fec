// Proposal review: loops, curves with bands, GPR features, the table (editable into a new version), diff,
// approve/reject, push with live status, and the simulated preview against the FSMIC.
import { get } from "../api.js";
import { app, onLeave } from "../main.js";
import { legend, loopChart, phaseChart } from "../charts.js";
import { parameterTable, tableView } from "./parameter_table.js";
import { BENCH_CHIP, renderDecision } from "../decision_panel.js";
import { renderPush } from "../push_panel.js";
import { chip, extrapolationChip, fieldWords, FIT_METHOD_WORDS, fmt, inWords, h, momentScale, momentToggle, momentUnit, momentView,
  pm, referenceLabel, SUBPHASE_COLOUR, SUBPHASE_LABEL, SUBPHASES, table, when } from "../ui.js";

const RAD = Math.PI / 180;

// the measured conditions behind the model, and the reference at this task with what it really is
export function reference(task) {
  return get(`/api/reference?speed_mps=${task.speed_mps}&incline_deg=${task.incline_deg}`);
}

export async function proposalPage(view, id) {
  const p = await get(`/api/proposals/${id}`);
  const [ref, patient] = await Promise.all([reference(p.task), get(`/api/patients/${p.patient_id}`)]);
  const mass = p.task.body_mass_kg;
  const canDecide = app.me.role === "prosthetist";
  const atTask = ref.at_task;   // null: nothing measured this steep

  const head = [
    h("p", { class: "crumbs" }, h("a", { href: "#/patients" }, "Patients"), " / ",
      h("a", { href: `#/patients/${patient.id}` }, patient.code_name), " / ", `table v${p.version}`),
    h("h1", {}, `${p.table_label} · ${fmt(p.task.speed_mps, 2, "m/s")} · incline ${fmt(p.task.incline_deg, 1, "°")}`),
    headChips(p),
    h("p", { class: "provenance" }, `Model ${p.model.version} · training data sha256 ${p.model.data_sha256.slice(0, 12)}… · `,
      `patient mass ${fmt(mass, 1, "kg")} · created by ${p.created_by} ${when(p.created_at)} · table sha256 `,
      h("span", { class: "mono" }, p.table_sha256.slice(0, 12) + "…"),
      p.edit_comment ? ` · edit: “${p.edit_comment}”` : "",
      p.decision ? ` · ${p.decision.status} by ${p.decision.by} ${when(p.decision.at)}${p.decision.comment ? `: “${p.decision.comment}”` : ""}` : ""),
  ];
  if (p.extrapolation) {
    const outside = p.features.filter((f) => f.extrapolation).map((f) => f.label).join(", ");
    head.push(h("div", { class: "banner warn", role: "alert", id: "extrapolation" },
      h("strong", {}, p.extrapolation_reason ? "Extrapolated beyond what the model knows: " : "Extrapolation: "),
      "this task is outside the walking data the model was trained on. ",
      "Predictions there are less certain (see the ± SD); review every value. Outside: ", outside || "task hull",
      p.extrapolation_reason ? h("span", { id: "extrapolation-reason" }, `. Requested anyway by the prosthetist: “${p.extrapolation_reason}”`) : ""));
  }
  if (!p.safety.ok) {
    head.push(h("div", { class: "banner bad", role: "alert" }, h("strong", {}, "Safety limits: "),
      p.safety.violations.map((v) => inWords(v.message, v.field)).join("; ")));
  }

  const loops = h("div", { class: "two" }, h("figure", { id: "loop-knee", class: "chart" }),
    h("figure", { id: "loop-ankle", class: "chart" }));
  const loopLegend = legend([["#1f4e99", "proposal (KMP mean) with ±1 SD band", "band"],
    ["#999", atTask ? `grey: measured level walking; bold: reference at this task — ${atTask.label}`
      : "grey: measured level walking (no curves were measured this steep: the proposal is the model's prediction)"],
    ["#222", "via-points: the GPR's predicted peaks at this task; the loop passes close to a confident one, only near an uncertain one", "star"],
    ...SUBPHASES.map((sp) => [SUBPHASE_COLOUR[sp], `${SUBPHASE_LABEL[sp]} fit τ = k(θ − θe)`, "dash"])]);
  const curveBox = h("div", { class: "four", id: "curves" });
  const decisionBox = h("section", { class: "card", id: "decision" });
  const pushBox = h("section", { class: "card", id: "push" });
  const previewBox = h("section", { class: "card", id: "preview" }, h("h2", {}, "Simulated preview: this table vs the FSMIC"),
    h("p", { class: "muted", id: "preview-status" }, "Walking both controllers on the simulated bench…"));

  view.replaceChildren(...head,
    h("section", { class: "card" }, h("div", { class: "inline" }, h("h2", {}, "Torque-angle loops"),
      momentToggle(mass, () => proposalPage(document.getElementById("view"), p.id))), loops, loopLegend,
      h("p", { class: "small", id: "via-note" }),
      h("p", { class: "muted small", id: "reference-note" }, `Moments on this page in ${momentUnit()}: internal joint moments `,
        momentView.unit === "Nm" ? `of this patient (N·m = N·m/kg × ${fmt(mass, 1, "kg")})` : "per kg of body mass",
        ", flexor / dorsiflexor positive. ", atTask
          ? `Reference at this task: ${atTask.source}. Data: ${atTask.citations.join(" ")}`
          : `No measured curves at ${fmt(p.task.incline_deg, 1, "°")}: the reference is the model's own prediction, not data.`)),
    h("section", { class: "card" }, h("h2", {}, "Over the gait cycle"), curveBox,
      h("p", { class: "muted small" }, "Dotted lines: sub-phase boundaries (stance flexion | stance extension | swing flexion | swing extension).")),
    h("section", { class: "card" }, h("h2", {}, "Predicted features (GPR, ±1 SD)"), featureTable(p)),
    h("section", { class: "card", id: "table-card" }, parameterTable(p, canDecide)),
    decisionBox, pushBox, h("section", { class: "card", id: "versions" }), previewBox);

  drawLoops(p, ref, atTask);
  explainVias(p, document.getElementById("via-note"));
  drawCurves(p, atTask, curveBox);
  renderDecision(decisionBox, { item: p, name: p.table_label, path: `/api/proposals/${p.id}`, canDecide,
    reload: () => proposalPage(document.getElementById("view"), p.id) });
  renderPush(pushBox, { item: p, kind: "table", name: p.table_label, canPush: canDecide, patient,
    what: `${p.table_label} (${fmt(p.task.speed_mps, 2, "m/s")}, incline ${fmt(p.task.incline_deg, 1, "°")})`,
    path: `/api/proposals/${p.id}` });
  app.proposalInteractiveAt = performance.now();
  if (app.proposalReturnedAt !== undefined) {
    app.proposalViewMs = app.proposalInteractiveAt - app.proposalReturnedAt;
    app.proposalReturnedAt = undefined;
  }
  renderVersions(document.getElementById("versions"), p);
  renderPreview(previewBox, p);
  // a push (here or elsewhere in this tab) changes where this version runs: the header follows without a reload
  const refresh = async () => {
    const now = await get(`/api/proposals/${p.id}`).catch(() => null);
    if (now) document.getElementById("proposal-chips")?.replaceWith(headChips(now));
  };
  window.addEventListener("quasitune:device-changed", refresh);
  window.addEventListener("quasitune:bench-walked", refresh);
  onLeave(() => {
    window.removeEventListener("quasitune:device-changed", refresh);
    window.removeEventListener("quasitune:bench-walked", refresh);
  });
}

const DEPLOYMENT_WORDS = { pushed: ["sent to a leg, waiting for heel strike", "warn"],
  active_on_device: ["running on a leg", "ok"], replaced: ["was on a leg, since replaced", ""],
  unconfirmed: ["push unconfirmed: waiting for the leg's status", "warn"],
  not_on_device: ["no longer on the leg (the leg reported it does not hold it)", "bad"],
  push_failed: ["last push failed", "bad"] };

function headChips(p) {
  const [words, kind] = DEPLOYMENT_WORDS[p.deployment] || [];
  return h("p", { class: "chips", id: "proposal-chips" }, chip(p.status, p.status),
    words ? chip(words, kind) : null,
    chip(p.safety.ok ? "within parameter limits" : "outside parameter limits", p.safety.ok ? "ok" : "bad"),
    p.bench ? h("span", { id: "bench-chip" }, chip(p.bench.words, BENCH_CHIP[p.bench.status])) : null,
    p.decision?.override_reason ? chip("approved without a clean bench preview", "warn") : null,
    p.extrapolation_reason ? extrapolationChip(p) : null,
    p.source === "edit" ? chip(`edited from v${p.parent_version}`) : chip("model"));
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

function interp(x, xs, ys) {
  if (x <= xs[0]) return ys[0];
  for (let i = 1; i < xs.length; i++) {
    if (x <= xs[i]) return ys[i - 1] + (ys[i] - ys[i - 1]) * (x - xs[i - 1]) / (xs[i] - xs[i - 1]);
  }
  return ys[ys.length - 1];
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

// ---------------------------------------------------------------------------------------------- versions, preview

async function renderVersions(box, p) {
  const versions = await get(`/api/patients/${p.patient_id}/proposals`);
  const other = h("select", { id: "diff-other", "aria-label": "Compare with version" },
    versions.filter((v) => v.id !== p.id).map((v) => h("option", { value: v.id, selected: v.id === p.parent_id },
      `v${v.version} (${v.status}, ${fmt(v.task.speed_mps, 2)} m/s)`)));
  const out = h("div", { id: "diff" });
  const show = async () => {
    if (!other.value) return;
    const d = await get(`/api/proposals/${other.value}/diff/${p.id}`);
    out.replaceChildren(d.changes.length ? table([`Field`, `v${d.from_version}`, `v${d.to_version} (this)`, "Unit"],
      d.changes.map((c) => h("tr", {}, h("td", { title: c.field }, tableView.view === "clinical" ? fieldWords(c.field) : c.field), h("td", { class: "num" }, shownValue(c.field, c.before)),
        h("td", { class: "num changed" }, shownValue(c.field, c.after)), h("td", {}, c.unit || "")))) : h("p", {}, "No differences."));
  };
  other.addEventListener("change", show);
  box.replaceChildren(h("h2", {}, "Versions and differences"),
    versions.length > 1 ? h("div", { class: "inline" }, h("label", {}, "Compare with ", other)) : h("p", { class: "muted" }, "Only one version so far."),
    out);
  await show();
}

function shownValue(field, v) {
  return field.endsWith(".fit_method") && tableView.view === "clinical" ? FIT_METHOD_WORDS[v] ?? v : fmtAny(v);
}

function fmtAny(v) {
  return typeof v === "number" ? (Math.abs(v) >= 100 ? v.toFixed(1) : v.toFixed(3)) : v ?? "—";
}

async function renderPreview(box, p) {
  let alive = true;
  onLeave(() => { alive = false; });
  let pv;
  try {
    pv = await get(`/api/proposals/${p.id}/preview`);
    window.dispatchEvent(new CustomEvent("quasitune:bench-walked", { detail: { path: `/api/proposals/${p.id}` } }));
  } catch (err) {
    if (alive) box.querySelector("#preview-status").textContent = `Preview failed: ${err.message}`;
    return;
  }
  if (!alive) return;
  const t = pv.controllers.table, f = pv.controllers.fsmic, vs = t.vs_fsmic || {};
  const metric = (label, key, d, unit) => h("tr", {}, h("td", {}, label), h("td", { class: "num" }, fmt(t[key], d, unit)),
    h("td", { class: "num" }, fmt(f[key], d, unit)), h("td", {}));
  // an RMSE with its 95 % interval over strides, and this table's difference from the FSMIC with its verdict;
  // previews stored before the intervals existed show the point estimates only
  const rmseRow = (label, base, u, unitIn, dIn) => {
    // moments in the page's unit (RMSE scales with it); angles as they come
    const k = u === "Nm_per_kg" ? momentScale(p.task.body_mass_kg) : 1;
    const unit = u === "Nm_per_kg" ? momentUnit() : unitIn, d = u === "Nm_per_kg" && unit === "N·m" ? 1 : dIn;
    const key = `${base}_rmse_${u}`, ciKey = `${base}_rmse_ci95_${u}`;
    const x = (v) => (v === null || v === undefined ? v : v * k);
    const withCi = (run) => fmt(x(run[key]), d) + (run[ciKey] ? ` [${fmt(x(run[ciKey][0]), d)}, ${fmt(x(run[ciKey][1]), d)}]` : "")
      + ` ${unit}`;
    const diff = x(vs[`${base}_rmse_difference_${u}`]), diffCi = vs[`${base}_rmse_difference_ci95_${u}`]?.map(x);
    const verdict = { "learned lower": "this table lower", "FSMIC lower": "FSMIC lower" }[vs[`${base}_verdict`]]
      || vs[`${base}_verdict`];
    const signed = (v) => (v > 0 ? "+" : "") + fmt(v, d);
    const diffCell = diff === undefined || diff === null ? "—"
      : `${signed(diff)} [${signed(diffCi[0])}, ${signed(diffCi[1])}] ${unit}: ${verdict}`;
    return h("tr", {}, h("td", {}, label), h("td", { class: "num" }, withCi(t)), h("td", { class: "num" }, withCi(f)),
      h("td", { class: verdict === "not resolved" ? "num muted" : "num" }, diffCell));
  };
  const x = pv.phase_grid.map((s) => s * 100);
  const charts = h("div", { class: "two" });
  box.replaceChildren(...[h("h2", {}, "Simulated preview: this table vs the FSMIC"),
    h("p", { class: "muted small" }, `Both controllers walked ${fmt(pv.seconds, 0, "s")} each on the MuJoCo bench at this task `,
      `(socket driven along the able-bodied hip trajectory; metrics as in quasitune simulate). Reference: ${referenceLabel(t)} (${t.reference_source}). `,
      `Simulated ${when(pv.created_at)}.`),
    safetyFigures(pv.safety || [], t, f),
    h("h3", {}, "Tracking the reference"),
    table(["Metric", "This table", "FSMIC (hand-tuned, not re-tuned)", "This table − FSMIC, 95 % interval"], [
      metric("strides", "strides", 0),
      rmseRow("knee angle RMSE", "knee_angle", "deg", "deg", 1), rmseRow("ankle angle RMSE", "ankle_angle", "deg", "deg", 1),
      rmseRow("knee moment RMSE", "knee_moment", "Nm_per_kg", "N·m/kg", 3),
      rmseRow("ankle moment RMSE", "ankle_moment", "Nm_per_kg", "N·m/kg", 3),
      metric("cadence", "cadence_steps_per_min", 1, "steps/min")],
    { id: "preview-metrics" }),
    (pv.safety || []).length ? h("p", { class: "notice-inline warn small" },
      "Lower tracking errors do not outweigh the safety flags above.") : null,
    h("p", { class: "muted small" }, "[a, b]: 95 % interval over the strides walked (strides resampled with replacement). ",
      "\"not resolved\": with these strides either controller could be the lower one. A preview walks only a few strides, ",
      "and the FSMIC's strides change over a longer walk, so a longer walk can change the verdict (quasitune simulate ",
      "--seconds 20). The intervals say nothing about the bench's own assumptions (docs/results.md)."),
    charts].filter(Boolean));
  for (const key of ["knee_angle_deg", "ankle_angle_deg"]) {
    const el = h("figure", { class: "chart" });
    charts.append(el);
    phaseChart(el, { title: `${key.split("_")[0]} angle (deg), stride mean`, yLabel: "deg", x, lines: [
      { label: `reference: ${referenceLabel(t)}`, values: pv.reference_curves[key], color: "#222222" },
      { label: "this table", values: t.mean_curves[key] || x.map(() => null), color: "#1f4e99" },
      { label: "FSMIC", values: f.mean_curves[key] || x.map(() => null), color: "#E69F00", dash: [6, 3] }] });
  }
}

// The bench's safety figures, before any tracking error: each flagged on its own bound by the server
// (backend/experiments/safety_figures.py), whatever the RMSEs say.
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
        "longest ≤ 50 ms, not 20 ms behind the FSMIC")],
    { id: "preview-safety-table" }),
    h("p", { class: "muted small" }, "Safety figures are not scores: how often the foot caught or the leg gave way, and how ",
      "long a loaded leg stayed on the weak swing settings after the foot touched down."));
}
