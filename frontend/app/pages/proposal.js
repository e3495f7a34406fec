// Proposal review: loops, curves with bands, GPR features, the table (editable into a new version), diff,
// approve/reject, push with live status, and the simulated preview against the FSMIC.
import { get, post, put } from "../api.js";
import { app, onLeave } from "../main.js";
import { legend, loopChart, phaseChart } from "../charts.js";
import { chip, confirmDialog, fmt, h, notice, pm, referenceLabel, SUBPHASE_COLOUR, SUBPHASE_LABEL, SUBPHASES, table, tableName,
  when } from "../ui.js";

const RAD = Math.PI / 180;
const state = { kUnit: "rad" };   // stiffness display unit, kept across versions

// the measured conditions behind the model, and the reference at this task with what it really is
function reference(task) {
  return get(`/api/reference?speed_mps=${task.speed_mps}&incline_deg=${task.incline_deg}`);
}

const FIT_METHOD_HELP = {
  least_squares: "least-squares line τ = kθ + c through the predicted loop",
  extension_window: "least-squares line over the knee's stance extension only (stance-flexion peak to its late-stance minimum); pre-swing left out",
  range_guard: "the fitted θe lay outside the joint range: θe clamped to the range and k re-fitted",
  passivity_guard: "the fitted line would inject energy with θe inside the swept angles: k set to the restoring floor, θe re-fitted",
  swing_target: "not a fit: θe is the predicted swing target, k the model's swing stiffness (restoring)",
  manual: "edited by hand",
  literature: "published table",
};

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
    h("p", { class: "chips" }, chip(p.status, p.status), p.deployment ? chip(p.deployment.replaceAll("_", " "), "ok") : null,
      chip(p.safety.ok ? "within safety limits" : "outside safety limits", p.safety.ok ? "ok" : "bad"),
      p.source === "edit" ? chip(`edited from v${p.parent_version}`) : chip("model")),
    h("p", { class: "provenance" }, `Model ${p.model.version} · training data sha256 ${p.model.data_sha256.slice(0, 12)}… · `,
      `patient mass ${fmt(mass, 1, "kg")} · created by ${p.created_by} ${when(p.created_at)} · table sha256 `,
      h("span", { class: "mono" }, p.table_sha256.slice(0, 12) + "…"),
      p.edit_comment ? ` · edit: “${p.edit_comment}”` : "",
      p.decision ? ` · ${p.decision.status} by ${p.decision.by} ${when(p.decision.at)}${p.decision.comment ? `: “${p.decision.comment}”` : ""}` : ""),
  ];
  if (p.extrapolation) {
    const outside = p.features.filter((f) => f.extrapolation).map((f) => f.label).join(", ");
    head.push(h("div", { class: "banner warn", role: "alert", id: "extrapolation" },
      h("strong", {}, "Extrapolation: "), "this task is outside the walking data the model was trained on. ",
      "Predictions there are less certain (see the ± SD); review every value. Outside: ", outside || "task hull"));
  }
  if (!p.safety.ok) {
    head.push(h("div", { class: "banner bad", role: "alert" }, h("strong", {}, "Safety limits: "),
      p.safety.violations.map((v) => v.message).join("; ")));
  }

  const loops = h("div", { class: "two" }, h("figure", { id: "loop-knee", class: "chart" }),
    h("figure", { id: "loop-ankle", class: "chart" }));
  const loopLegend = legend([["#1f4e99", "proposal (KMP mean) with ±1 SD band", "band"],
    ["#999", atTask ? `grey: measured level walking; bold: reference at this task — ${atTask.label}`
      : "grey: measured level walking (no curves were measured this steep: the proposal is the model's prediction)"],
    ["#222", "via-points from the GPR feature predictions", "star"],
    ...SUBPHASES.map((sp) => [SUBPHASE_COLOUR[sp], `${SUBPHASE_LABEL[sp]} fit τ = k(θ − θe)`, "dash"])]);
  const curveBox = h("div", { class: "four", id: "curves" });
  const decisionBox = h("section", { class: "card", id: "decision" });
  const pushBox = h("section", { class: "card", id: "push" });
  const previewBox = h("section", { class: "card", id: "preview" }, h("h2", {}, "Simulated preview: this table vs the FSMIC"),
    h("p", { class: "muted", id: "preview-status" }, "Walking both controllers on the simulated bench…"));

  view.replaceChildren(...head,
    h("section", { class: "card" }, h("h2", {}, "Torque-angle loops"), loops, loopLegend,
      h("p", { class: "muted small", id: "reference-note" }, "Moments are internal joint moments of this patient (N·m = N·m/kg × ",
        fmt(mass, 1, "kg"), "), flexor / dorsiflexor positive. ", atTask
          ? `Reference at this task: ${atTask.source}. Data: ${atTask.citations.join(" ")}`
          : `No measured curves at ${fmt(p.task.incline_deg, 1, "°")}: the reference is the model's own prediction, not data.`)),
    h("section", { class: "card" }, h("h2", {}, "Over the gait cycle"), curveBox,
      h("p", { class: "muted small" }, "Dotted lines: sub-phase boundaries (stance flexion | stance extension | swing flexion | swing extension).")),
    h("section", { class: "card" }, h("h2", {}, "Predicted features (GPR, ±1 SD)"), featureTable(p)),
    h("section", { class: "card", id: "table-card" }, parameterTable(p, canDecide)),
    decisionBox, pushBox, h("section", { class: "card", id: "versions" }), previewBox);

  drawLoops(p, ref, atTask);
  drawCurves(p, atTask, curveBox);
  renderDecision(decisionBox, p, canDecide);
  renderPush(pushBox, p, canDecide);
  app.proposalInteractiveAt = performance.now();
  if (app.proposalReturnedAt !== undefined) {
    app.proposalViewMs = app.proposalInteractiveAt - app.proposalReturnedAt;
    app.proposalReturnedAt = undefined;
  }
  renderVersions(document.getElementById("versions"), p);
  renderPreview(previewBox, p);
}

function moments(p, joint) {
  return p.curves[`${joint}_moment_Nm_per_kg`].map((m) => m * p.task.body_mass_kg);
}

function subphaseOf(phase, b) {
  const edges = [0, b.stance_flexion_to_stance_extension, b.stance_extension_to_swing_flexion,
    b.swing_flexion_to_swing_extension, 1];
  return SUBPHASES.filter((_, i) => phase >= edges[i] - 1e-9 && phase <= edges[i + 1] + 1e-9);
}

function drawLoops(p, ref, atTask) {
  const mass = p.task.body_mass_kg;
  for (const joint of ["knee", "ankle"]) {
    const ang = p.curves[`${joint}_angle_deg`];
    const mom = moments(p, joint);
    const sd = p.curves[`${joint}_moment_Nm_per_kg_std`].map((x) => x * mass);
    const lines = [];
    for (const row of p.table.filter((r) => r.joint === joint)) {
      const inPhase = ang.filter((_, i) => subphaseOf(p.curves.phase[i], p.subphase_boundaries_phase).includes(row.subphase));
      if (!inPhase.length) continue;
      const lo = Math.min(...inPhase), hi = Math.max(...inPhase);
      lines.push({ color: SUBPHASE_COLOUR[row.subphase], points: [lo, hi].map((th) => [th, row.k_Nm_per_rad * (th - row.theta_e_deg) * RAD]),
        label: `${SUBPHASE_LABEL[row.subphase]}: k = ${fmt(row.k_Nm_per_rad, 0)} N·m/rad, θe = ${fmt(row.theta_e_deg, 1)}°, R² = ${fmt(row.r2, 2)}` });
    }
    loopChart(document.getElementById(`loop-${joint}`), {
      title: `${joint === "knee" ? "Knee" : "Ankle"} torque-angle loop`,
      xLabel: `${joint} angle (deg, ${joint === "knee" ? "flexion" : "dorsiflexion"} +)`,
      yLabel: `${joint} moment (N·m)`,
      reference: [...ref.conditions.map((c) => ({ nearest: false, label: `measured: ${c.name} (${fmt(c.speed_mps, 2)} m/s, level)`,
        points: c[`${joint}_angle_deg`].map((a, i) => [a, c[`${joint}_moment_Nm_per_kg`][i] * mass]) })),
      ...(atTask ? [{ nearest: true, label: `reference at this task: ${atTask.label}`,
        points: atTask[`${joint}_angle_deg`].map((a, i) => [a, atTask[`${joint}_moment_Nm_per_kg`][i] * mass]) }] : [])],
      mean: ang.map((a, i) => [a, mom[i]]),
      band: { upper: ang.map((a, i) => [a, mom[i] + sd[i]]), lower: ang.map((a, i) => [a, mom[i] - sd[i]]) },
      vias: p.via_points.filter((v) => v.joint === joint).map((v) => ({ point: [v.angle_deg, v.moment_Nm_per_kg * mass],
        label: `via-point at ${fmt(v.phase * 100, 0)} % of the cycle: ${fmt(v.angle_deg, 1)}°, ${fmt(v.moment_Nm_per_kg * mass, 1)} N·m` })),
      lines,
    });
  }
}

function drawCurves(p, atTask, box) {
  const x = p.curves.phase.map((s) => s * 100);
  const b = p.subphase_boundaries_phase;
  const markers = [b.stance_flexion_to_stance_extension, b.stance_extension_to_swing_flexion,
    b.swing_flexion_to_swing_extension].map((v) => v * 100);
  const refX = atTask ? atTask.phase.map((s) => s * 100) : null;
  for (const [key, label] of [["knee_angle_deg", "knee angle (deg)"], ["knee_moment_Nm_per_kg", "knee moment (N·m/kg)"],
    ["ankle_angle_deg", "ankle angle (deg)"], ["ankle_moment_Nm_per_kg", "ankle moment (N·m/kg)"]]) {
    const el = h("figure", { class: "chart", dataset: { channel: key } });
    box.append(el);
    const lines = [{ label: "proposal", values: p.curves[key], color: "#1f4e99" }];
    if (atTask) {
      lines.push({ label: atTask.kind === "measured" ? "measured level walking at this speed"
        : "measured level walking + measured ramp change", values: x.map((xx) => interp(xx, refX, atTask[key])),
      color: "#888888", dash: [6, 4], width: 1.5 });
    }
    phaseChart(el, { title: label, yLabel: label.match(/\((.*)\)/)[1], x, markers,
      bands: [{ label: "proposal", mean: p.curves[key], sd: p.curves[`${key}_std`], color: "#1f4e99" }], lines });
  }
}

function interp(x, xs, ys) {
  if (x <= xs[0]) return ys[0];
  for (let i = 1; i < xs.length; i++) {
    if (x <= xs[i]) return ys[i - 1] + (ys[i] - ys[i - 1]) * (x - xs[i - 1]) / (xs[i] - xs[i - 1]);
  }
  return ys[ys.length - 1];
}

function featureTable(p) {
  const rows = p.features.map((f) => h("tr", { class: f.extrapolation ? "warn-row" : "" },
    h("td", {}, f.label), h("td", {}, f.joint), h("td", { class: "num" }, pm(f.value, f.std, f.unit === "deg" ? 1 : 3, f.unit)),
    h("td", { class: "num" }, pm(f.phase * 100, f.phase_std * 100, 1, "% cycle")),
    h("td", {}, f.extrapolation ? chip("outside data", "warn") : "")));
  return table(["Feature", "Joint", "Value ± SD", "Phase ± SD", ""], rows, { id: "features" });
}

// ---------------------------------------------------------------------------------------------- parameter table

function kShown(k) {
  return state.kUnit === "rad" ? k : k * RAD;
}

function parameterTable(p, canEdit) {
  const L = p.limits;
  const violated = new Set(p.safety.violations.map((v) => v.field));
  const kUnit = state.kUnit === "rad" ? "N·m/rad" : "N·m/deg";
  const range = (r, scale = 1, d = 0) => `${fmt(r.low * scale, d)} … ${fmt(r.high * scale, d)}`;
  const toggle = h("fieldset", { class: "toggle", id: "k-unit" }, h("legend", {}, "Stiffness unit"),
    ...["rad", "deg"].map((u) => h("label", {}, h("input", { type: "radio", name: "k-unit", value: u,
      checked: state.kUnit === u, onchange: () => { state.kUnit = u; rerender(); } }), `N·m/${u}`)));
  const cell = (row, field, value, digits, limit) => {
    const key = `${row.joint}.${row.subphase}.${field}`;
    const out = violated.has(key) || value < limit.low || value > limit.high;
    const shown = field === "k_Nm_per_rad" ? kShown(value) : value;
    const content = canEdit
      ? h("input", { type: "number", step: "any", value: shown.toFixed(digits), "aria-label": `${key} (${field === "k_Nm_per_rad" ? kUnit : field.endsWith("deg") ? "deg" : "N·m·s/rad"})`,
        dataset: { field: key, original: shown.toFixed(digits) } })
      : fmt(shown, digits);
    return h("td", { class: `num${out ? " out" : ""}`, title: out ? `outside the safety limits` : "" }, content);
  };
  const fitChip = (r) => r.fit_method === "swing_target" ? chip("swing target")
    : r.guarded ? chip("guarded fit", "warn") : r.fit_method;
  const rows = p.table.map((r) => {
    const thetaLim = r.joint === "knee" ? L.knee_theta_e_deg : L.ankle_theta_e_deg;
    return h("tr", {},
      h("td", {}, r.joint), h("td", {}, h("span", { class: "dot", style: `--c:${SUBPHASE_COLOUR[r.subphase]}` }), SUBPHASE_LABEL[r.subphase]),
      cell(r, "k_Nm_per_rad", r.k_Nm_per_rad, state.kUnit === "rad" ? 1 : 3, L.k_Nm_per_rad),
      cell(r, "theta_e_deg", r.theta_e_deg, 2, thetaLim),
      cell(r, "b_Nm_s_per_rad", r.b_Nm_s_per_rad, 2, L.b_Nm_s_per_rad),
      h("td", { class: "num" }, r.r2 === null ? "—" : fmt(r.r2, 2)),
      h("td", { title: FIT_METHOD_HELP[r.fit_method] ?? "" }, fitChip(r)));
  });
  const th = p.thresholds;
  const thUnits = { sf_to_se_ankle_moment_Nm: ["SF→SE: ankle moment below", "N·m", L.ankle_moment_Nm],
    se_to_wf_load_N: ["SE→WF (toe-off): load below", "N", L.load_N],
    wf_to_we_knee_angle_deg: ["WF→WE: knee flexed beyond", "deg", L.knee_theta_e_deg],
    we_to_sf_load_N: ["WE→SF (heel strike): load above", "N", L.load_N],
    min_state_time_s: ["minimum time in a state", "s", L.state_time_s],
    max_state_time_s: ["maximum time in a state", "s", L.state_time_s],
    sf_to_se_knee_extension_deg_per_s: ["SF→SE also: loaded knee extending faster than (0 = off)", "deg/s",
      L.knee_extension_deg_per_s] };
  const thRows = Object.entries(thUnits).map(([k, [label, unit, lim]]) => {
    const out = violated.has(`thresholds.${k}`) || th[k] < lim.low || th[k] > lim.high;
    return h("tr", {}, h("td", {}, label), h("td", { class: `num${out ? " out" : ""}` },
      canEdit ? h("input", { type: "number", step: "any", value: th[k].toFixed(3), "aria-label": `${k} (${unit})`,
        dataset: { field: `thresholds.${k}`, original: th[k].toFixed(3) } }) : fmt(th[k], 3)),
    h("td", {}, unit), h("td", { class: "muted" }, range(lim, 1, 2)));
  });
  const box = h("div", {},
    h("h2", {}, "Parameter table: τ = k(θ − θe) − b·θ̇ per sub-phase"), toggle,
    table(["Joint", "Sub-phase", `k (${kUnit})`, "θe (deg)", "b (N·m·s/rad)", "R²", "Fit"], rows, { id: "param-table" }),
    h("p", { class: "muted small" }, `Limits: k ${range(L.k_Nm_per_rad, state.kUnit === "rad" ? 1 : RAD, state.kUnit === "rad" ? 0 : 2)} ${kUnit} (negative = restoring); `,
      `θe knee ${range(L.knee_theta_e_deg)}°, ankle ${range(L.ankle_theta_e_deg)}°; b ${range(L.b_Nm_s_per_rad)} N·m·s/rad. `,
      "Cells outside the limits are marked red. R²: how well the row's straight line fits the predicted loop in that sub-phase. ",
      "Swing-target rows are not fits: in swing the foot is unloaded, so θe is the predicted swing target (knee: swing-flexion peak, then heel-strike angle; ankle: swing dorsiflexion plus a toe-clearance margin) and k a set swing stiffness; their R² (often far below 0) says how little of the able-bodied swing moment such a line explains."),
    h("h3", {}, "State-machine thresholds"),
    table(["Transition", "Value", "Unit", "Limits"], thRows, { id: "thresholds" }));
  if (canEdit) box.append(editForm(p));
  function rerender() {
    document.getElementById("table-card").replaceChildren(parameterTable(p, canEdit));
  }
  return box;
}

function editForm(p) {
  const error = h("p", { class: "error", role: "alert", id: "edit-error" });
  const form = h("form", { class: "inline", id: "edit-form" },
    h("label", {}, "Why (audited)", h("input", { name: "comment", required: true, maxlength: 2000, size: 40 })),
    h("button", { type: "submit" }, "Save edits as a new draft version"), error);
  form.addEventListener("submit", async (ev) => {
    ev.preventDefault();
    error.textContent = "";
    const rows = {};
    const thresholds = {};
    for (const input of document.querySelectorAll("#table-card input[data-field]")) {
      if (input.value === input.dataset.original) continue;
      const value = Number(input.value);
      if (input.value.trim() === "" || !Number.isFinite(value)) {
        error.textContent = `${input.dataset.field}: “${input.value}” is not a number`;
        return;
      }
      const parts = input.dataset.field.split(".");
      if (parts[0] === "thresholds") thresholds[parts[1]] = value;
      else {
        const key = `${parts[0]}.${parts[1]}`;
        rows[key] ??= { joint: parts[0], subphase: parts[1] };
        rows[key][parts[2]] = parts[2] === "k_Nm_per_rad" && state.kUnit === "deg" ? value / RAD : value;
      }
    }
    if (!Object.keys(rows).length && !Object.keys(thresholds).length) {
      error.textContent = "nothing changed: edit a cell first";
      return;
    }
    const body = { rows: Object.values(rows), comment: new FormData(form).get("comment") };
    if (Object.keys(thresholds).length) body.thresholds = thresholds;
    try {
      const created = await post(`/api/proposals/${p.id}/edits`, body);
      notice(`Saved as draft v${created.version}`, "ok");
      location.hash = `#/proposals/${created.id}`;
    } catch (err) {
      error.textContent = err.message;
      for (const v of err.body?.violations || []) {
        document.querySelector(`#table-card input[data-field="${v.field}"]`)?.parentElement.classList.add("out");
      }
    }
  });
  return form;
}

// ---------------------------------------------------------------------------------------------- decisions, push

function renderDecision(box, p, canDecide) {
  box.replaceChildren(h("h2", {}, "Decision"));
  if (p.status !== "draft") {
    box.append(h("p", {}, `${p.decision.status} by ${p.decision.by} ${when(p.decision.at)}`,
      p.decision.comment ? ` — “${p.decision.comment}”` : "", ". An approved or rejected version never changes; edit it into a new draft instead."));
    return;
  }
  if (!canDecide) {
    box.append(h("p", { class: "muted" }, "Draft. Only a prosthetist can approve or reject it."));
    return;
  }
  const error = h("p", { class: "error", role: "alert" });
  const comment = h("input", { name: "comment", maxlength: 2000, size: 50, "aria-label": "Decision comment" });
  const decide = (what) => async () => {
    error.textContent = "";
    try {
      await post(`/api/proposals/${p.id}/${what}`, { comment: comment.value });
      notice(`${p.table_label} ${what === "approve" ? "approved" : "rejected"}`, "ok");
      await proposalPage(document.getElementById("view"), p.id);
    } catch (err) {
      error.textContent = err.message;
    }
  };
  const approve = h("button", { id: "approve", onclick: decide("approve"), disabled: true,
    title: p.safety.ok ? "say why first (what you reviewed)" : "outside the safety limits: cannot be approved" }, "Approve");
  const reject = h("button", { id: "reject", class: "secondary", onclick: decide("reject"), disabled: true,
    title: "say why first" }, "Reject");
  comment.addEventListener("input", () => {       // a decision needs its reason, like an edit
    const said = comment.value.trim().length > 0;
    approve.disabled = !said || !p.safety.ok;
    reject.disabled = !said;
  });
  box.append(h("div", { class: "inline" }, h("label", {}, "Why (required, audited) ", comment), approve, reject), error);
}

async function renderPush(box, p, canPush) {
  box.replaceChildren(h("h2", {}, "Device"));
  const [pushes, devices, patient] = await Promise.all([get(`/api/proposals/${p.id}/pushes`), get("/api/devices"),
    get(`/api/patients/${p.patient_id}`)]);
  const name = `${patient.code_name} · table v${p.version}`;
  const status = h("div", { id: "push-status", "aria-live": "polite" });
  if (pushes.length) {
    status.append(table(["Push", "Device", "CRC-32", "Status", "Requested", "Acknowledged", "Active"],
      pushes.map((x) => h("tr", {}, h("td", {}, `#${x.id}`), h("td", {}, x.device_id), h("td", { class: "mono" }, x.crc32),
        h("td", {}, chip(x.status, x.status === "failed" ? "bad" : x.status === "superseded" ? "" : "ok")),
        h("td", {}, when(x.requested_at)), h("td", {}, when(x.acknowledged_at)), h("td", {}, when(x.active_at))))));
  }
  if (p.status !== "approved" || !canPush || !devices.length) {
    box.append(h("p", { class: "muted" }, p.status !== "approved" ? "Only an approved version can be pushed to a device."
      : !devices.length ? "No device on this server." : "Only a prosthetist can push."), status);
    return;
  }
  const wearer = (d) => (d.patient ? `worn by ${d.patient.patient_code}` : "assigned to nobody");
  const select = h("select", { id: "push-device", "aria-label": "Device" },
    devices.map((d) => h("option", { value: d.id }, `${d.id} (${d.online ? "online" : "offline"}, ${wearer(d)})`)));
  const error = h("p", { class: "error", role: "alert" });
  const steps = h("ol", { class: "steps", id: "push-steps" });
  const button = h("button", { id: "push-button" }, "Push to device…");
  const assignBox = h("p", { id: "push-assignment" });
  const showAssignment = () => {
    const d = devices.find((x) => x.id === select.value);
    const mine = d.patient && d.patient.patient_id === p.patient_id;
    button.disabled = !mine;
    assignBox.replaceChildren(mine ? chip(`${d.id} is assigned to ${patient.code_name}`, "ok")
      : h("span", {}, chip(`${d.id} is ${wearer(d)}`, "warn"), " A table goes only to the leg of its patient. ",
        h("button", { id: "assign-device", class: "secondary", onclick: assign }, `Assign ${d.id} to ${patient.code_name}…`)));
  };
  async function assign() {
    const d = devices.find((x) => x.id === select.value);
    const ok = await confirmDialog({ id: "assign-dialog", title: `Assign ${d.id} to ${patient.code_name}?`,
      facts: [["Worn now by", d.patient ? `${d.patient.patient_code} (${fmt(d.patient.body_mass_kg, 0, "kg")})` : "nobody"],
        ["Will be worn by", `${patient.code_name} (${fmt(patient.body_mass_kg, 0, "kg")})`],
        ["Table on the leg", tableName(d.active_table, true)]],
      confirm: "Assign" });
    if (!ok) return;
    try {
      Object.assign(d, await put(`/api/devices/${d.id}/assignment`, { patient_id: p.patient_id }));
      showAssignment();
    } catch (err) {
      error.textContent = err.message;
    }
  }
  select.addEventListener("change", showAssignment);
  showAssignment();
  button.addEventListener("click", async () => {
    error.textContent = "";
    const d = await get(`/api/devices/${select.value}`);
    const current = d.pending_table || d.active_table;
    const ok = await confirmDialog({ id: "push-dialog", title: `Replace the table on ${d.id}?`,
      facts: [["Patient", `${patient.code_name} (${fmt(patient.body_mass_kg, 0, "kg")})`],
        ["On the leg now", tableName(current, true)],
        ["Replaced by", `${name} (${fmt(p.task.speed_mps, 2, "m/s")}, incline ${fmt(p.task.incline_deg, 1, "°")})`],
        ["When", "at the next heel strike after the device verifies it"]],
      requires: "The patient is seated or standing in the parallel bars.", confirm: "Push now" });
    if (!ok) return;
    button.disabled = true;
    steps.replaceChildren(h("li", { class: "doing" }, "sending the table over CAN…"));
    try {
      const push = await post(`/api/proposals/${p.id}/push`, { device_id: d.id,
        replaces_proposal_id: current ? current.proposal_id : null, patient_ready: true });
      steps.replaceChildren(h("li", { class: "done" }, `device read back CRC-32 ${push.crc32} (matches) in ${fmt(push.elapsed_ms, 1, "ms")}`),
        h("li", { class: "doing", id: "push-active" }, "waiting for the device to switch at the next heel strike…"));
      const deadline = Date.now() + 15000;
      while (Date.now() < deadline) {
        const now = await get(`/api/devices/${d.id}`);
        if (now.active_crc32 === push.crc32 && now.active_version === push.table_version) {
          steps.lastChild.className = "done";
          steps.lastChild.textContent = `active on ${now.id}: ${push.table_label}, CRC-32 ${now.active_crc32}, mode ${now.mode}`;
          break;
        }
        await new Promise((r) => setTimeout(r, 200));
      }
      if (steps.lastChild.className !== "done") steps.lastChild.textContent = "acknowledged, not yet active (the device switches at its next heel strike)";
      window.dispatchEvent(new CustomEvent("quasitune:device-changed"));
    } catch (err) {
      steps.lastChild.className = "failed";
      error.textContent = err.message;
    } finally {
      showAssignment();
    }
  });
  box.append(h("div", { class: "inline" }, select, button), assignBox, steps, error, status);
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
      d.changes.map((c) => h("tr", {}, h("td", {}, c.field), h("td", { class: "num" }, fmtAny(c.before)),
        h("td", { class: "num changed" }, fmtAny(c.after)), h("td", {}, c.unit || "")))) : h("p", {}, "No differences."));
  };
  other.addEventListener("change", show);
  box.replaceChildren(h("h2", {}, "Versions and differences"),
    versions.length > 1 ? h("div", { class: "inline" }, h("label", {}, "Compare with ", other)) : h("p", { class: "muted" }, "Only one version so far."),
    out);
  await show();
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
  const rmseRow = (label, base, u, unit, d) => {
    const key = `${base}_rmse_${u}`, ciKey = `${base}_rmse_ci95_${u}`;
    const withCi = (run) => fmt(run[key], d) + (run[ciKey] ? ` [${fmt(run[ciKey][0], d)}, ${fmt(run[ciKey][1], d)}]` : "")
      + ` ${unit}`;
    const diff = vs[`${base}_rmse_difference_${u}`], diffCi = vs[`${base}_rmse_difference_ci95_${u}`];
    const verdict = { "learned lower": "this table lower", "FSMIC lower": "FSMIC lower" }[vs[`${base}_verdict`]]
      || vs[`${base}_verdict`];
    const signed = (v) => (v > 0 ? "+" : "") + fmt(v, d);
    const diffCell = diff === undefined || diff === null ? "—"
      : `${signed(diff)} [${signed(diffCi[0])}, ${signed(diffCi[1])}] ${unit}: ${verdict}`;
    return h("tr", {}, h("td", {}, label), h("td", { class: "num" }, withCi(t)), h("td", { class: "num" }, withCi(f)),
      h("td", { class: verdict === "not resolved" ? "num muted" : "num" }, diffCell));
  };
  const medMax = (run) => run.heel_strike_to_stance_ms_median === undefined ? "—"
    : `${fmt(run.heel_strike_to_stance_ms_median, 0)} / ${fmt(run.heel_strike_to_stance_ms_max, 0)} ms`;
  const x = pv.phase_grid.map((s) => s * 100);
  const charts = h("div", { class: "two" });
  box.replaceChildren(h("h2", {}, "Simulated preview: this table vs the FSMIC"),
    h("p", { class: "muted small" }, `Both controllers walked ${fmt(pv.seconds, 0, "s")} each on the MuJoCo bench at this task `,
      `(socket driven along the able-bodied hip trajectory; metrics as in quasitune simulate). Reference: ${referenceLabel(t)} (${t.reference_source}). `,
      `Simulated ${when(pv.created_at)}.`),
    table(["Metric", "This table", "FSMIC (hand-tuned, not re-tuned)", "This table − FSMIC, 95 % interval"], [
      metric("falls", "falls", 0), metric("toe catches", "toe_catches", 0), metric("strides", "strides", 0),
      rmseRow("knee angle RMSE", "knee_angle", "deg", "deg", 1), rmseRow("ankle angle RMSE", "ankle_angle", "deg", "deg", 1),
      rmseRow("knee moment RMSE", "knee_moment", "Nm_per_kg", "N·m/kg", 3),
      rmseRow("ankle moment RMSE", "ankle_moment", "Nm_per_kg", "N·m/kg", 3),
      metric("cadence", "cadence_steps_per_min", 1, "steps/min"),
      h("tr", {}, h("td", {}, "foot contact → stance state, median / max"), h("td", { class: "num" }, medMax(t)),
        h("td", { class: "num" }, medMax(f)), h("td", {})),
      metric("on a swing row with > ½ body weight, per stride", "loaded_swing_ms_per_stride", 0, "ms")],
    { id: "preview-metrics" }),
    h("p", { class: "muted small" }, "[a, b]: 95 % interval over the strides walked (strides resampled with replacement). ",
      "\"not resolved\": with these strides either controller could be the lower one. A preview walks only a few strides, ",
      "and the FSMIC's strides change over a longer walk, so a longer walk can change the verdict (quasitune simulate ",
      "--seconds 20). The intervals say nothing about the bench's own assumptions (docs/results.md). ",
      "The last two rows are safety figures, not scores: how long a loaded leg stays on the weak swing impedance ",
      "after the foot touches down."),
    charts);
  if (t.falls > 0) box.insertBefore(h("div", { class: "banner bad" }, `This table fell ${t.falls} time(s) on the simulated bench. `,
    "Do not push it without understanding why."), box.children[1]);
  for (const key of ["knee_angle_deg", "ankle_angle_deg"]) {
    const el = h("figure", { class: "chart" });
    charts.append(el);
    phaseChart(el, { title: `${key.split("_")[0]} angle (deg), stride mean`, yLabel: "deg", x, lines: [
      { label: `reference: ${referenceLabel(t)}`, values: pv.reference_curves[key], color: "#222222" },
      { label: "this table", values: t.mean_curves[key] || x.map(() => null), color: "#1f4e99" },
      { label: "FSMIC", values: f.mean_curves[key] || x.map(() => null), color: "#E69F00", dash: [6, 3] }] });
  }
}
