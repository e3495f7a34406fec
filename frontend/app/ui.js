// Small DOM helpers and the number formats used on every page (unit always shown).
import CLINICAL_WORDS from "/clinical_words.json" with { type: "json" };

export function h(tag, attrs = {}, ...children) {
  const el = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs || {})) {
    if (v === undefined || v === null || v === false) continue;
    if (k === "class") el.className = v;
    else if (k.startsWith("on")) el.addEventListener(k.slice(2), v);
    else if (k === "dataset") Object.assign(el.dataset, v);
    else if (k === "style") el.style.cssText = v;   // through the CSSOM: the page's CSP allows no inline style attribute
    else el.setAttribute(k, v === true ? "" : v);
  }
  for (const c of children.flat()) {
    if (c === undefined || c === null || c === false) continue;
    el.append(c instanceof Node ? c : document.createTextNode(String(c)));
  }
  return el;
}

const G_MPS2 = 9.80665;

// Body weight (N) of a patient of ``massKg``; null when the mass is unknown
export function bodyWeightN(massKg) {
  return massKg ? massKg * G_MPS2 : null;
}

// y at x, linearly between the points (xs increasing), held at the ends
export function interp(x, xs, ys) {
  if (x <= xs[0]) return ys[0];
  if (x >= xs[xs.length - 1]) return ys[ys.length - 1];
  let lo = 0, hi = xs.length - 1;
  while (hi - lo > 1) { const mid = (lo + hi) >> 1; if (xs[mid] <= x) lo = mid; else hi = mid; }
  return ys[lo] + ((x - xs[lo]) / (xs[hi] - xs[lo])) * (ys[hi] - ys[lo]);
}

export function fmt(value, digits = 1, unit = "") {
  if (value === null || value === undefined || Number.isNaN(value)) return "—";
  const s = Number(value).toFixed(digits);
  return unit ? `${s} ${unit}` : s;
}

export function pm(value, sd, digits = 1, unit = "") {
  return `${fmt(value, digits)} ± ${fmt(sd, digits)}${unit ? " " + unit : ""}`;
}

export function notice(message, kind = "error") {
  const el = document.getElementById("notice");
  el.textContent = message;
  el.className = `notice ${kind}`;
  el.hidden = !message;
  if (message && kind !== "error") setTimeout(() => { if (el.textContent === message) el.hidden = true; }, 4000);
}

export function when(iso) {
  return iso ? iso.replace("T", " ").replace(/\.\d+Z$/, " UTC").replace(/Z$/, " UTC") : "—";
}

export const SUBPHASES = ["stance_flexion", "stance_extension", "swing_flexion", "swing_extension"];
export const SUBPHASE_LABEL = {
  stance_flexion: "stance flexion", stance_extension: "stance extension",
  swing_flexion: "swing flexion", swing_extension: "swing extension",
};
// Settings named as clinicians name them (the engineering view keeps the codes): the server's one copy of the words
// (backend/clinical_words.json), which its refusals use too
export const ROW_WORDS = CLINICAL_WORDS.rows;
const PARAMETER_WORDS = CLINICAL_WORDS.parameters;
// the server's threshold (controller_core.table.WEAK_FIT_R2): a line fit below it is marked a weak fit
export const WEAK_FIT_R2 = 0.5;
export const FIT_METHOD_WORDS = {
  least_squares: "fitted to the predicted loop", extension_window: "fitted to stance extension",
  range_guard: "fitted, angle held in range", passivity_guard: "fitted, held resistive",
  swing_target: "set from the swing target", manual: "edited by hand", literature: "published value",
  neighbour_guard: "held within a step of its envelope neighbours",
  support_floor: "held at the stance support floor",
  refined: "refined from the patient's own strides",
};
const THRESHOLD_WORDS = CLINICAL_WORDS.thresholds;

// "knee.stance_flexion.k_Nm_per_rad" -> the row's words and the parameter's ("…: resistance K")
export function fieldWords(field) {
  const [a, b, c] = field.split(".");
  if (a === "thresholds") return THRESHOLD_WORDS[b] || field;
  const row = ROW_WORDS[`${a}.${b}`];
  return row && PARAMETER_WORDS[c] ? `${row}: ${PARAMETER_WORDS[c]}` : field;
}

// A server message about a field, with the field named in words (the code stays in brackets for the engineers)
export function inWords(message, field) {
  const words = fieldWords(field);
  return words === field ? message : message.replace(field, `${words} [${field}]`);
}

// colour-blind safe (Okabe–Ito) per sub-phase
export const SUBPHASE_COLOUR = {
  stance_flexion: "#009E73", stance_extension: "#D55E00", swing_flexion: "#0072B2", swing_extension: "#CC79A7",
};
// What the device's mode means, in words (the API's codes stay in the engineering view and the JSON)
const MODE_WORDS = { active: "running its table", safe: "SAFE MODE (passive: holds the loaded knee)", no_table: "no table (passive: holds the loaded knee)",
  calibrating: "CALIBRATING (no torque at all: the leg is in its stand)" };
export function modeWords(mode) {
  return MODE_WORDS[mode] || (mode ? `mode ${mode}` : "mode not reported");
}

export const FSM_STATES = ["stance flexion", "stance extension", "swing flexion", "swing extension"];

export function chip(text, kind = "") {
  return h("span", { class: `chip ${kind}` }, text);
}

export function table(headers, rows, attrs = {}) {
  return h("table", attrs,
    h("thead", {}, h("tr", {}, headers.map((x) => h("th", { scope: "col" }, x)))),
    h("tbody", {}, rows));
}

// What a reference curve really is (summaries carry reference_kind; older ones only a source sentence)
export const REFERENCE_KIND = {
  measured: "measured able-bodied level walking",
  measured_ramp_trend: "measured level walking + one participant's measured ramp change, scaled to the incline",
  model_prediction: "the model's own prediction (no curves were measured this steep), not data",
};

export function referenceLabel(summary) {
  return REFERENCE_KIND[summary.reference_kind] || "reference";
}

// A modal question with the facts it is about; resolves true only when confirmed. With `requires`, the confirm
// button stays disabled until that checkbox (a clinical precondition) is ticked.
// reason: { label, min } asks for a written reason too (e.g. an override); the promise then resolves to the text
// (or false), else to true or false.
export function confirmDialog({ id, title, facts = [], requires = null, confirm = "Confirm", danger = false, reason = null }) {
  return new Promise((resolve) => {
    const tick = requires ? h("input", { type: "checkbox", id: `${id}-ready` }) : null;
    const text = reason ? h("textarea", { id: `${id}-reason`, rows: 2, cols: 50, maxlength: 2000, "aria-label": reason.label }) : null;
    const yes = h("button", { id: `${id}-confirm`, class: danger ? "danger" : "", disabled: Boolean(requires || reason) }, confirm);
    const no = h("button", { id: `${id}-cancel`, class: "secondary", type: "button" }, "Cancel");
    const dlg = h("dialog", { id, "aria-labelledby": `${id}-title` },
      h("h2", { id: `${id}-title` }, title),
      h("dl", { class: "facts" }, facts.flatMap(([k, v]) => [h("dt", {}, k), h("dd", {}, v)])),
      text ? h("p", {}, h("label", {}, `${reason.label} (at least ${reason.min} characters) `, text)) : null,
      tick ? h("p", {}, h("label", {}, tick, " ", requires)) : null,
      h("div", { class: "inline" }, yes, no));
    const ready = () => { yes.disabled = (tick && !tick.checked) || (text && text.value.trim().length < reason.min); };
    tick?.addEventListener("change", ready);
    text?.addEventListener("input", ready);
    const close = (answer) => { dlg.close(); dlg.remove(); resolve(answer); };
    yes.addEventListener("click", () => close(text ? text.value.trim() : true));
    no.addEventListener("click", () => close(false));
    dlg.addEventListener("cancel", (ev) => { ev.preventDefault(); close(false); });
    document.body.append(dlg);
    dlg.showModal();
    (tick || no).focus();
  });
}

// What a leg runs, by its one name everywhere ("P-001 · table v3", "P-001 · envelope v2"), with its task when asked
export function tableName(t, withTask = false) {
  if (!t) return "no table from this server";
  const name = t.label ?? t.table_label;
  if (!withTask) return name;
  const task = `${fmt(t.task.speed_mps, 2, "m/s")}, incline ${fmt(t.task.incline_deg, 1, "°")}`;
  return t.kind === "envelope" ? `${name} (adapts to the task; nominal ${task})` : `${name} (${task})`;
}

// A version's extrapolation, said the same way everywhere: beyond what the model knows (with the prosthetist's written
// reason), or only a little outside its data
export function extrapolationChip(v, outsideWords = "extrapolation") {
  if (v.extrapolation_reason) {
    return h("span", { class: "chip bad", title: `requested beyond what the model knows: ${v.extrapolation_reason}` },
      "extrapolated beyond the data");
  }
  return v.extrapolation ? chip(outsideWords, "warn") : "";
}

// One moment unit per page, the prosthetist's choice, kept across pages and visits: the patient's N·m (what the leg
// produces) or N·m/kg (how walking data compare across people). Values arrive in N·m/kg.
export const momentView = { unit: localStorage.getItem("quasitune.momentUnit") === "Nm_per_kg" ? "Nm_per_kg" : "Nm" };
export function momentUnit() {
  return momentView.unit === "Nm" ? "N·m" : "N·m/kg";
}
export function momentScale(mass) {
  return momentView.unit === "Nm" ? mass : 1;
}
export function momentToggle(mass, onChange) {
  const radio = (value, text) => h("label", {}, h("input", { type: "radio", name: "moment-unit", value,
    checked: momentView.unit === value, onchange: () => {
      momentView.unit = value;
      localStorage.setItem("quasitune.momentUnit", value);
      onChange();
    } }), text);
  return h("fieldset", { class: "toggle", id: "moment-unit" }, h("legend", {}, "Moments in"),
    radio("Nm", `N·m (this patient, ${fmt(mass, 1)} kg)`), radio("Nm_per_kg", "N·m/kg (per kg of body mass)"));
}

// an envelope's grid in words: "0.6–1.6 m/s × -10…10°"
// the range an envelope covers, as requested: "0.85–1.6 m/s × −6…+6°" (no rounding of 0.85 to "0.8")
export function rangeText(e) {
  const n = (x, digits) => String(Number(x.toFixed(digits)));
  const deg = (x) => (x > 0 ? `+${n(x, 1)}` : n(x, 1).replace("-", "−"));
  return `${n(e.speeds_mps[0], 2)}–${n(e.speeds_mps.at(-1), 2)} m/s × ${deg(e.inclines_deg[0])}…${deg(e.inclines_deg.at(-1))}°`;
}

/** The leg the swing rows were proposed for, in words ("" for the reference leg): the rows that move the leg against
 * its own inertia were scaled with it, so a number the prosthetist compares with another leg's table says why. */
export function swingInertiaWords(s) {
  if (!s || (Math.abs(s.knee_ratio - 1) < 0.005 && Math.abs(s.ankle_ratio - 1) < 0.005)) return "";
  return `swing rows for this leg (swing inertia ${s.knee_ratio.toFixed(2)}× the reference leg's about the knee, `
    + `${s.ankle_ratio.toFixed(2)}× about the ankle) · `;
}
