// One node of an envelope, shown as a proposal is: the torque-angle loops, the curves over the gait cycle and the
// GPR features at the node's task (the model's prediction there), and the node's own table as the envelope holds it
// (fitted, held to the neighbour rule, edited). Read-only: an envelope is edited as a whole, on its page.
import { get } from "../api.js";
import { legend } from "../widgets/charts.js";
import { drawCurves, drawLoops, explainVias, featureTable, reference } from "../widgets/proposal_views.js";
import { parameterTable } from "../widgets/parameter_table.js";
import { chip, fieldWords, fmt, h, momentToggle, SUBPHASE_COLOUR, SUBPHASE_LABEL, SUBPHASES, table } from "../ui.js";

export async function envelopeNodePage(view, id, i, j) {
  const p = await get(`/api/envelopes/${id}/nodes/${i}/${j}`);
  const [ref, patient] = await Promise.all([reference(p.task), get(`/api/patients/${p.patient_id}`)]);
  const atTask = ref.at_task;
  const mass = p.task.body_mass_kg;
  const guarded = Object.entries(p.neighbour_guarded);
  const head = [
    h("p", { class: "crumbs" }, h("a", { href: "#/patients" }, "Patients"), " / ",
      h("a", { href: `#/patients/${patient.id}` }, patient.code_name), " / ",
      h("a", { href: `#/envelopes/${p.envelope_id}`, id: "back-to-envelope" }, p.envelope_label), " / ",
      `node ${fmt(p.task.speed_mps, 2, "m/s")}, ${fmt(p.task.incline_deg, 1, "°")}`),
    h("h1", {}, `${p.envelope_label} · node at ${fmt(p.task.speed_mps, 2, "m/s")} · incline ${fmt(p.task.incline_deg, 1, "°")}`),
    h("p", { class: "chips" }, chip(`envelope ${p.envelope_status}`, p.envelope_status),
      chip(p.safety.ok ? "within parameter limits" : "outside parameter limits", p.safety.ok ? "ok" : "bad"),
      p.extrapolation ? chip("outside the training data", "warn") : chip("inside the training data", "ok")),
    h("p", { class: "provenance" }, `Table: as the envelope holds it (built by model ${p.envelope_model.version}). Loops, curves and `,
      `features: the model serving now (${p.model.version}) at this task, for ${fmt(mass, 1, "kg")}.`,
      p.model.version !== p.envelope_model.version ? " The models differ: the curves may not be what the table was fitted to." : ""),
  ];
  if (guarded.length) {
    head.push(h("div", { class: "banner warn", id: "guarded" }, h("strong", {}, "Held to the neighbour rule: "),
      guarded.map(([field, fitted]) => `${fieldWords(field)} (the fit gave ${fmt(fitted, 2)})`).join("; "),
      ". These values differ from the loop's fit so that no blend between neighbouring nodes is unsafe."));
  }
  const loops = h("div", { class: "two" }, h("figure", { id: "loop-knee", class: "chart" }), h("figure", { id: "loop-ankle", class: "chart" }));
  const curveBox = h("div", { class: "four", id: "curves" });
  const stds = Object.entries(p.feature_std);
  view.replaceChildren(...head,
    h("section", { class: "card" }, h("div", { class: "inline" }, h("h2", {}, "Torque-angle loops at this node"),
      momentToggle(mass, () => envelopeNodePage(document.getElementById("view"), id, i, j))), loops,
      legend([["#1f4e99", "model prediction (KMP mean) with ±1 SD band", "band"],
        ["#999", atTask ? `grey: measured level walking; bold: reference at this task — ${atTask.label}` : "grey: measured level walking"],
        ["#222", "via-points: the GPR's predicted peaks at this task", "star"],
        ...SUBPHASES.map((sp) => [SUBPHASE_COLOUR[sp], `${SUBPHASE_LABEL[sp]}: this node's τ = −K(θ − θe)`, "dash"])]),
      h("p", { class: "small", id: "via-note" })),
    h("section", { class: "card" }, h("h2", {}, "Over the gait cycle"), curveBox),
    h("section", { class: "card" }, h("h2", {}, "Predicted features (GPR, ±1 SD)"), featureTable(p),
      stds.length ? h("details", {}, h("summary", {}, "Feature SDs stored with the envelope"),
        table(["Feature", "SD"], stds.map(([k, v]) => h("tr", {}, h("td", {}, k), h("td", { class: "num" }, fmt(v, 3)))))) : null),
    h("section", { class: "card", id: "table-card" }, parameterTable(p, false)));
  drawLoops(p, ref, atTask);
  explainVias(p, document.getElementById("via-note"));
  drawCurves(p, atTask, curveBox, "model prediction at this node");
}
