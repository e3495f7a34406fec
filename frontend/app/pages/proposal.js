// Proposal review: loops, curves with bands, GPR features, the table (editable into a new version), diff,
// approve/reject, push with live status, and the simulated preview against the FSMIC.
import { get } from "../api.js";
import { app, onLeave } from "../state.js";
import { legend, phaseChart } from "../widgets/charts.js";
import { benchLegNote, drawCurves, drawLoops, explainVias, featureTable, reference, safetyFigures } from "../widgets/proposal_views.js";
import { parameterTable, tableView } from "../widgets/parameter_table.js";
import { shownChange, shownNumber, signed } from "../quantities.js";
import { renderDecision } from "../widgets/decision_panel.js";
import { renderPush } from "../widgets/push_panel.js";
import { renderRefine } from "../widgets/refine_panel.js";
import { fieldWords, FIT_METHOD_WORDS, fmt, inWords, h, momentScale, momentToggle, momentUnit, momentView,
  referenceLabel, SUBPHASE_COLOUR, SUBPHASE_LABEL, SUBPHASES, swingInertiaWords, table, when } from "../ui.js";
import { versionChips, walkedPreview } from "../widgets/version_head.js";

export async function proposalPage(view, id) {
  const p = await get(`/api/proposals/${id}`);
  const [ref, patient] = await Promise.all([reference(p.task), get(`/api/patients/${p.patient_id}`)]);
  const mass = p.task.body_mass_kg;
  const canDecide = app.me.role === "prosthetist";
  const atTask = ref.at_task;   // null: nothing measured this steep

  const worseSlot = h("div", { id: "worse-slot" });   // worse on the bench than its parent: said first
  const head = [
    h("p", { class: "crumbs" }, h("a", { href: "#/patients" }, "Patients"), " / ",
      h("a", { href: `#/patients/${patient.id}` }, patient.code_name), " / ", `table v${p.version}`),
    h("h1", {}, `${p.table_label} · ${fmt(p.task.speed_mps, 2, "m/s")} · incline ${fmt(p.task.incline_deg, 1, "°")}`),
    worseSlot,
    headChips(p),
    h("p", { class: "provenance" }, `Model ${p.model.version} · training data sha256 ${p.model.data_sha256.slice(0, 12)}… · `,
      `patient mass ${fmt(mass, 1, "kg")} · `, swingInertiaWords(p.swing_inertia),
      `created by ${p.created_by} ${when(p.created_at)} · table sha256 `,
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
    ...SUBPHASES.map((sp) => [SUBPHASE_COLOUR[sp], `${SUBPHASE_LABEL[sp]} fit τ = −K(θ − θe)`, "dash"])]);
  const curveBox = h("div", { class: "four", id: "curves" });
  const decisionBox = h("section", { class: "card", id: "decision" });
  const pushBox = h("section", { class: "card", id: "push" });
  const previewBox = h("section", { class: "card", id: "preview" }, h("h2", {}, "Simulated preview: this table vs the FSMIC"),
    h("p", { class: "muted", id: "preview-status" }, "Walking both controllers on the simulated bench…"));

  const refineBox = h("section", { class: "card", id: "refine" });
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
    decisionBox, pushBox, refineBox, h("section", { class: "card", id: "versions" }), previewBox);

  renderRefine(refineBox, { kind: "proposal", item: p, canRefine: canDecide });
  drawLoops(p, ref, atTask);
  explainVias(p, document.getElementById("via-note"));
  drawCurves(p, atTask, curveBox);
  renderDecision(decisionBox, { item: p, name: p.table_label, path: `/api/proposals/${p.id}`, canDecide, worseSlot,
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

function headChips(p) {
  return versionChips(p, "proposal-chips", "within parameter limits");
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
    const mass = p.task.body_mass_kg;
    out.replaceChildren(d.changes.length ? table([`Setting`, `v${d.from_version}`, `v${d.to_version} (this)`, "Change", "%", "Unit"],
      d.changes.map((c) => {
        const numeric = typeof c.before === "number" && typeof c.after === "number";
        const ch = numeric ? shownChange(c.field, c.before, c.after, mass) : null;
        return h("tr", {}, h("td", { title: c.field }, tableView.view === "clinical" ? fieldWords(c.field) : c.field),
          h("td", { class: "num" }, shownValue(c.field, c.before, mass)),
          h("td", { class: "num changed" }, shownValue(c.field, c.after, mass)),
          h("td", { class: "num" }, ch ? signed(ch.change, ch.digits) : ""),
          h("td", { class: "num" }, ch?.percent === null || !ch ? "—" : `${signed(ch.percent, 1)} %`),
          h("td", {}, ch ? ch.unit : ""));
      }), { id: "diff-table" }) : h("p", {}, "No differences."));
  };
  other.addEventListener("change", show);
  box.replaceChildren(h("h2", {}, "Versions and differences"),
    versions.length > 1 ? h("div", { class: "inline" }, h("label", {}, "Compare with ", other)) : h("p", { class: "muted" }, "Only one version so far."),
    out);
  await show();
}

function shownValue(field, v, mass) {
  if (field.endsWith(".fit_method")) return tableView.view === "clinical" ? FIT_METHOD_WORDS[v] ?? v : v;
  return typeof v === "number" ? shownNumber(field, v, mass) : v ?? "—";
}

async function renderPreview(box, p) {
  const pv = await walkedPreview(box, `/api/proposals/${p.id}`, "table preview");
  if (!pv) return;
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
    benchLegNote(pv.leg, p.leg),
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
