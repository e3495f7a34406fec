// "Refine from walking": the patient's stopped sessions on an approved version → a refined draft, and the evidence of
// a refinement (strides per node, per node the errors measured on the leg, what the step expects and what the bench
// expects, what changed and why, nodes left alone and why). The draft is decided like any version.
import { get, post } from "../api.js";
import { shownChange, signed, units } from "../quantities.js";
import { chip, fieldWords, fmt, h, table, when } from "../ui.js";
import { watchBench } from "./bench_progress.js";

const UNIT = { deg: "°", "% gait cycle": "% cycle" };

// strides per node as the leg blended them (incline rows top-down), changed nodes marked
function strideMap(ev, speeds, inclines) {
  if (!speeds || !inclines || speeds.length * inclines.length === 1) return null;
  const at = new Map(ev.nodes.map((n) => [`${n.node[0]},${n.node[1]}`, n]));
  return h("table", { class: "histogram", id: "refine-map" },
    h("caption", {}, "Strides per node (the leg's own estimate of each stride's task, shared by the blend weights); ● changed"),
    h("thead", {}, h("tr", {}, h("th", { scope: "col" }, "incline \\ speed"), speeds.map((v) => h("th", { scope: "col" }, fmt(v, 2, "m/s"))))),
    h("tbody", {}, [...inclines.keys()].reverse().map((j) => h("tr", {},
      h("th", { scope: "row" }, `${inclines[j] > 0 ? "+" : ""}${fmt(inclines[j], 1, "°")}`),
      speeds.map((_, i) => {
        const n = at.get(`${i},${j}`);
        const td = h("td", { class: `num${n?.strides ? " filled" : ""}`, dataset: { cell: `${i},${j}` } },
          n?.strides ? `${fmt(n.stride_weight, 1)}${n.changed ? " ●" : ""}` : "—");
        if (n?.strides) td.style.setProperty("--f", String(Math.min(1, n.stride_weight / 20)));
        return td;
      })))));
}

function nodeCard(n, ev) {
  const qs = ev.quantities;
  const rows = Object.entries(n.quantities).map(([key, q]) => {
    const unit = UNIT[qs[key]?.unit] || "";
    const bench = n.bench?.walked ? signed(n.bench.change?.[key]) : "—";
    return h("tr", { class: q.act ? "" : "muted" }, h("td", {}, qs[key]?.label || key),
      h("td", { class: "num" }, q.strides ? `${fmt(q.effective_strides, 1)}` : "0"),
      h("td", { class: "num" }, q.measured === null ? "—" : `${fmt(q.measured, 1)}${unit}`),
      h("td", { class: "num" }, q.target === null ? "—" : `${fmt(q.target, 1)}${unit}`),
      h("td", { class: "num" }, q.error === null ? "—" : `${signed(q.error)}${unit}${q.ci95 ? ` [${signed(q.ci95[0])}, ${signed(q.ci95[1])}]` : ""}`),
      h("td", { class: "num" }, q.spread === null || q.spread === undefined ? "—" : `±${fmt(q.spread, 1)}${unit}`),
      h("td", { class: "num" }, q.expected_error === null || q.expected_error === undefined ? "—" : `${signed(q.expected_error)}${unit}`),
      h("td", { class: "num" }, bench),
      h("td", {}, q.act ? chip("acted on", "ok") : q.held === "out of reach" ? chip("beyond a round's reach", "warn") : "", " ", q.reason));
  });
  return h("details", { class: "refine-node", open: n.changed, dataset: { node: n.node.join(",") } },
    h("summary", {}, `${fmt(n.speed_mps, 2, "m/s")}, ${n.incline_deg > 0 ? "+" : ""}${fmt(n.incline_deg, 1, "°")}: `,
      `${fmt(n.stride_weight, 1)} strides (blend-weighted, as on the map) · `, n.changed ? chip("changed", "warn") : chip(n.left_alone || "left alone")),
    table(["Quantity", "Strides with this quantity (blend-weighted)", "Measured", "Target", "Bias: mean error [95 % interval]",
      "Spread from stride to stride (no row moves it)", "Expected after (step)", "Bench: change", "Acted on?"], rows),
    n.transition_strides ? h("p", { class: "muted small transition-strides" }, `${n.transition_strides} more stride(s) here `,
      "were within a change of task (the leg's estimate moving): shown as evidence of the change, not used for this node.") : null,
    n.step_refused ? h("p", { class: "small" }, chip(`step at ${fmt(n.step_scale * 100, 0)} %`, "warn"),
      ` The bench refused a larger step here: ${n.step_refused}.`) : null,
    n.bench?.walked ? h("p", { class: "muted small" }, `Bench: the old and new rows walked ${fmt(n.bench.seconds, 0, "s")} at this task `,
      `(falls ${n.bench.falls_before} → ${n.bench.falls_after}); the bench is not the patient, so read the change.`) : null);
}

// the evidence and the changes of one refinement
// a change in the table's units (resistance positive, loads in % body weight), with digits enough to show it
function changeWords(c, mass) {
  const u = units(c.field, mass);
  const ch = shownChange(c.field, c.before, c.after, mass);
  let digits = u.digits;
  while (Math.abs(ch.change) > 0 && Math.abs(ch.change) < 10 ** -digits && digits < 4) digits += 1;
  const v = (x) => fmt(x * u.scale + 0, digits);
  return `${fieldWords(c.field)} ${v(c.before)} → ${v(c.after)} ${u.unit} (${signed(ch.change, digits)}`
    + `${ch.percent === null ? "" : `, ${signed(ch.percent, 1)} %`})`
    + (c.held_from !== undefined ? ` (held within a step of its neighbours; the step gave ${v(c.held_from)})` : "");
}

export function refinementView(ev, grid = {}, mass = null) {
  const changes = ev.changes.map((c) => h("li", {}, h("strong", {}, `${fmt(c.speed_mps, 2)} m/s, ${c.incline_deg > 0 ? "+" : ""}${fmt(c.incline_deg, 1)}°: `),
    changeWords(c, mass), h("span", { class: "muted" }, ` — ${c.why}`)));
  const errs = Object.entries(ev.feature_abs_error).map(([k, v]) => `${ev.quantities[k]?.label || k} ${fmt(v, 1)}${UNIT[ev.quantities[k]?.unit] || ""}`);
  return h("div", { id: "refinement" },
    h("p", {}, `From session(s) ${ev.session_ids.map((s) => `#${s}`).join(", ")}: ${ev.strides} strides, ${ev.strides_on_version} on the version, `,
      `${ev.strides_used} compared with the model's targets at each stride's task. Mean absolute error: ${errs.join("; ")}.`),
    Object.keys(ev.strides_without_feature).length ? h("p", { class: "small" }, "Strides without a feature (counted, not guessed): ",
      Object.entries(ev.strides_without_feature).map(([k, v]) => `${k.replaceAll("_", " ")} ${v}`).join(", "), ".") : null,
    strideMap(ev, grid.speeds, grid.inclines),
    h("h3", {}, "What changed and why"),
    changes.length ? h("ul", { id: "refine-changes" }, changes) : h("p", {}, "Nothing."),
    h("h3", {}, "Per node"),
    ev.nodes.filter((n) => n.strides).map((n) => nodeCard(n, ev)),
    h("p", { class: "muted small" }, `A node's quantity is acted on with at least ${fmt(ev.rules.min_consistent_strides, 0)} strides, `,
      "80 % of them on the same side of the target, beyond the tolerance and with a 95 % interval clear of zero. ",
      `Sensitivity: ${ev.sensitivity}. ${ev.bench_leg ? `The bench walked ${ev.bench_leg}. ` : ""}Steps per round at most ${fmt(ev.rules.theta_step_deg, 0, "°")} of equilibrium angle and `,
      `${fmt(ev.rules.k_step_fraction * 100, 0)} % of stiffness or damping; every limit and the neighbour rule hold. `,
      "A quantity one round could move by less than a quarter of its error is held as beyond a round's reach and left to you (larger changes by hand, previewed on the bench, may still move it)."));
}

// the card on an envelope's or a table's page (kind "envelope" or "proposal")
export async function renderRefine(box, { kind, item, canRefine, grid }) {
  box.replaceChildren(h("h2", {}, "Refine from walking"));
  const mass = item.task?.body_mass_kg ?? item.body_mass_kg ?? null;
  const made = await get(`/api/${kind}s/${item.id}/refinement`);   // null: not made by a refinement
  if (made) {
    box.append(h("p", { class: "banner warn", id: "refined-from" }, h("strong", {}, "Made by a refinement from walking: "),
      `derived from the approved version by ${made.created_by} ${when(made.created_at)}. Review it like any draft: `,
      "the diff below, its bench preview, then approve or reject."), refinementView(made, grid, mass));
  }
  if (item.status !== "approved") {
    if (!made) box.append(h("p", { class: "muted" }, "A refinement derives from the approved version the leg walked; this one is ", item.status, "."));
    return;
  }
  const sessions = (await get(`/api/patients/${item.patient_id}/sessions`))
    .filter((s) => s.status === "stopped" && (kind === "envelope" ? s.envelope_id === item.id : s.proposal_id === item.id));
  if (!sessions.length) {
    box.append(h("p", { class: "muted", id: "refine-none" }, "No stopped session on this version yet: record the patient walking on it first."));
    return;
  }
  const picks = sessions.map((s) => h("label", { class: "block" }, h("input", { type: "checkbox", name: "session", value: s.id, checked: true }),
    ` #${s.id} · ${when(s.started_at)} · ${s.summary?.strides ?? "?"} strides · ${s.task_words}`));
  const comment = h("input", { id: "refine-comment", required: true, size: 40, maxlength: 2000, "aria-label": "Why" });
  const error = h("p", { class: "error", role: "alert", id: "refine-error" });
  const out = h("div", { id: "refine-result" });
  const form = h("form", { id: "refine-form" }, h("fieldset", {}, h("legend", {}, "Sessions on this version"), picks),
    h("div", { class: "inline" }, h("label", {}, "Why (required, audited) ", comment),
      h("button", { type: "submit", disabled: !canRefine }, "Refine from walking")),
    h("p", { class: "muted small" }, "The result is a new draft, never a push: review, preview, approve or reject it like any version."),
    error, out);
  form.addEventListener("submit", async (ev) => {
    ev.preventDefault();
    error.replaceChildren();
    out.replaceChildren(h("p", { class: "muted" }, "Reading the strides and walking the changed nodes on the bench…"));
    const ids = [...form.querySelectorAll("input[name=session]:checked")].map((c) => Number(c.value));
    const stopWatching = watchBench(out, `/api/${kind}s/${item.id}`, "refinement");
    try {
      const r = await post(`/api/${kind}s/${item.id}/refinements`, { session_ids: ids, comment: comment.value });
      const id = kind === "envelope" ? r.envelope_id : r.proposal_id;
      out.replaceChildren(h("p", {}, h("a", { href: `#/${kind}s/${id}`, id: "refined-link" }, `Open the refined draft v${r.version.version}`)),
        refinementView(r, grid, mass));
    } catch (err) {
      out.replaceChildren();
      error.append(err.message);
      if (err.body?.nodes) out.append(refinementView({ session_ids: ids, strides: 0, strides_on_version: 0, strides_used: 0,
        feature_abs_error: {}, strides_without_feature: {}, quantities: {}, nodes: err.body.nodes, changes: [],
        rules: { min_consistent_strides: 10, theta_step_deg: 5, k_step_fraction: 0.25 }, sensitivity: "—" }, grid));
    } finally {
      stopWatching();
    }
  });
  if (!canRefine) box.append(h("p", { class: "muted" }, "Only a prosthetist can refine."));
  box.append(form);
}
