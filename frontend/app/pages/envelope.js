// Envelope review: per row (joint × sub-phase) a map over speed × incline of k, θe or b, nodes outside the training
// data hatched, the measured walking conditions as dots; click a node to open it like a proposal. Edits (everywhere
// or at one node) make a new draft; decide once; push; the bench preview walks the varying-task course with this
// envelope and with the FSMIC, safety figures first.
import { get, post } from "../api.js";
import { app } from "../state.js";
import { envelopeMap, nodeGrid } from "../widgets/envelope_map.js";
import { BENCH_CHIP, flagWords, renderDecision } from "../widgets/decision_panel.js";
import { renderPush } from "../widgets/push_panel.js";
import { renderRefine } from "../widgets/refine_panel.js";
import { benchLegNote, safetyFigures } from "../widgets/proposal_views.js";
import { shownChange, shownNumber, signed, toSI, units } from "../quantities.js";
import { chip, fieldWords, fmt, h, inWords, rangeText, ROW_WORDS, SUBPHASE_LABEL, SUBPHASES, swingInertiaWords, table,
  when } from "../ui.js";
import { versionChips, walkedPreview } from "../widgets/version_head.js";

// darker reads the same way on every map: firmer (more resistance K = −k, more damping), or more flexion /
// dorsiflexion; scale: from the API's value to the shown one (resistance positive, as on every page)
const QUANTITIES = {
  k_Nm_per_rad: { label: "resistance K (larger = firmer)", short: "K", unit: "N·m/rad", digits: 0, darker: "high",
    scale: -1, keyWords: () => "darker = firmer" },
  theta_e_deg: { label: "equilibrium angle θe", short: "θe", unit: "deg", digits: 1, darker: "high", scale: 1,
    keyWords: (joint) => (joint === "knee" ? "darker = more flexed" : "darker = more dorsiflexed") },
  b_Nm_s_per_rad: { label: "damping b (a default per kg, not fitted)", short: "b", unit: "N·m·s/rad", digits: 2,
    darker: "high", scale: 1, keyWords: () => "darker = firmer" },
};
const HELD_WORDS = { range_guard: "θe held in the joint range", passivity_guard: "held resistive",
  support_floor: "held at the stance support floor", neighbour_guard: "held within a step of its neighbours" };

// per node, how a row's value was made: held at a limit, floor or neighbour's step; or a weak line fit (R² < 0.5)
function valueMark(n, joint, sp, q) {
  const r = n.table.find((x) => x.joint === joint && x.subphase === sp);
  if (!r) return null;
  const field = `${joint}.${sp}.${q}`;
  const held = field in n.neighbour_guarded ? HELD_WORDS.neighbour_guard
    : q !== "b_Nm_s_per_rad" && r.held ? HELD_WORDS[r.fit_method] || r.fit_method : null;
  return { held, weak: q !== "b_Nm_s_per_rad" && r.weak_fit };
}

export async function envelopePage(view, id, params) {
  const [e, ref] = await Promise.all([get(`/api/envelopes/${id}`), get("/api/reference")]);
  const patient = await get(`/api/patients/${e.patient_id}`);
  const canDecide = app.me.role === "prosthetist";
  const quantity = params?.get("q") in QUANTITIES ? params.get("q") : "k_Nm_per_rad";
  const nExtra = e.nodes.filter((n) => n.extrapolation).length;
  const guarded = e.nodes.filter((n) => Object.keys(n.neighbour_guarded).length);
  const worseSlot = h("div", { id: "worse-slot" });   // worse on the bench than its parent: said first
  const head = [
    h("p", { class: "crumbs" }, h("a", { href: "#/patients" }, "Patients"), " / ",
      h("a", { href: `#/patients/${patient.id}` }, patient.code_name), " / ", `envelope v${e.version}`),
    h("h1", {}, `${e.envelope_label} · ${rangeText(e)}`),
    worseSlot,
    versionChips(e, "envelope-chips", "every node within the parameter limits and the neighbour rule",
      [chip(`${e.grid[0]} × ${e.grid[1]} nodes`)]),
    h("p", { class: "provenance" }, `Model ${e.model.version} · training data sha256 ${e.model.data_sha256.slice(0, 12)}… · `,
      `patient mass ${fmt(e.body_mass_kg, 1, "kg")} · nominal task ${fmt(e.nominal.speed_mps, 2, "m/s")}, ${fmt(e.nominal.incline_deg, 1, "°")} `,
      "(the leg returns there when unsure of its task) · ", swingInertiaWords(e.swing_inertia), "created by ", e.created_by, " ", when(e.created_at), " · CRC-32 ",
      h("span", { class: "mono", id: "envelope-crc" }, e.wire_crc32 === null ? "—" : hex(e.wire_crc32)), " (as the device runs it)",
      e.edit_comment ? ` · edit: “${e.edit_comment}”` : "",
      e.decision ? ` · ${e.decision.status} by ${e.decision.by} ${when(e.decision.at)}${e.decision.comment ? `: “${e.decision.comment}”` : ""}` : ""),
  ];
  if (nExtra) {
    head.push(h("div", { class: "banner warn", role: "alert", id: "extrapolation" }, h("strong", {}, "Extrapolation: "),
      `${nExtra} of ${e.nodes.length} nodes lie outside the walking data the model was trained on (hatched on the maps). `,
      "Their tables are less certain; open them and review their values.",
      e.extrapolation_reason ? h("span", { id: "extrapolation-reason" }, ` Requested beyond what the model knows by the prosthetist: “${e.extrapolation_reason}”`) : ""));
  }
  if (!e.safety.ok) {
    head.push(h("div", { class: "banner bad", role: "alert" }, h("strong", {}, "Safety: "),
      e.safety.violations.slice(0, 6).map((v) => inWords(v.message, v.field)).join("; ")));
  }
  const picker = h("div", { class: "inline", role: "radiogroup", "aria-label": "Value shown on the maps" },
    Object.entries(QUANTITIES).map(([q, d]) => h("label", {}, h("input", { type: "radio", name: "quantity", value: q,
      checked: q === quantity, onchange: () => draw(q) }), ` ${d.label} (${d.unit})`)));
  const maps = h("div", { class: "maps", id: "envelope-maps" });
  const measured = [...ref.conditions, ...ref.ramp_conditions]
    .filter((c) => c.speed_mps !== null && c.incline_deg !== null)
    .map((c) => ({ speed_mps: c.speed_mps, incline_deg: c.incline_deg, label: `${c.name} — ${c.citation}` }));
  const mapNote = h("p", { class: "muted small", id: "map-note" }, "Each cell is one node of the grid (its task at the cell's centre); the leg ",
    "blends the four nodes around its estimated task, bilinearly, and holds at the edge beyond the grid. Hatched: outside ",
    "the training data. Dots: measured walking conditions behind the model (",
    measured.map((c) => `${fmt(c.speed_mps, 2)} m/s ${c.incline_deg > 0 ? "+" : ""}${fmt(c.incline_deg, 0)}°`).join("; "),
    "; the ±10° ramps are one participant, so the incline change is a trend, not a population). Each map has its own ",
    "colour key (its range and unit); darker always reads firmer for stiffness and damping, more flexed or dorsiflexed ",
    "for angles. ◥ corner: a value held at a limit, the stance support floor or a neighbour's step; dashed outline: a weak ",
    "fit (R² below 0.5). Click a node to open its loops, curves and table.");
  const draw = (q) => {
    const d = QUANTITIES[q];
    maps.replaceChildren();
    for (const joint of ["knee", "ankle"]) {
      for (const sp of SUBPHASES) {
        const fig = h("figure", { class: "map", dataset: { row: `${joint}.${sp}` } });
        maps.append(fig);
        envelopeMap(fig, { title: `${joint} ${SUBPHASE_LABEL[sp]} · ${d.short} (${d.unit})`, id: `map-${joint}-${sp}`,
          speeds: e.speeds_mps, inclines: e.inclines_deg, unit: d.unit, digits: d.digits, measured,
          values: nodeGrid(e, (n) => {
            const v = n.table.find((r) => r.joint === joint && r.subphase === sp)?.[q];
            return v === null || v === undefined ? null : v * d.scale + 0;
          }),
          extrapolated: nodeGrid(e, (n) => n.extrapolation), darker: d.darker, keyWords: d.keyWords(joint),
          marks: nodeGrid(e, (n) => valueMark(n, joint, sp, q)),
          onPick: (i, j) => { location.hash = `#/envelopes/${e.id}/nodes/${i}/${j}`; } });
      }
    }
    history.replaceState(null, "", `#/envelopes/${e.id}?q=${q}`);
  };
  const decisionBox = h("section", { class: "card", id: "decision" });
  const pushBox = h("section", { class: "card", id: "push" });
  const refineBox = h("section", { class: "card", id: "refine" });
  const previewBox = h("section", { class: "card", id: "preview" }, h("h2", {}, "Simulated preview: the varying-task course"),
    h("p", { class: "muted", id: "preview-status" }, "Walking the course with this envelope and with the FSMIC on the simulated bench (up to about ten seconds, once)…"));
  view.replaceChildren(...head,
    h("section", { class: "card" }, h("h2", {}, "Maps over speed × incline"), picker, maps, mapNote,
      guarded.length ? h("p", { class: "small", id: "guarded-note" }, `${guarded.length} node(s) have values held within a step of `,
        "their neighbours (the neighbour rule keeps every blend between two safe nodes safe); their tables say which.") : null),
    decisionBox, pushBox, refineBox, editCard(e, canDecide), h("section", { class: "card", id: "versions" }), previewBox);
  draw(quantity);
  renderRefine(refineBox, { kind: "envelope", item: e, canRefine: canDecide,
    grid: { speeds: e.speeds_mps, inclines: e.inclines_deg } });
  renderDecision(decisionBox, { item: e, name: e.envelope_label, path: `/api/envelopes/${e.id}`, canDecide, worseSlot,
    reload: () => envelopePage(document.getElementById("view"), e.id) });
  renderPush(pushBox, { item: e, kind: "envelope", name: e.envelope_label, canPush: canDecide, patient,
    what: `${e.envelope_label} (adapts over ${rangeText(e)}; nominal ${fmt(e.nominal.speed_mps, 2, "m/s")}, ${fmt(e.nominal.incline_deg, 1, "°")})`,
    path: `/api/envelopes/${e.id}` });
  app.envelopeInteractiveAt = performance.now();
  if (app.envelopeReturnedAt !== undefined) {   // the request's own time, and the page's after it returned
    app.envelopeViewMs = app.envelopeInteractiveAt - app.envelopeReturnedAt;
    app.envelopeFromRequestMs = app.envelopeInteractiveAt - app.envelopeRequestedAt;
    app.envelopeReturnedAt = undefined;
  }
  renderVersions(document.getElementById("versions"), e);
  renderPreview(previewBox, e);
}

function hex(n) {
  return n.toString(16).padStart(8, "0");
}

// One setting changed across the envelope or at one node, by a percentage or an offset; a new draft, or a refusal
// that says which node and which rule
function editCard(e, canEdit) {
  const card = h("section", { class: "card", id: "edit" }, h("h2", {}, "Edit into a new draft"));
  if (!canEdit || e.status === "rejected") {
    card.append(h("p", { class: "muted" }, canEdit ? "A rejected envelope is not edited; request a new one." : "Only a prosthetist can edit."));
    return card;
  }
  const fields = [...Object.keys(ROW_WORDS).flatMap((row) => Object.keys(QUANTITIES).map((q) => `${row}.${q}`)),
    ...Object.keys(e.nodes[0].thresholds).filter((k) => typeof e.nodes[0].thresholds[k] === "number").map((k) => `thresholds.${k}`)];
  const field = h("select", { name: "field", id: "edit-field", "aria-label": "Setting" },
    fields.map((f) => h("option", { value: f }, fieldWords(f))));
  const how = h("select", { name: "how", id: "edit-how", "aria-label": "Change by" },
    h("option", { value: "percent" }, "percent (resistance: + is firmer)"), h("option", { value: "offset" }, "offset, in the unit shown"),
    h("option", { value: "set_to" }, "set to, in the unit shown"));
  const unitNote = h("span", { class: "muted small", id: "edit-unit" });
  const showUnit = () => {
    const u = units(field.value, e.body_mass_kg);
    unitNote.textContent = how.value === "percent" ? "% of the value" : u.unit;
  };
  field.addEventListener("change", showUnit);
  how.addEventListener("change", showUnit);
  showUnit();
  const amount = h("input", { name: "amount", id: "edit-amount", type: "number", step: "any", required: true, size: 6, "aria-label": "Amount" });
  const where = h("select", { name: "where", id: "edit-where", "aria-label": "Where" },
    h("option", { value: "" }, "every node"),
    e.nodes.map((n, k) => h("option", { value: k }, `only at ${fmt(n.speed_mps, 2)} m/s, ${fmt(n.incline_deg, 1)}°`)));
  const comment = h("input", { name: "comment", id: "edit-comment", required: true, size: 40, maxlength: 2000, "aria-label": "Why" });
  const error = h("p", { class: "error", role: "alert", id: "edit-error" });
  const form = h("form", { id: "envelope-edit" },
    h("div", { class: "inline" }, h("label", {}, "Setting ", field), h("label", {}, "by ", how), h("label", {}, "amount ", amount, " ", unitNote),
      h("label", {}, "at ", where)),
    h("div", { class: "inline" }, h("label", {}, "Why (required, audited) ", comment), h("button", { type: "submit" }, "Make new draft")),
    h("p", { class: "muted small" }, "Every node's limits and the neighbour rule are checked again as the device runs them; a refused edit stores nothing. ",
      "A percentage also scales the differences between neighbours, so it can break the neighbour rule where an offset would not; ",
      "you can then hold those values within a step (the new draft's nodes say which, with what the edit gave)."),
    error);
  const send = async (hold) => {
    error.replaceChildren();
    // the server takes SI and the paper's signed k: an offset or a value typed in the shown unit is turned back
    const typed = Number(amount.value);
    const edit = { field: field.value, [how.value]: how.value === "percent" ? typed : toSI(field.value, typed, e.body_mass_kg) };
    if (where.value !== "") edit.node = [Math.floor(Number(where.value) / e.inclines_deg.length), Number(where.value) % e.inclines_deg.length];
    try {
      const made = await post(`/api/envelopes/${e.id}/edits`, { edits: [edit], comment: comment.value, hold_to_neighbour_rule: hold });
      location.hash = `#/envelopes/${made.id}`;
    } catch (err) {
      error.append(err.message);
      // only the neighbour rule broke: offer to hold those values within a step (each listed in the new draft)
      if (err.body?.neighbour_rule_only) {
        error.append(" ", h("button", { type: "button", id: "edit-hold", class: "secondary", onclick: () => send(true) },
          "Make the draft holding those values within a step"));
      }
    }
  };
  form.addEventListener("submit", (ev) => {
    ev.preventDefault();
    send(false);
  });
  card.append(form);
  return card;
}

async function renderVersions(box, e) {
  const versions = await get(`/api/patients/${e.patient_id}/envelopes`);
  const others = versions.filter((v) => v.id !== e.id);
  const other = h("select", { id: "diff-other", "aria-label": "Compare with version" },
    others.map((v) => h("option", { value: v.id, selected: v.id === e.parent_id }, `v${v.version} (${v.status}, ${rangeText(v)})`)));
  const out = h("div", { id: "diff" });
  const show = async () => {
    if (!other.value) return;
    const d = await get(`/api/envelopes/${other.value}/diff/${e.id}`);
    if (!d.same_grid) {
      out.replaceChildren(h("p", {}, "The grids differ: no node-by-node comparison."));
      return;
    }
    const held = d.changes.filter((c) => c.held_by_neighbour_rule).length;
    out.replaceChildren(...(d.changes.length ? [
      held ? h("p", { class: "banner warn", id: "diff-held" }, h("strong", {}, `${held} value(s) held by the neighbour rule: `),
        "marked below; they changed by other amounts than the edit asked, to stay within a step of their neighbouring tasks.") : null,
      table(["Node", "Setting", `v${d.from_version}`, `v${d.to_version} (this)`, "Change", "%", "Unit", ""],
        d.changes.map((c) => h("tr", { class: c.held_by_neighbour_rule ? "warn-row" : "" },
          h("td", {}, `${fmt(c.speed_mps, 2)} m/s, ${fmt(c.incline_deg, 1)}°`),
          h("td", { title: c.field }, c.setting), h("td", { class: "num" }, shownNumber(c.field, c.before, e.body_mass_kg)),
          h("td", { class: "num changed" }, shownNumber(c.field, c.after, e.body_mass_kg)),
          ...((ch) => [h("td", { class: "num" }, signed(ch.change, ch.digits)),
            h("td", { class: "num" }, ch.percent === null ? "—" : `${signed(ch.percent, 1)} %`),
            h("td", {}, ch.unit)])(shownChange(c.field, c.before, c.after, e.body_mass_kg)),
          h("td", {}, c.held_by_neighbour_rule ? chip(`held by the neighbour rule (asked for ${shownNumber(c.field, c.wanted, e.body_mass_kg)})`, "warn") : ""))),
        { id: "diff-table" })].filter(Boolean) : [h("p", {}, "No differences.")]));
  };
  other.addEventListener("change", show);
  box.replaceChildren(h("h2", {}, "Versions and differences"),
    others.length ? h("div", { class: "inline" }, h("label", {}, "Compare with ", other)) : h("p", { class: "muted" }, "Only one version so far."),
    out);
  await show();
}

async function renderPreview(box, e) {
  const pv = await walkedPreview(box, `/api/envelopes/${e.id}`, "envelope preview");
  if (!pv) return;
  const now = await get(`/api/envelopes/${e.id}`).catch(() => null);   // the header's bench chip follows
  if (now?.bench) document.getElementById("bench-chip")?.replaceChildren(chip(now.bench.words, BENCH_CHIP[now.bench.status]));
  const t = pv.controllers.envelope, f = pv.controllers.fsmic;
  const ci = (row, key) => (row[key.replace("_rmse_", "_rmse_ci95_")] ? ` [${fmt(row[key.replace("_rmse_", "_rmse_ci95_")][0], 1)}, ${fmt(row[key.replace("_rmse_", "_rmse_ci95_")][1], 1)}]` : "");
  const segRows = t.by_segment.map((s, k) => {
    const fs = f.by_segment[k] || {};
    return h("tr", {}, h("td", {}, `${k + 1}`), h("td", {}, `${fmt(s.speed_mps, 2, "m/s")}, ${fmt(s.incline_deg, 0, "°")}`),
      h("td", { class: "num" }, `${s.strides} / ${fs.strides ?? "—"}`),
      h("td", { class: "num" }, `${fmt(s.knee_angle_rmse_deg, 1)}${ci(s, "knee_angle_rmse_deg")}`),
      h("td", { class: "num" }, `${fmt(fs.knee_angle_rmse_deg, 1)}${ci(fs, "knee_angle_rmse_deg")}`),
      h("td", { class: "num" }, `${fmt(s.ankle_angle_rmse_deg, 1)}${ci(s, "ankle_angle_rmse_deg")}`),
      h("td", { class: "num" }, `${fmt(fs.ankle_angle_rmse_deg, 1)}${ci(fs, "ankle_angle_rmse_deg")}`));
  });
  const diffRow = (label, key, unit, digits) => {
    const d = pv.envelope_minus_fsmic[key];
    return h("tr", {}, h("td", {}, label), h("td", { class: d.verdict === "not resolved" ? "num muted" : "num" },
      d.rmse_difference === null ? "—" : `${fmt(d.rmse_difference, digits)} [${fmt(d.ci95[0], digits)}, ${fmt(d.ci95[1], digits)}] ${unit}: ${d.verdict}`));
  };
  const est = t.estimation || {};
  box.replaceChildren(...[h("h2", {}, "Simulated preview: the varying-task course"),
    h("p", { class: "muted small" }, `The bench walked the “${pv.course.name}” course (`,
      pv.course.segments.map((s) => `${fmt(s.speed_mps, 2)} m/s ${s.incline_deg >= 0 ? "+" : ""}${fmt(s.incline_deg, 0)}° for ${fmt(s.duration_s, 0)} s`).join(" → "),
      `) twice at ${fmt(pv.mass_kg, 0, "kg")}: with this envelope (the leg estimating its own task and changing its rows at heel strikes) and with the FSMIC. `,
      "Each stride is scored against the reference at its true task. ", `Simulated ${when(pv.created_at)}.`),
    benchLegNote(pv.leg, e.leg),
    safetyFigures(courseAndNodeFlags(pv), t, f, "This envelope"),
    h("h3", {}, "Errors per segment (RMSE, deg; [95 % interval])"),
    table(["Segment", "Task", "Strides (envelope / FSMIC)", "Knee: envelope", "Knee: FSMIC", "Ankle: envelope", "Ankle: FSMIC"], segRows,
      { id: "preview-segments" }),
    h("h3", {}, "Whole course: envelope − FSMIC, mean per-stride RMSE"),
    table(["Channel", "Difference [95 % interval]"], [diffRow("knee angle", "knee_angle_deg", "deg", 2),
      diffRow("ankle angle", "ankle_angle_deg", "deg", 2), diffRow("knee moment", "knee_moment_Nm_per_kg", "N·m/kg", 3),
      diffRow("ankle moment", "ankle_moment_Nm_per_kg", "N·m/kg", 3)], { id: "preview-differences" }),
    h("p", { class: "small", id: "preview-estimation" }, "The leg's own estimate of its task (not counting 3 strides after each change): speed within ±0.1 m/s on ",
      fmt((est.speed_within_0_1_mps_fraction ?? NaN) * 100, 0), " % and incline within ±1.5° on ",
      fmt((est.incline_within_1_5_deg_fraction ?? NaN) * 100, 0), ` % of ${est.strides_counted ?? 0} strides. Rows per stride: `,
      Object.entries(t.strides_by_mode || {}).map(([m, n]) => `${m} ${n}`).join(", "), "."),
    (pv.safety || []).length ? h("p", { class: "notice-inline warn small" }, "Lower tracking errors do not outweigh the safety flags above.") : null,
    nodeWalks(pv, e)]
    .filter(Boolean));
}

// the course walk's flags, and one for the nodes walked alone (their own section below names each): the banner's
// findings, while the course's figures table marks only the course's own
function courseAndNodeFlags(pv) {
  const safety = pv.safety || [];
  const course = safety.filter((f) => f.node_speed_mps === null || f.node_speed_mps === undefined);
  const words = flagWords(safety).slice(course.length);
  return [...course, ...words.map((message) => ({ figure: "nodes_beyond_bounds", severity: "bad", message }))];
}

// a node flag's message begins with its walk's start (backend/bench/node_previews.py): the table's column says it
const START_PREFIX = { standing: "from standing: ", level: "reached from level walking: " };

// Every node walked alone at its own task (from standing, and reached from level walking): a map of how many figures
// each node has beyond a bound (0: clean), and one row per node that has any, naming the figures
function nodeWalks(pv, e) {
  const box = h("div", { id: "preview-nodes" }, h("h3", {}, "Each node alone at its own task"));
  if (!pv.nodes) {
    box.append(h("p", { class: "notice-inline bad" }, "Its nodes were not walked alone: this preview predates node walks."));
    return box;
  }
  const said = pv.node_walks || {};
  const flagged = pv.nodes.filter((n) => n.flags.length);
  box.append(h("p", { class: flagged.length ? "notice-inline bad" : "notice-inline ok", id: "preview-nodes-summary" },
    flagged.length ? `${flagged.length} of ${pv.nodes.length} nodes have figures beyond their bounds when walked alone at their own task; each gates this envelope like a fall on the course.`
      : `All ${pv.nodes.length} nodes walked alone at their own task stay within every bound.`),
  h("p", { class: "muted small" }, `Each node's own rows on the leg (${said.controller || "its table"}), walked twice at its task: `,
    `${said.starts?.standing || "from standing"}; and ${said.starts?.level || "reached from level walking"}; `,
    `${fmt(said.seconds_at_task, 0, "s")} scored at the task each, at ${fmt(pv.mass_kg, 0, "kg")}. Bounds: ${said.bounds || "as above"}.`));
  const fig = h("figure", { class: "map node-walk-map" });
  box.append(fig);
  envelopeMap(fig, { title: "figures beyond a bound (0 = clean)", id: "map-node-walks", speeds: e.speeds_mps,
    inclines: e.inclines_deg, unit: "figures", digits: 0, darker: "high", keyWords: "darker = more beyond a bound",
    values: nodeGrid({ ...e, nodes: pv.nodes }, (n) => n.flags.length),
    onPick: (i, j) => { location.hash = `#/envelopes/${e.id}/nodes/${i}/${j}`; } });
  if (flagged.length) {
    const cell = (n, start) => {
      if (!n.walks[start]) return h("td", { class: "muted" }, "a level node: its walk from standing is its level walking");
      const mine = n.flags.filter((f) => f.start === start);
      return h("td", { class: mine.length ? "bad" : "ok" }, mine.length
        ? h("ul", { class: "tight" }, mine.map((f) => h("li", {},
          f.message.startsWith(START_PREFIX[start]) ? f.message.slice(START_PREFIX[start].length) : f.message)))
        : "within every bound");
    };
    box.append(table(["Node (task)", "From standing", "Reached from level walking"], flagged.map((n) => h("tr", {},
      h("td", {}, `${fmt(n.speed_mps, 2, "m/s")}, ${n.incline_deg > 0 ? "+" : ""}${fmt(n.incline_deg, 1)}°`),
      cell(n, "standing"), cell(n, "level"))), { id: "preview-node-flags" }));
  }
  return box;
}
