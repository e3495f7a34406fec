// A proposal's parameter table: read in clinical words (default) or engineering codes, edited into a new draft
// version with every value checked against the safety limits as it is typed (the server checks again on save).
import { post } from "../api.js";
import { EQUATION, EQUATION_WORDS, shownRange, tableView, units } from "../quantities.js";
import { chip, fieldWords, FIT_METHOD_WORDS, fmt, h, inWords, notice, ROW_WORDS, SUBPHASE_COLOUR, table, WEAK_FIT_R2 } from "../ui.js";

export { tableView };

const FIT_METHOD_HELP = {
  least_squares: "least-squares line τ = kθ + c through the predicted loop",
  extension_window: "least-squares line over the knee's stance extension only (stance-flexion peak to its late-stance minimum); pre-swing left out",
  range_guard: "the fitted θe lay outside the joint range: θe clamped to the range and k re-fitted",
  passivity_guard: "the fitted line would inject energy with θe inside the swept angles: k set to the restoring floor, θe re-fitted",
  swing_target: "not a fit: θe is the predicted swing target, k the model's swing stiffness (restoring)",
  manual: "edited by hand",
  literature: "published table",
  neighbour_guard: "an envelope node: the fitted value differed from a neighbouring node's by more than the envelope's step per cell, so it was moved the least into that step",
  support_floor: "the person does positive work here (the knee extends under load, which a spring cannot); the leg holds the knee firm instead: k at the stance support floor, θe re-fitted",
  refined: "moved by a refinement from the patient's own strides: the version's evidence says from what and why",
};

// The knee's stance-flexion ceiling (N·m/rad, negative): the stance support floor for the body mass
export function supportFloor(L, mass) {
  return -L.knee_stance_support_Nm_per_rad_per_kg * mass;
}

// The SI range of a field (the server's SafetyLimits): stance stiffness has its own (resistive only) range, and
// the knee's stance flexion must be at least as firm as the stance support floor for the body mass
function limitOf(field, L, mass) {
  const [a, b, c] = field.split(".");
  if (a === "thresholds") {
    return { sf_to_se_ankle_moment_Nm: L.ankle_moment_Nm, se_to_wf_load_N: L.load_N, we_to_sf_load_N: L.load_N,
      wf_to_we_knee_angle_deg: L.knee_theta_e_deg, min_state_time_s: L.state_time_s, max_state_time_s: L.state_time_s,
      sf_to_se_knee_extension_deg_per_s: L.knee_extension_deg_per_s }[b] ?? L[b];   // the stumble ones by their name
  }
  if (c === "k_Nm_per_rad" && `${a}.${b}` === "knee.stance_flexion" && mass) {
    return { low: L.stance_k_Nm_per_rad.low, high: Math.min(L.stance_k_Nm_per_rad.high, supportFloor(L, mass)) };
  }
  if (c === "k_Nm_per_rad") return b.startsWith("stance") ? L.stance_k_Nm_per_rad : L.k_Nm_per_rad;
  if (c === "theta_e_deg") return a === "knee" ? L.knee_theta_e_deg : L.ankle_theta_e_deg;
  return L.b_Nm_s_per_rad;
}

function label(field) {
  return tableView.view === "clinical" ? fieldWords(field) : field;
}

// What is wrong with the values as typed (SI), in the words of the current view; mirrors the server's checks
export function liveViolations(values, L, mass) {
  const out = [];
  for (const [field, v] of Object.entries(values)) {
    const u = units(field, mass), lim = limitOf(field, L, mass);
    const shown = `${fmt(v * u.scale + 0, u.digits)} ${u.unit}`;
    if (!Number.isFinite(v)) out.push({ field, message: `${label(field)}: not a number` });
    else if (field === "knee.stance_flexion.k_Nm_per_rad" && v > lim.high && v <= L.stance_k_Nm_per_rad.high) {
      out.push({ field, message: `${label(field)} = ${shown} is softer than the stance support floor: at least `
        + `${fmt(lim.high * u.scale, u.digits)} ${u.unit} (${fmt(L.knee_stance_support_Nm_per_rad_per_kg, 1)} `
        + `N·m/rad per kg × ${fmt(mass, 1)} kg), or the knee could buckle under the patient's weight` });
    } else if (field.endsWith("k_Nm_per_rad") && field.includes(".stance_") && v > lim.high) {
      const joint = field.split(".")[0];
      out.push({ field, message: `${label(field)} = ${shown} pushes the joint instead of resisting it (${joint === "knee"
        ? "the knee gives way into flexion under load" : "the ankle is pushed off its equilibrium under load"}): a stance `
        + `setting must resist, at least ${fmt(lim.high * u.scale + 0, u.digits)} ${u.unit}` });
    } else if (v < lim.low || v > lim.high) {
      out.push({ field, message: `${label(field)} = ${shown} is outside ${shownRange(lim, u)} ${u.unit}` });
    }
  }
  const t = (k) => values[`thresholds.${k}`];
  if (t("min_state_time_s") >= t("max_state_time_s")) {
    out.push({ field: "thresholds.min_state_time_s", message: `${label("thresholds.min_state_time_s")} must be below the maximum` });
  }
  if (t("se_to_wf_load_N") >= t("we_to_sf_load_N")) {
    out.push({ field: "thresholds.se_to_wf_load_N", message: `${label("thresholds.se_to_wf_load_N")} must be below the heel-strike load, or the machine chatters` });
  }
  return out;
}

const THRESHOLD_KEYS = ["sf_to_se_ankle_moment_Nm", "se_to_wf_load_N", "wf_to_we_knee_angle_deg", "we_to_sf_load_N",
  "min_state_time_s", "max_state_time_s", "sf_to_se_knee_extension_deg_per_s"];
// the stumble support's trigger (controller_core/fsm.py, "Stumbles"); the support itself is the knee's stance-flexion row;
// and the early landing on the forefoot's ("An early landing on the forefoot"), whose support is the ankle's row
const STUMBLE_KEYS = ["stumble_knee_margin_deg", "stumble_knee_rate_deg_per_s", "fold_knee_rate_deg_per_s",
  "fold_window_of_stance_pct", "early_landing_swing_pct", "forefoot_landing_pct"];

export function parameterTable(p, canEdit) {
  const L = p.limits, mass = p.task.body_mass_kg;
  const clinical = tableView.view === "clinical";
  const violated = new Set(p.safety.violations.map((v) => v.field));
  const radio = (name, value, text, current, set) => h("label", {}, h("input", { type: "radio", name, value,
    checked: current === value, onchange: () => { set(value); rerender(); } }), text);
  const toggles = h("div", { class: "inline" },
    h("fieldset", { class: "toggle", id: "table-view" }, h("legend", {}, "View"),
      radio("table-view", "clinical", "clinical", tableView.view, (v) => { tableView.view = v; localStorage.setItem("quasitune.view", v); }),
      radio("table-view", "engineering", "engineering", tableView.view, (v) => { tableView.view = v; localStorage.setItem("quasitune.view", v); })),
    h("fieldset", { class: "toggle", id: "k-unit" }, h("legend", {}, "Stiffness and damping per"),
      ...["rad", "deg"].map((u) => radio("k-unit", u, u === "rad" ? "radian" : "degree", tableView.kUnit,
        (v) => { tableView.kUnit = v; localStorage.setItem("quasitune.kUnit", v); }))));
  const cell = (field, si, held = false) => {
    const u = units(field, mass);
    const shown = (si * u.scale + 0).toFixed(u.digits);
    const lim = limitOf(field, L, mass);
    const out = violated.has(field) || si < lim.low || si > lim.high;
    return h("td", { class: `num${out ? " out" : ""}${held ? " held" : ""}`, dataset: { cell: field },
      title: held ? "held at a limit, the stance support floor or a neighbour's step, not the plain fit (see where the value comes from)" : null }, canEdit
      ? h("input", { type: "number", step: "any", value: shown, "aria-label": `${label(field)} (${u.unit})`,
        dataset: { field, original: shown, si, scale: u.scale } })
      : `${shown}`);
  };
  // the rows scaled for the leg's swing inertia (the API names them) say so and by how much
  const s = p.swing_inertia, ratio = (r) => !s || !s.scaled_rows.includes(`${r.joint}.${r.subphase}`) ? 1
    : r.joint === "ankle" ? s.ankle_ratio : s.knee_ratio;
  const fit = (r) => {
    let words = clinical ? FIT_METHOD_WORDS[r.fit_method] ?? r.fit_method : r.fit_method;
    if (["swing_target", "neighbour_guard"].includes(r.fit_method) && Math.abs(ratio(r) - 1) >= 0.005) {
      words += `, k and b × ${ratio(r).toFixed(2)} for this leg`;   // not for a hand edit: its values are the prosthetist's
    }
    return r.fit_method === "swing_target" ? chip(words) : r.guarded ? chip(words, "warn") : words;
  };
  // R² says how well a fitted line explains the loop; a swing target or a hand edit is not a fit
  const r2 = (r) => r.r2 === null || ["swing_target", "manual", "literature", "refined"].includes(r.fit_method)
    ? h("span", { title: r.r2 === null ? "" : `not a fit (a line through the swing moment would explain R² = ${fmt(r.r2, 2)})` }, "—")
    : r.weak_fit ? h("span", { class: "weak-fit", title: `R² below ${WEAK_FIT_R2}: the line explains less than half of the `
      + "moment in this phase; read k and θe as a rough summary" }, `${fmt(r.r2, 2)} `, chip("weak fit", "warn"))
      : fmt(r.r2, 2);
  const rows = p.table.map((r) => {
    const key = `${r.joint}.${r.subphase}`;
    const name = clinical ? [h("td", {}, r.joint === "knee" ? "Knee" : "Ankle"),
      h("td", {}, h("span", { class: "dot", style: `--c:${SUBPHASE_COLOUR[r.subphase]}` }), ROW_WORDS[key].replace(/^(knee|ankle) /, ""))]
      : [h("td", {}, r.joint), h("td", {}, h("span", { class: "dot", style: `--c:${SUBPHASE_COLOUR[r.subphase]}` }), r.subphase)];
    return h("tr", { class: [r.held ? "held-row" : "", r.weak_fit ? "weak-row" : ""].join(" ").trim() || null },
      ...name, cell(`${key}.k_Nm_per_rad`, r.k_Nm_per_rad, r.held), cell(`${key}.theta_e_deg`, r.theta_e_deg, r.held),
      cell(`${key}.b_Nm_s_per_rad`, r.b_Nm_s_per_rad), h("td", { class: "num" }, r2(r)),
      h("td", { title: FIT_METHOD_HELP[r.fit_method] ?? "" }, fit(r)));
  });
  const th = p.thresholds;
  const thresholdRow = (k) => {
    const field = `thresholds.${k}`, u = units(field, mass), lim = limitOf(field, L, mass);
    return h("tr", {}, h("td", {}, label(field)), cell(field, th[k]), h("td", {}, u.unit),
      h("td", { class: "muted" }, shownRange(lim, u)));
  };
  const thRows = THRESHOLD_KEYS.map(thresholdRow), stumbleRows = STUMBLE_KEYS.map(thresholdRow);
  const ku = units("k_Nm_per_rad", mass), bu = units("b_Nm_s_per_rad", mass), au = units("theta_e_deg", mass);
  const heads = clinical ? ["Joint", "Phase of gait", `Resistance K (${ku.unit}; larger = firmer)`, "Equilibrium angle θe (deg)",
    `Damping b (${bu.unit}; a default per kg, not fitted)`, "Fit quality R²", "Where the value comes from"]
    : ["joint", "subphase", `K = −k (${ku.unit})`, "theta_e (deg)", `b (${bu.unit}; default, not fitted)`, "R²", "fit_method"];
  const stanceLim = units("knee.stance_flexion.k_Nm_per_rad", mass);
  const box = h("div", {},
    h("h2", {}, "Parameter table per phase of gait"), toggles,
    h("p", { id: "equation" }, h("strong", {}, EQUATION), ` — ${EQUATION_WORDS}`),
    table(heads, rows, { id: "param-table" }),
    h("p", { class: "muted small" }, `Limits: resistance ${shownRange(L.k_Nm_per_rad, ku)} ${ku.unit}; in stance at least `,
      `${fmt(L.stance_k_Nm_per_rad.high * stanceLim.scale + 0, stanceLim.digits)} ${ku.unit} (a stance setting must resist, never push); `,
      h("span", { id: "support-floor" }, `the knee in stance flexion at least ${fmt(supportFloor(L, mass) * ku.scale, ku.digits)} `
        + `${ku.unit}: the stance support floor, ${fmt(L.knee_stance_support_Nm_per_rad_per_kg, 1)} N·m/rad per kg × `
        + `${fmt(mass, 1)} kg (the Open Source Leg's published early-stance knee stiffness), softer than which the knee `
        + "could buckle under load; "),
      `θe knee ${shownRange(L.knee_theta_e_deg, { ...au, digits: 0 })}°, ankle ${shownRange(L.ankle_theta_e_deg, { ...au, digits: 0 })}°; `,
      `damping ${shownRange(L.b_Nm_s_per_rad, bu)} ${bu.unit}. Values outside the limits are marked red as you type. `,
      "R² (fit quality): how well the row's straight line explains the predicted torque-angle loop in that phase; ",
      `below ${WEAK_FIT_R2} it is marked a weak fit. Values held at a limit, the stance support floor or a neighbour's step are `,
      "marked ◥ (their row says why). Damping is never fitted: a default per kg of body mass, editable. ",
      "Swing rows are not fits (R² —): in swing the foot is unloaded, so θe is the predicted swing target (knee: ",
      "swing-flexion peak, then heel-strike angle; ankle: swing dorsiflexion plus a toe-clearance margin) and K a set ",
      "swing resistance. The API keeps the paper's signed k (τ = k(θ − θe), negative resists); this page shows K = −k."),
    h("h3", {}, "When the leg changes phase (state-machine thresholds)"),
    table(["Transition", "Value", "Unit", "Limits"], thRows, { id: "thresholds" }),
    h("p", { class: "muted small" }, "Phases: stance flexion (loading response, knee bends under the weight) → stance ",
      "extension (mid and terminal stance, ankle push-off) → swing flexion (toe-off, knee bends to clear the foot) → ",
      "swing extension (knee straightens for heel strike). SF→SE: from stance flexion to stance extension; WF→WE: from ",
      "swing flexion to swing extension."),
    h("h3", {}, "When the leg catches a stumble (stumble support)"),
    table(["Trigger", "Value", "Unit", "Limits"], stumbleRows, { id: "stumble-support" }),
    h("p", { class: "muted small" }, "A toe caught in swing or a foot landing early on a bent knee: the knee, still ",
      "flexed beyond the margin above its straightening angle, stops extending because the floor holds the foot. A ",
      "knee folding under the body early in stance: it flexes faster than the fold speed. Either way the leg goes at ",
      "once to its stance-flexion setting (the knee's loading-response row above: that is the support), holds it until ",
      "the knee is back within the margin of that row's angle or the foot is lifted, and returns to the usual rows at ",
      "the next clean heel strike. The support cannot be switched off; the limits keep it from holding a freely ",
      "swinging knee or pre-swing's flexion stiff. A foot put down early on its toe (on an obstacle's top, a step ",
      "up): the swing ended before its early-landing share of the last ordinary swing and the weight landed beyond ",
      "its share of the forefoot; the ankle then gives no toe-down push while the weight stays on the toe, so the heel ",
      "comes down, and its stance row is the row again once the foot is flat."));
  if (canEdit) box.append(editForm(p));
  function rerender() {
    document.getElementById("table-card").replaceChildren(parameterTable(p, canEdit));
  }
  return box;
}

// a cell whose typed number is not the one shown (retyping the shown "15" changes nothing)
function changed(input) {
  return input.value.trim() === "" || Number(input.value) !== Number(input.dataset.original);
}

// the values as typed, in SI, for every editable cell (an unchanged cell keeps its stored value exactly)
function typedValues() {
  const values = {};
  for (const input of document.querySelectorAll("#table-card input[data-field]")) {
    values[input.dataset.field] = !changed(input) ? Number(input.dataset.si)
      : input.value.trim() === "" ? NaN : Number(input.value) / Number(input.dataset.scale);
  }
  return values;
}

function editForm(p) {
  const error = h("p", { class: "error", role: "alert", id: "edit-error" });
  const live = h("ul", { class: "error", id: "edit-live", "aria-live": "polite" });
  const comment = h("input", { name: "comment", required: true, maxlength: 2000, size: 40 });
  const save = h("button", { type: "submit" }, "Save edits as a new draft version");
  const discard = h("button", { type: "button", class: "secondary", id: "discard-edits" }, "Discard edits");
  const form = h("form", { id: "edit-form" }, h("div", { class: "inline" }, h("label", {}, "Why (audited)", comment), save,
    discard), live, error);
  // checked as the prosthetist types: the touched cell is painted, the reasons listed, Save held back
  const check = () => {
    const found = liveViolations(typedValues(), p.limits, p.task.body_mass_kg);
    const bad = new Set(found.map((v) => v.field));
    for (const td of document.querySelectorAll("#table-card td[data-cell]")) {
      const input = td.querySelector("input");
      td.classList.toggle("out", bad.has(td.dataset.cell));
      td.classList.toggle("changed", Boolean(input) && changed(input));
      td.title = found.filter((v) => v.field === td.dataset.cell).map((v) => v.message).join("; ");
    }
    live.replaceChildren(...found.map((v) => h("li", { dataset: { field: v.field } }, v.message)));
    save.disabled = found.length > 0;
    save.title = found.length ? "fix the values marked red first" : "";
    // typed but not saved: the page's Approve and Push must not act on the stored values as if they were these
    const unsaved = [...document.querySelectorAll("#table-card input[data-field]")].some(changed);
    window.dispatchEvent(new CustomEvent("quasitune:unsaved-edits", { detail: { unsaved } }));
    return found;
  };
  discard.addEventListener("click", () => {
    for (const input of document.querySelectorAll("#table-card input[data-field]")) input.value = input.dataset.original;
    error.textContent = "";
    check();
  });
  queueMicrotask(() => document.getElementById("table-card")?.addEventListener("input", check));
  form.addEventListener("submit", async (ev) => {
    ev.preventDefault();
    error.textContent = "";
    if (check().length) return;
    const rows = {};
    const thresholds = {};
    const values = typedValues();
    for (const input of document.querySelectorAll("#table-card input[data-field]")) {
      if (!changed(input)) continue;
      const [a, b, c] = input.dataset.field.split(".");
      if (a === "thresholds") thresholds[b] = values[input.dataset.field];
      else {
        rows[`${a}.${b}`] ??= { joint: a, subphase: b };
        rows[`${a}.${b}`][c] = values[input.dataset.field];
      }
    }
    if (!Object.keys(rows).length && !Object.keys(thresholds).length) {
      error.textContent = "nothing changed: edit a cell first";
      return;
    }
    const body = { rows: Object.values(rows), comment: comment.value };
    if (Object.keys(thresholds).length) body.thresholds = thresholds;
    try {
      const created = await post(`/api/proposals/${p.id}/edits`, body);
      notice(`Saved as draft v${created.version}`, "ok");
      location.hash = `#/proposals/${created.id}`;
    } catch (err) {
      const violations = err.body?.violations || [];
      error.textContent = violations.length ? violations.map((v) => inWords(v.message, v.field)).join("; ") : err.message;
      for (const v of violations) {
        document.querySelector(`#table-card td[data-cell="${v.field}"]`)?.classList.add("out");
      }
    }
  });
  return form;
}
