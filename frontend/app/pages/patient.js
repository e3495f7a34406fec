import { api, get, post } from "../api.js";
import { app } from "../state.js";
import { chip, confirmDialog, extrapolationChip, fmt, h, modeWords, rangeText, table, tableName, when } from "../ui.js";

export async function patientPage(view, id) {
  const [patient, proposals, envelopes, sessions, devices, trend, range] = await Promise.all([
    get(`/api/patients/${id}`), get(`/api/patients/${id}/proposals`), get(`/api/patients/${id}/envelopes`),
    get(`/api/patients/${id}/sessions`), get("/api/devices"), get(`/api/patients/${id}/trend`), get("/api/task-range")]);
  const details = h("dl", { class: "facts" },
    h("dt", {}, "Body mass"), h("dd", { id: "patient-mass" }, fmt(patient.body_mass_kg, 1, "kg")),
    h("dt", {}, "Height"), h("dd", {}, fmt(patient.height_m, 2, "m")),
    h("dt", {}, "Side"), h("dd", {}, patient.side),
    h("dt", {}, "K-level"), h("dd", {}, patient.k_level === null ? "—" : `K${patient.k_level}`),
    h("dt", {}, "Notes"), h("dd", {}, patient.notes || "—"));

  const versionOf = Object.fromEntries(proposals.map((p) => [p.id, p.version]));
  const propRows = proposals.map((p) => h("tr", {},
    h("td", {}, h("a", { href: `#/proposals/${p.id}` }, `v${p.version}`)),
    h("td", { class: "num" }, fmt(p.task.speed_mps, 2)), h("td", { class: "num" }, fmt(p.task.incline_deg, 1)),
    h("td", {}, chip(p.status, p.status)), h("td", {}, p.source === "edit" ? `edited from v${versionOf[p.parent_id] ?? "?"}` : "model"),
    h("td", {}, extrapolationChip(p)), h("td", {}, p.created_by),
    h("td", {}, when(p.created_at))));

  const envVersion = Object.fromEntries(envelopes.map((e) => [e.id, e.version]));
  const envRows = envelopes.map((e) => h("tr", {},
    h("td", {}, h("a", { href: `#/envelopes/${e.id}` }, `v${e.version}`)), h("td", {}, rangeText(e)),
    h("td", { class: "num" }, `${e.grid[0]} × ${e.grid[1]}`), h("td", {}, chip(e.status, e.status)),
    h("td", {}, e.source === "edit" ? `edited from v${envVersion[e.parent_id] ?? "?"}` : "model"),
    h("td", {}, extrapolationChip(e, "some nodes outside data")), h("td", {}, e.created_by),
    h("td", {}, when(e.created_at))));

  const sessRows = sessions.map((s) => h("tr", {},
    h("td", {}, `#${s.id}`, s.simulated ? h("span", { class: "simulated-chip" }, " ", chip("simulated", "warn")) : ""),
    h("td", {}, s.device_id), h("td", {}, s.table_label ?? "—"),
    h("td", {}, s.task_words), h("td", {}, chip(s.status, s.status)),
    h("td", { class: "num" }, s.summary ? s.summary.strides : "—"), h("td", { class: "num" }, sessionErrors(s.summary)),
    h("td", {}, when(s.started_at)),
    h("td", {}, s.status === "stopped" ? h("a", { href: `#/sessions/${s.id}/report` }, "report")
      : h("a", { href: `#/monitor/${s.device_id}?patient=${patient.id}` }, "monitor"))));

  const devRows = devices.map((d) => h("tr", {},
    h("td", {}, h("a", { href: `#/monitor/${d.id}?patient=${patient.id}` }, d.id)), h("td", {}, d.kind),
    h("td", {}, chip(d.online ? "online" : "offline", d.online ? "ok" : "bad")), h("td", {}, modeWords(d.mode)),
    h("td", {}, d.patient ? d.patient.patient_code : "nobody"),
    h("td", {}, d.active_table ? tableName(d.active_table) : d.active_version === null ? "—" : `device version ${d.active_version}`),
    h("td", { class: "mono" }, d.active_crc32 || "—")));

  view.replaceChildren(...[
    h("p", { class: "crumbs" }, h("a", { href: "#/patients" }, "Patients"), " / ", patient.code_name),
    h("h1", {}, `Patient ${patient.code_name}`),
    h("section", { class: "card" }, details, app.me.role === "prosthetist" ? massForm(patient) : null),
    legCard(patient, app.me.role === "prosthetist"),
    h("section", { class: "card" }, h("h2", {}, "Proposals"),
      app.me.role === "prosthetist" ? proposalForm(patient, range) : null,
      proposals.length ? table(["Version", "Speed (m/s)", "Incline (deg)", "Status", "Source", "", "By", "Created"],
        propRows, { id: "proposals" }) : h("p", { class: "muted" }, "No proposals yet.")),
    h("section", { class: "card" }, h("h2", {}, "Envelopes (the leg adapts to speed and incline inside one)"),
      app.me.role === "prosthetist" ? envelopeForm(patient, range) : null,
      envelopes.length ? table(["Version", "Range", "Grid (speeds × inclines)", "Status", "Source", "", "By", "Created"],
        envRows, { id: "envelopes" }) : h("p", { class: "muted" }, "No envelopes yet.")),
    h("section", { class: "card" }, h("h2", {}, "Devices"),
      devices.length ? table(["Device", "Kind", "Link", "Mode", "Worn by", "Active table", "Active CRC-32"], devRows)
        : h("p", { class: "muted" }, "No device configured on this server (quasitune serve --device).")),
    h("section", { class: "card" }, h("h2", {}, "Walking sessions"),
      sessions.length ? table(["Session", "Device", "Table", "Task", "Status", "Strides",
        "Angle error per stride, knee / ankle (deg)", "Started", ""], sessRows,
        { id: "sessions" }) : h("p", { class: "muted" }, "No sessions recorded.")),
    trend.length ? h("section", { class: "card" }, h("h2", {}, "Trend over days"), trendTable(trend),
      h("p", { class: "muted small" }, "Per day (UTC) of stopped sessions. Cadence and errors (each stride against the reference at its own task): weighted by strides. Where: time per ",
        "task class (slow < 0.9 m/s ≤ moderate < 1.3 m/s ≤ fast; downhill < −4° ≤ level ≤ +4° < uphill), by the leg's own estimate ",
        "in adaptive sessions, at the session's task otherwise.")) : null].filter(Boolean));   // no "null" text nodes
}

const CLASS_WORDS = (key) => key.replace("_", ", ");

// a session's headline errors (each stride at its own task), or why there are none
function sessionErrors(m) {
  const head = m?.headline;
  if (!head) return "—";
  if (!head.enough_strides) return h("span", { class: "muted", title: `at least ${head.min_strides} strides are needed` }, "too few strides to judge");
  return `${fmt(head.knee_angle_rmse_deg, 1)} / ${fmt(head.ankle_angle_rmse_deg, 1)}`;
}

function trendTable(trend) {
  return table(["Day", "Sessions", "Strides", "Walking (min)", "Cadence (steps/min)", "Knee angle error per stride (deg)",
    "Ankle angle error per stride (deg)", "Where (min)"], trend.map((d) => h("tr", {}, h("td", {}, d.day), h("td", { class: "num" }, d.sessions),
    h("td", { class: "num" }, d.strides), h("td", { class: "num" }, fmt(d.walking_s / 60, 1)),
    h("td", { class: "num" }, fmt(d.cadence_steps_per_min, 1)), h("td", { class: "num" }, fmt(d.knee_angle_rmse_deg, 1)),
    h("td", { class: "num" }, fmt(d.ankle_angle_rmse_deg, 1)),
    h("td", { class: "small" }, Object.entries(d.time_by_task_class_s).filter(([, t]) => t > 0)
      .sort((a, b) => b[1] - a[1]).map(([k, t]) => `${CLASS_WORDS(k)} ${fmt(t / 60, 1)}`).join(" · ") || "—"))), { id: "trend" });
}

// The tasks the model knows (the server's range): a request beyond them needs "extrapolate" and a written reason,
// asked for here only when a value typed lies beyond
function extrapolationFields(range, tasks) {
  const k = range.known;
  const note = h("p", { class: "muted small", id: "known-range" }, `The model knows ${fmt(k.speed_mps[0], 2)}–`
    + `${fmt(k.speed_mps[1], 2)} m/s and ${fmt(k.incline_deg[0], 0)}° to +${fmt(k.incline_deg[1], 0)}°: its walking data `
    + `cover ${fmt(k.data_speed_mps[0], 2)}–${fmt(k.data_speed_mps[1], 2)} m/s and ${fmt(k.data_incline_deg[0], 0)}° to `
    + `+${fmt(k.data_incline_deg[1], 0)}°, and it predicts up to ${fmt(k.speed_margin_mps, 2)} m/s and `
    + `${fmt(k.incline_margin_deg, 0)}° beyond them (flagged as extrapolation). Further out its uncertainty no longer `
    + "says anything about the patient: it is built only with a written reason.");
  const check = h("input", { type: "checkbox", name: "extrapolate" });
  const reason = h("textarea", { name: "reason", rows: 2, cols: 50, minlength: range.extrapolation_reason_min_chars,
    placeholder: `why this task, beyond what the model knows (at least ${range.extrapolation_reason_min_chars} characters)` });
  const box = h("fieldset", { class: "extrapolate", hidden: true }, h("legend", {}, "Beyond what the model knows"),
    h("label", {}, check, " build it anyway (audited; the version is marked as extrapolated everywhere)"), reason);
  const beyond = () => tasks().some(([s, g]) => s < k.speed_mps[0] || s > k.speed_mps[1] || g < k.incline_deg[0]
    || g > k.incline_deg[1]);
  const update = () => { box.hidden = !beyond(); reason.required = !box.hidden && check.checked; };
  check.addEventListener("change", update);
  return { note, box, update, body: () => (!box.hidden && check.checked ? { extrapolate: true, reason: reason.value } : {}) };
}

function envelopeForm(patient, range) {
  const error = h("p", { class: "error", role: "alert" });
  const num = (name, label, value, min, max, step) => h("label", {}, label,
    h("input", { name, type: "number", min, max, step, value, required: true, size: 5 }));
  const [s0, s1] = range.speed_mps, [g0, g1] = range.incline_deg, [n0, n1] = range.envelope_nodes_per_axis;
  const form = h("form", { class: "inline", id: "request-envelope" },
    num("speed_lo", "Speed from (m/s)", "0.6", s0, s1, 0.05), num("speed_hi", "to", "1.6", s0, s1, 0.05),
    num("incline_lo", "Incline from (deg)", "-10", g0, g1, 0.5), num("incline_hi", "to", "10", g0, g1, 0.5),
    num("n_speeds", "Grid: speeds", "5", n0, n1, 1), num("n_inclines", "× inclines", "5", n0, n1, 1),
    h("button", { type: "submit" }, "Request envelope"), error);
  const value = (name) => Number(form.elements[name].value);
  const extra = extrapolationFields(range, () => [value("speed_lo"), value("speed_hi")].flatMap((s) =>
    [[s, value("incline_lo")], [s, value("incline_hi")]]));
  const grid = h("p", { class: "muted small" }, `At most ${range.envelope_max_nodes} nodes in all (what one transfer to the `
    + "leg carries).");
  form.append(extra.box, extra.note, grid);
  form.addEventListener("input", extra.update);
  form.addEventListener("submit", async (ev) => {
    ev.preventDefault();
    error.textContent = "";
    const d = new FormData(form);
    const n = (k) => Number(d.get(k));
    const button = form.querySelector("button");
    button.disabled = true;
    button.textContent = "Building every node…";
    app.envelopeRequestedAt = performance.now();
    try {
      const e = await post(`/api/patients/${patient.id}/envelopes`, { speed_range_mps: [n("speed_lo"), n("speed_hi")],
        incline_range_deg: [n("incline_lo"), n("incline_hi")], grid: [n("n_speeds"), n("n_inclines")], ...extra.body() });
      app.envelopeReturnedAt = performance.now();   // start of "interactive within 1 s" (bench-ui reads it)
      location.hash = `#/envelopes/${e.id}`;
    } catch (err) {
      error.textContent = err.message;
    } finally {
      button.disabled = false;
      button.textContent = "Request envelope";
    }
  });
  return form;
}

function proposalForm(patient, range) {
  const error = h("p", { class: "error", role: "alert" });
  const form = h("form", { class: "inline", id: "propose" },
    h("label", {}, "Speed (m/s)", h("input", { name: "speed_mps", type: "number", min: range.speed_mps[0],
      max: range.speed_mps[1], step: 0.01, value: "1.25", required: true })),
    h("label", {}, "Incline (deg, + uphill)", h("input", { name: "incline_deg", type: "number",
      min: range.incline_deg[0], max: range.incline_deg[1], step: 0.5, value: "0", required: true })),
    h("button", { type: "submit" }, "Request proposal"), error);
  const extra = extrapolationFields(range, () => [[Number(form.elements.speed_mps.value),
    Number(form.elements.incline_deg.value)]]);
  form.append(extra.box, extra.note);
  form.addEventListener("input", extra.update);
  form.addEventListener("submit", async (ev) => {
    ev.preventDefault();
    error.textContent = "";
    const d = new FormData(form);
    const button = form.querySelector("button");
    button.disabled = true;
    try {
      const p = await post(`/api/patients/${patient.id}/proposals`,
        { speed_mps: Number(d.get("speed_mps")), incline_deg: Number(d.get("incline_deg")), ...extra.body() });
      app.proposalReturnedAt = performance.now();   // start of "interactive within 1 s" (bench-ui reads it)
      location.hash = `#/proposals/${p.id}`;
    } catch (err) {
      error.textContent = err.message;
    } finally {
      button.disabled = false;
    }
  });
  return form;
}

// Body mass sets every torque and load threshold of a proposal: editable here, and a version built for a mass
// more than 5 % away is then pushed only with a written reason (propose again).
// the leg file's fields (device_bridge/sim/leg_file.py) in words with their units, in the file's order
const LEG_FIELDS = [["name", "Name", ""], ["body_height_m", "Body height", "m"], ["socket_mass_kg", "Socket and thigh mass", "kg"],
  ["shank_mass_kg", "Shank mass", "kg"], ["ankle_unit_mass_kg", "Ankle unit mass", "kg"], ["foot_mass_kg", "Foot mass", "kg"],
  ["heel_back_m", "Heel behind the ankle", "m"], ["contact_radius_m", "Foot contact radius", "m"],
  ["knee_armature_kg_m2", "Knee drive's reflected inertia", "kg·m²"], ["ankle_armature_kg_m2", "Ankle drive's reflected inertia", "kg·m²"],
  ["knee_friction_Nm", "Knee drive friction", "N·m"], ["ankle_friction_Nm", "Ankle drive friction", "N·m"],
  ["knee_damping_Nm_s_per_rad", "Knee drive damping", "N·m·s/rad"], ["ankle_damping_Nm_s_per_rad", "Ankle drive damping", "N·m·s/rad"]];

// The patient's leg: new versions are made for it (swing rows for its inertia) and the bench walks it for their
// previews and refinements; none described: the server's bench leg stands in, and the card says so
function legCard(patient, canEdit) {
  const leg = patient.leg;
  const given = leg ? LEG_FIELDS.filter(([k]) => k in leg) : [];
  const shown = leg
    ? table(["Leg", "Value", "Unit"], given.map(([k, words, unit]) => h("tr", {}, h("td", {}, words),
      h("td", { class: k === "name" ? "" : "num" }, String(leg[k])), h("td", {}, unit))), { id: "leg-description" })
    : h("p", { id: "leg-description", class: "muted" }, "No description of this patient's leg: new versions are made for ",
      "the server's bench leg (the nominal one unless the server was started with --leg) and their previews walk it.");
  const card = h("section", { class: "card", id: "leg-card" }, h("h2", {}, "The patient's leg (what the bench walks)"), shown,
    h("p", { class: "muted small" }, leg ? "Fields not given are the nominal bench leg's. " : "",
      "Versions keep the leg they were made for: after a change, propose again for the new leg."));
  if (!canEdit) return card;
  const error = h("p", { class: "error", role: "alert" });
  const text = h("textarea", { name: "leg", rows: 4, cols: 60, spellcheck: "false",
    placeholder: '{"name": "…", "body_height_m": 1.62, "foot_mass_kg": 1.2, "ankle_friction_Nm": 2.0}' },
  leg ? JSON.stringify(leg) : "");
  const save = async (value) => {
    error.textContent = "";
    try {
      await api(`/api/patients/${patient.id}`, { method: "PATCH", body: { leg: value } });
      await patientPage(document.getElementById("view"), patient.id);
    } catch (err) {
      error.textContent = err.message;
    }
  };
  const form = h("form", { id: "edit-leg" }, h("label", {}, "Describe the leg (a leg file's fields, JSON) ", text),
    h("button", { type: "submit", class: "secondary" }, "Save the leg"),
    leg ? h("button", { type: "button", class: "secondary", id: "clear-leg", onclick: () => save(null) }, "No description") : null,
    error);
  form.addEventListener("submit", (ev) => {
    ev.preventDefault();
    let value;
    try {
      value = JSON.parse(text.value);
    } catch (err) {
      error.textContent = `not JSON: ${err.message}`;
      return;
    }
    save(value);
  });
  card.append(form);
  return card;
}

function massForm(patient) {
  const error = h("p", { class: "error", role: "alert" });
  const mass = h("input", { name: "body_mass_kg", type: "number", min: 20, max: 200, step: 0.1, required: true,
    value: patient.body_mass_kg });
  const form = h("form", { class: "inline", id: "edit-mass" }, h("label", {}, "Body mass (kg) ", mass),
    h("button", { type: "submit", class: "secondary" }, "Save body mass"),
    h("span", { class: "muted small" }, "A table or envelope built for another mass (more than 5 % away) is pushed only with a written reason; propose again for the new mass."),
    error);
  form.addEventListener("submit", async (ev) => {
    ev.preventDefault();
    error.textContent = "";
    const now = Number(mass.value);
    if (Math.abs(now - patient.body_mass_kg) > 0.05 * patient.body_mass_kg) {   // every torque and threshold scales with it
      const legs = (await get("/api/devices")).filter((d) => d.patient?.patient_id === patient.id);
      const ok = await confirmDialog({ id: "mass-dialog", title: `Change ${patient.code_name}'s body mass by more than 5 %?`,
        facts: [["Body mass", `${fmt(patient.body_mass_kg, 1, "kg")} → ${fmt(now, 1, "kg")}`],
          ...legs.map((d) => [`On ${d.id} now`, `${tableName(d.pending_table || d.active_table, true)}: built for `
            + `${fmt((d.pending_table || d.active_table)?.body_mass_kg ?? patient.body_mass_kg, 0, "kg")}; it keeps running, `
            + "and is pushed again only with a written reason (propose again for the new mass)"]),
          ...(legs.length ? [] : [["On a leg", "no leg is assigned to this patient"]])],
        confirm: "Change body mass" });
      if (!ok) return;
    }
    try {
      await api(`/api/patients/${patient.id}`, { method: "PATCH", body: { body_mass_kg: now } });
      await patientPage(document.getElementById("view"), patient.id);
    } catch (err) {
      error.textContent = err.message;
    }
  });
  return form;
}
