// Live monitoring of a device: status, safe mode, walking session start/stop, telemetry charts, the 3D view.
import { del, get, post, put, token } from "../api.js";
import { app, onLeave } from "../state.js";
import { liveChart } from "../widgets/charts.js";
import { liveTarget } from "../widgets/live_target.js";
import { legView } from "../widgets/leg_view.js";
import { adaptivePanel } from "../widgets/adaptive_panel.js";
import { calibrationPanel } from "../widgets/calibration_panel.js";
import { headline, offTable } from "../widgets/session_views.js";
import { bodyWeightN, chip, confirmDialog, fmt, FSM_STATES, h, modeWords, notice, table, tableName, when } from "../ui.js";

// the device's fault flags (DEVICE_HEALTH), as the leg reports them, in a prosthetist's words
const FAULT_WORDS = {
  heartbeat_lost: "lost contact with this server",
  table_refused: "refused the last table sent",
  malformed_frame: "received a damaged message",
  no_table: "holds no table",
  over_temperature: "too hot",
  receive_error: "aborted a transfer after an internal fault (still runs its previous table)",
  control_error: "control fault: went to safe mode",
};

const canCommandOf = () => app.me.role === "prosthetist";

// what the simulated patient is doing, beside "live"
const BENCH_WORDS = { walking: " · the simulated patient walks", standing: " · the patient stands (quiet stance between walks)" };

// In a recording, what the patient does now: a course ends and the patient stands while the session still records
function walkState(status) {
  const el = document.getElementById("walk-state");
  if (!el || status.recording_session_id === null || status.bench_state === null || status.bench_state === undefined) return;
  const safe = status.safe_mode ? " — and the leg is in SAFE MODE: passive, it holds the loaded knee against bending and lets it straighten; its table does not run" : "";
  const leg = status.bench_leg && status.bench_state !== "not_worn" ? ` (the simulated leg: “${status.bench_leg}”)` : "";
  const text = (status.bench_state === "walking" ? (status.bench_task?.course ? `walking the “${status.bench_task.course}” course`
    : "walking") : status.bench_state === "standing" ? "the walk has ended and the patient stands: the session still "
      + "records (standing adds no strides); stop it to summarise" : "nobody wears the leg") + leg + safe;
  if (el.dataset.text === text) return;
  el.dataset.text = text;
  const what = status.bench_state === "walking" ? "walking" : status.bench_state === "standing" ? "standing" : "not worn";
  el.replaceChildren(chip(status.safe_mode ? `${what} · SAFE MODE` : what,
    status.safe_mode ? "bad" : status.bench_state === "walking" ? "ok" : "warn"), ` ${text}`);
}

export async function monitorPage(view, deviceId, params) {
  const [device, patients] = await Promise.all([get(`/api/devices/${deviceId}`), get("/api/patients")]);
  const canCommand = app.me.role === "prosthetist";
  const statusBox = h("div", { id: "device-status", "aria-live": "polite" });
  const readout = h("dl", { class: "readout", id: "readout" });
  const sessionBox = h("section", { class: "card", id: "session" }, h("h2", {}, "Walking session"),
    h("p", { class: "muted" }, "Reading the leg's sessions…"));   // never an empty card while the API answers
  const adaptiveBox = h("section", { class: "card", id: "adaptive", hidden: true });
  // a real leg's guided calibration (the simulated leg has no sensors to calibrate), for the prosthetist
  const calibrationBox = h("section", { class: "card", id: "calibration", hidden: true });
  const viewerBox = h("figure", { class: "viewer", id: "viewer3d" });
  // viser's 3D scene: only where the server was started with --viewer3d (viser has no login); WebGL, so it opens
  // on request (and the choice is remembered)
  const viewerToggle = h("details", { id: "viewer3d-toggle", open: localStorage.getItem("quasitune.show3d") === "1" },
    h("summary", {}, "3D view of the leg (viser, engineering bench only)"), viewerBox);
  const legFigure = h("figure", { class: "leg-view", id: "leg-view" });
  const charts = h("div", { class: "three" });
  // Safe mode and Stop stay in reach beside the charts: a bar that sticks to the top of the window while they scroll
  const actions = h("div", { class: "monitor-actions", id: "monitor-actions" },
    h("span", { id: "telemetry-state", "aria-live": "polite" }, chip("waiting for data…", "warn")),
    h("span", { class: "spacer" }),
    h("span", { id: "stop-slot" }),
    canCommand ? h("button", { class: "danger", id: "enter-safe", onclick: () => command("enter_safe_mode") }, "Enter safe mode") : null,
    canCommand ? h("button", { class: "secondary", id: "leave-safe", onclick: () => command("leave_safe_mode") }, "Leave safe mode") : null);
  view.replaceChildren(
    h("p", { class: "crumbs" }, h("a", { href: "#/patients" }, "Patients"), " / live monitor"),
    h("h1", {}, `Live monitor · ${deviceId}`),
    actions,
    h("section", { class: "card" }, h("h2", {}, "Device"), statusBox),
    calibrationBox, adaptiveBox, sessionBox,
    h("section", { class: "card" }, h("h2", {}, "Telemetry (last 5 s, 100 Hz)"),
      h("div", { class: "readout-row" }, legFigure, readout), charts),
    h("section", { class: "card" }, viewerToggle));

  const leg = legView(legFigure);
  const figs = [0, 1, 2].map(() => h("figure", { class: "chart" }));
  charts.append(...figs);
  const angle = liveChart(figs[0], { title: "joint angles (deg): measured, and the target at the leg's task (dashed)", yLabel: "deg",
    lines: [{ label: "knee (flexion +)", color: "#0072B2" }, { label: "ankle (dorsiflexion +)", color: "#D55E00" },
      { label: "knee target: the reference at the leg's task", color: "#0072B2", dash: true },
      { label: "ankle target", color: "#D55E00", dash: true }] });
  const target = liveTarget();
  const targetNote = h("p", { class: "muted small", id: "target-note" }, "Target: waiting for the leg's task and a full stride.");
  figs[0].append(targetNote);
  const torque = liveChart(figs[1], { title: "joint torques (N·m)", yLabel: "N·m",
    lines: [{ label: "knee", color: "#0072B2" }, { label: "ankle", color: "#D55E00" }] });
  const fsm = liveChart(figs[2], { title: "FSM state and pylon load", yLabel: "state / load (kN)",
    lines: [{ label: "FSM state (0 SF, 1 SE, 2 WF, 3 WE)", color: "#009E73" }, { label: "pylon load (kN, compression +)", color: "#555555" }],
    yRange: [-0.2, 3.2] });

  renderStatus(statusBox, device);
  const calibration = canCommand ? calibrationPanel(calibrationBox, deviceId) : null;
  const showCalibration = (d) => {
    calibrationBox.hidden = !calibration || !d.leg;
    calibration?.update(d);
  };
  showCalibration(device);
  await renderSession(sessionBox, deviceId, patients, params);
  recordingChip(device);
  let status = device;
  // an envelope on the leg: its map with the leg's estimated task, the values it runs, its state
  let panel = null, panelFor = null;
  const showAdaptive = async (d) => {
    const envelopeId = d.active_table?.kind === "envelope" ? d.active_table.envelope_id : null;
    if (envelopeId === panelFor) return;
    panelFor = envelopeId;
    panel = null;
    adaptiveBox.hidden = envelopeId === null;
    if (envelopeId === null) return;
    const e = await get(`/api/envelopes/${envelopeId}`);
    if (panelFor === envelopeId) panel = adaptivePanel(adaptiveBox, e);
  };
  await showAdaptive(device);

  // telemetry over the WebSocket; charts redraw once per animation frame
  const ws = new WebSocket(`${location.protocol === "https:" ? "wss" : "ws"}://${location.host}/api/devices/${deviceId}/telemetry?token=${token()}`);
  const stats = { samples: 0, frames: 0, since: performance.now(), lastSeq: null, gaps: 0 };
  app.monitor = stats;
  let t0 = null;
  let latest = null;
  ws.onmessage = (ev) => {
    const m = JSON.parse(ev.data);
    if (m.type === "status") {
      status = m;
      renderStatus(statusBox, m);
      showCalibration(m);
      recordingChip(m);
      showAdaptive(m);
      return;
    }
    if (stats.lastSeq !== null && m.seq !== stats.lastSeq + 1) stats.gaps += 1;
    stats.lastSeq = m.seq;
    stats.samples += 1;
    t0 ??= m.received_unix_s;
    const t = m.received_unix_s - t0;
    target.follow(status, m);
    const [kneeTarget, ankleTarget] = target.at(t, m.fsm_state);
    if (kneeTarget !== null) stats.targets = (stats.targets ?? 0) + 1;
    angle.push(t, [m.knee_angle_deg, m.ankle_angle_deg, kneeTarget, ankleTarget]);
    torque.push(t, [m.knee_torque_Nm, m.ankle_torque_Nm]);
    fsm.push(t, [m.fsm_state, m.load_N / 1000]);
    latest = m;
    lastSampleAt = performance.now();
  };
  // Live whenever the leg sends samples, with or without a session; "no data" (and why) when it sends none
  let lastSampleAt = null;
  const stateLine = document.getElementById("telemetry-state");
  const showDataState = () => {
    const fresh = lastSampleAt !== null && performance.now() - lastSampleAt < NO_DATA_AFTER_MS;
    const why = !status.online ? "the device is offline"
      : status.bench_state === "not_worn" ? "nobody wears the simulated leg (assign it to a patient: they stand on it between walks)"
        : "the leg sends no sensor samples";
    const what = BENCH_WORDS[status.bench_state] ?? "";
    const text = fresh ? `live${what}` : `no data: ${why}`;
    if (stateLine.dataset.text !== text) {
      stateLine.dataset.text = text;
      stateLine.replaceChildren(chip(fresh ? "live" : "no data", fresh ? "ok" : "warn"),
        fresh ? ` samples from ${deviceId}${what}` : ` ${why}; the charts hold the last data received.`);
    }
    walkState(status);
  };
  showDataState();
  const dataTimer = setInterval(showDataState, 250);
  ws.onclose = (ev) => { if (ev.code === 1008) notice(`Telemetry refused: ${ev.reason}`); };
  let raf = 0;
  const frame = () => {
    if (angle.draw() | torque.draw() | fsm.draw()) {
      stats.frames += 1;
      const dt = (performance.now() - stats.since) / 1000;
      stats.fps = stats.frames / dt;
      if (latest) {
        const weightN = bodyWeightN(status.patient?.body_mass_kg);
        renderReadout(readout, latest, stats, weightN);
        const words = target.state.task ? `Target: ${target.state.label ?? "no measured reference at this task"} `
          + `(${target.state.task.speed_mps.toFixed(2)} m/s, ${target.state.task.incline_deg.toFixed(1)}°), placed in each stride from `
          + "the last heel strike and the last stride's duration; none while standing." : targetNote.textContent;
        if (targetNote.textContent !== words) targetNote.textContent = words;
        leg.draw(latest, weightN);
        panel?.update(latest, status);
      }
    }
    raf = requestAnimationFrame(frame);
  };
  raf = requestAnimationFrame(frame);
  onLeave(() => { cancelAnimationFrame(raf); clearInterval(dataTimer); ws.close(); });

  const show3d = async () => {
    localStorage.setItem("quasitune.show3d", viewerToggle.open ? "1" : "0");
    if (!viewerToggle.open) {
      viewerBox.replaceChildren();
      return;
    }
    viewerBox.replaceChildren(h("figcaption", { class: "muted" }, "Starting the 3D view…"));
    try {
      const v = await get(`/api/devices/${deviceId}/viewer`);
      viewerBox.replaceChildren(h("iframe", { src: v.url, title: `3D view of ${deviceId}` }),
        h("figcaption", { class: "muted small" }, `viser on ${v.host}:${v.port} (loopback, no login: anyone on the `,
          "server machine can watch it). Thigh drawn upright: the device measures knee and ankle only. Foot colour: ",
          "pylon load (grey unloaded → orange at body weight)."));
    } catch (err) {
      viewerBox.replaceChildren(h("p", { class: err.status === 409 ? "muted" : "error", id: "viewer3d-off" },
        err.status === 409 ? err.message : `3D view unavailable: ${err.message}`));
    }
  };
  viewerToggle.addEventListener("toggle", show3d);
  if (viewerToggle.open) show3d();

  async function command(name) {
    if (name === "leave_safe_mode") {   // the table runs again under the patient: asked, never one stray click
      const ok = await confirmDialog({ id: "leave-safe-dialog", title: `Leave safe mode on ${deviceId}?`,
        facts: [["On the leg", tableName(status.active_table, true)],
          ["What changes", "the leg leaves its passive safe mode and runs this table again from the next heel strike"]],
        requires: "The patient is seated or standing in the parallel bars.", confirm: "Leave safe mode" });
      if (!ok) return;
    }
    try {
      const answer = await post(`/api/devices/${deviceId}/commands`, { command: name });
      // the device's own status stream is the truth: a reply made before the device answered must not undo it
      if ((answer.last_heartbeat_unix_s ?? 0) >= (status.last_heartbeat_unix_s ?? 0)) {
        status = answer;
        renderStatus(statusBox, status);
      }
      // a change of what the leg does is a caution, never a green "done"
      notice(name === "enter_safe_mode" ? "Safe mode requested: the leg goes passive (it holds the loaded knee against bending); the table does not run."
        : "Leaving safe mode: the leg runs its table again from the next heel strike.", "warn");
    } catch (err) {
      notice(err.message);
    }
  }
}

const NO_DATA_AFTER_MS = 1000;

function renderStatus(box, d) {
  // the safe-mode buttons only when they would change something
  const enter = document.getElementById("enter-safe"), leave = document.getElementById("leave-safe");
  if (enter) {
    enter.disabled = !d.online || d.safe_mode;
    enter.title = !d.online ? "the device is offline" : d.safe_mode ? "already in safe mode" : "";
  }
  if (leave) {
    const withdrawn = d.withdrawal_notice?.state === "runs_withdrawn";
    leave.disabled = !d.online || !d.safe_mode || withdrawn;
    leave.title = !d.online ? "the device is offline" : withdrawn ? "the leg holds a withdrawn version: push another first"
      : d.safe_mode ? "" : "not in safe mode";
  }
  box.replaceChildren(h("p", { class: "chips" },
    d.kind === "simulated" ? h("span", { id: "simulated-chip" }, chip("SIMULATED leg and patient", "warn")) : "",
    chip(d.online ? "online" : "offline", d.online ? "ok" : "bad"),
    chip(d.safe_mode ? "SAFE MODE" : modeWords(d.mode), d.safe_mode ? "bad" : d.mode === "active" ? "ok" : "warn"),
    d.faults.length ? chip(`the leg reports: ${d.faults.map((f) => FAULT_WORDS[f] || f).join("; ")}`, "bad") : null),
  ...(d.withdrawal_notice ? [h("p", { id: "withdrawal-notice", class: `banner ${d.withdrawal_notice.state === "runs_withdrawn" ? "bad" : "warn"}` },
    h("strong", {}, d.withdrawal_notice.state === "runs_withdrawn" ? "Withdrawn version on the leg: " : "Sent back: "),
    d.withdrawal_notice.words)] : []),
  h("dl", { class: "facts" },
    h("dt", {}, "Worn by"), h("dd", { id: "device-patient" }, d.patient ? `${d.patient.patient_code} (${fmt(d.patient.body_mass_kg, 0, "kg")})` : "nobody (not assigned)"),
    h("dt", {}, "On the leg"), h("dd", { id: "active-version" }, d.active_version === null ? "none"
      : d.active_table ? tableName(d.active_table, true) : `device version ${d.active_version} (not sent by this server)`,
      d.body_mass_mismatch ? h("span", { id: "mass-mismatch" }, " ", chip(d.body_mass_mismatch.message, "warn")) : null,
      d.active_table?.approval_override ? h("span", { id: "approval-override" }, " ",
        chip(`approved without a clean bench preview, signed off by ${d.active_table.approval_override}`, "warn")) : null,
      d.active_table?.extrapolation_reason ? h("span", { id: "extrapolated" }, " ",
        chip(`extrapolated beyond the data: “${d.active_table.extrapolation_reason}”`, "bad")) : null,
      d.active_table?.override_reason ? h("span", { id: "push-override" }, " ",
        chip(`pushed without a clean bench preview: “${d.active_table.override_reason}”`, "warn")) : null),
    h("dt", {}, "CRC-32 read back"), h("dd", { class: "mono" }, d.active_crc32 || "—"),
    h("dt", {}, "Waiting for heel strike"), h("dd", {}, d.pending_version === null ? "—"
      : d.pending_table ? tableName(d.pending_table) : `device version ${d.pending_version}`),
    h("dt", {}, "FSM state"), h("dd", {}, d.fsm_state === null ? "—" : FSM_STATES[d.fsm_state]),
    h("dt", {}, "Last heartbeat"), h("dd", { id: "heartbeat" }, d.last_heartbeat_age_s === null ? "never" : `${fmt(d.last_heartbeat_age_s, 2)} s ago`),
    h("dt", {}, "Samples reaching this server"), h("dd", { id: "stream" }, ...streamWords(d)),
    h("dt", {}, "Temperature"), h("dd", {}, d.temperature_degC === null ? "not measured" : fmt(d.temperature_degC, 1, "°C")),
    h("dt", {}, "The leg's hardware"), h("dd", { id: "leg-hardware" }, ...legWords(d.leg)),
    h("dt", {}, "If the link is lost"), h("dd", { id: "link-mode" }, ...linkModeWords(d))));
}

// What a real leg says of itself (DEVICE_LEG): which sensors are calibrated, who runs the impedance, thermal derating
function legWords(leg) {
  if (!leg) return ["the simulated leg (no sensors to calibrate)"];
  const parts = [["knee", leg.knee_calibrated], ["ankle", leg.ankle_calibrated], ["load cell", leg.loadcell_calibrated]];
  const missing = parts.filter(([, ok]) => !ok).map(([name]) => name);
  return ["Open Source Leg · ", missing.length ? chip(`not calibrated: ${missing.join(", ")}`, "bad") : chip("calibrated", "ok"),
    ` · ${leg.torque_mode === "actuator_impedance" ? "the actuators run each phase's spring and damper" : "QuasiTune computes every torque"}`,
    leg.derating_pct === null ? "" : ` · torque allowed by the thermal model: ${leg.derating_pct} %`];
}

// The leg's live samples as this server received them: how many since it connected, and whether any were missed
// (by the leg's own sequence numbers; samples the bridge delivers late fill a session's record afterwards)
function streamWords(d) {
  const got = `${d.telemetry_samples_received.toLocaleString("en")} since this server connected`;
  return d.telemetry_samples_missing === 0 ? [`${got}, none missed`]
    : [`${got}, `, chip(`${d.telemetry_samples_missing.toLocaleString("en")} missed on the way`, "warn")];
}

// What a lost link does to this leg: the prosthetist's choice, what the leg reports it does, and the way to change it
const LINK_WORDS = {
  supervised: "supervised: the leg goes to its passive safe mode (tuning in the clinic)",
  autonomous: "autonomous: the leg runs on with its approved table or envelope (daily life)",
};

function linkModeWords(d) {
  const other = d.link_mode === "supervised" ? "autonomous" : "supervised";
  const told = d.link_mode_on_device === d.link_mode ? null
    : chip(d.online ? "being sent to the leg…" : "the leg is told when it next reports", "warn");
  const change = canCommandOf() ? h("button", { class: "secondary", id: "link-mode-change",
    onclick: () => changeLinkMode(d.id, other) }, other === "autonomous" ? "Make autonomous…" : "Make supervised…") : null;
  return [LINK_WORDS[d.link_mode], told ? " " : null, told, change ? " " : null, change];
}

async function changeLinkMode(deviceId, mode) {
  const reason = await confirmDialog({ id: "link-mode-dialog", title: `${deviceId}: ${mode} when the link is lost?`,
    facts: [["From now on", LINK_WORDS[mode]], ["Recorded", "in the audit log, with your reason"]],
    reason: { label: "Why", min: 10 }, confirm: `Make ${mode}`, danger: mode === "autonomous" });
  if (!reason) return;
  try {
    await put(`/api/devices/${deviceId}/link-mode`, { link_mode: mode, reason });
    notice(`Lost-link mode ${mode}: the leg reports it in its next status.`, "warn");
  } catch (err) {
    notice(err.message);
  }
}

// While recording, the chip says whether the strides count: in safe mode (or without a table) the leg does not run
// the table, and those strides are left out of the session's errors.
function recordingChip(d) {
  const el = document.getElementById("recording-chip");
  if (!el) return;
  el.replaceChildren(d.mode === "active" ? chip("recording", "ok")
    : chip(`recording — leg ${d.safe_mode ? "in SAFE MODE" : "without a table"}: these strides are not scored`, "bad"));
}

function renderReadout(box, m, stats, weightN) {
  // each label with its value in one cell (a dl may group its pairs in divs), so they stay aligned at any width
  const item = (label, value, id) => [h("div", { class: "readout-item" }, h("dt", {}, label), h("dd", { id }, value))];
  box.replaceChildren(
    ...item("Knee angle (flexion +)", fmt(m.knee_angle_deg, 1, "deg"), "knee-angle"),
    ...item("Knee torque (flexor +)", fmt(m.knee_torque_Nm, 1, "N·m"), "knee-torque"),
    ...item("Ankle angle (dorsiflexion +)", fmt(m.ankle_angle_deg, 1, "deg"), "ankle-angle"),
    ...item("Ankle torque (dorsiflexor +)", fmt(m.ankle_torque_Nm, 1, "N·m"), "ankle-torque"),
    ...item("Pylon load (compression +)", weightN ? `${fmt(m.load_N, 0, "N")} (${fmt(100 * m.load_N / weightN, 0)} % body weight)`
      : fmt(m.load_N, 0, "N"), "load"),
    ...item("Mode", modeWords(m.mode), "sample-mode"),
    ...item("FSM state", m.fsm_state === null ? "—" : FSM_STATES[m.fsm_state], "fsm-state"),
    ...item("The leg is", m.mode === "active" && m.leg_behaviour ? m.leg_behaviour : "—", "leg-behaviour"),
    ...item("Drawn", `${fmt(stats.fps, 0)} frames/s · ${stats.samples} samples · ${stats.gaps} gaps`, "fps"));
}

async function renderSession(box, deviceId, patients, params) {
  const device = await get(`/api/devices/${deviceId}`);
  box.replaceChildren(h("h2", {}, "Walking session"));
  const error = h("p", { class: "error", role: "alert" });
  if (device.recording_session_id !== null) {
    const s = await get(`/api/sessions/${device.recording_session_id}`);
    const stop = h("button", { id: "stop-session" }, "Stop and summarise");
    stop.addEventListener("click", async () => {
      const ok = await confirmDialog({ id: "stop-dialog", title: `Stop recording session #${s.id}?`,
        facts: [["Patient", s.patient_code], ["Started", when(s.started_at)]], confirm: "Stop and summarise" });
      if (!ok) return;
      try {
        const done = await post(`/api/sessions/${s.id}/stop`);
        notice(`Session #${done.id} stopped: ${done.summary.strides} strides`, "ok");
        await renderSession(box, deviceId, patients, params);
        box.append(summaryTable(done));
      } catch (err) {
        error.textContent = err.message;
      }
    });
    box.append(h("p", {}, h("span", { id: "recording-chip" }, chip("recording", "ok")), ` session #${s.id} since ${when(s.started_at)} `,
      s.course ? `walking the “${s.course}” course, ` : `at ${fmt(s.task.speed_mps, 2, "m/s")}, incline ${fmt(s.task.incline_deg, 1, "°")}, `,
      `for ${s.patient_code}, running ${s.table_label ?? "no table from this server"}`),
      h("p", { id: "walk-state", "aria-live": "polite" }),
      ...(canCommandOf() ? [] : [h("p", { class: "muted", id: "stop-session-note" }, "Only a prosthetist stops a recording.")]),
      error);
    document.getElementById("stop-slot")?.replaceChildren(canCommandOf() ? stop : "");   // in the bar beside the charts
    return;
  }
  document.getElementById("stop-slot")?.replaceChildren();
  box.append(assignment(box, device, patients, deviceId, params));
  if (!device.patient) {
    box.append(error);
    return;
  }
  if (!canCommandOf()) {   // starting sets the simulated patient walking: the prosthetist's, as stopping is
    box.append(h("p", { class: "muted", id: "session-start-note" }, "No session is recording. A prosthetist starts one."));
    return;
  }
  const speed = h("input", { type: "number", name: "speed", min: 0.1, max: 3, step: 0.01, placeholder: "from the active table",
    "aria-label": "Speed (m/s), empty = the active table's task" });
  // the simulated patient can walk one task, or a course whose speed and incline change (to watch a leg adapt)
  const walk = device.kind === "simulated" ? h("select", { id: "session-walk", "aria-label": "What the simulated patient walks" },
    h("option", { value: "" }, "one task"),
    h("option", { value: "mixed" }, "course: speed changes, ramps up and down (92 s)"),
    h("option", { value: "terrain" }, "course: level, ramp up +8°, level, ramp down −8° (58 s)"),
    h("option", { value: "speed" }, "course: speed 1.0 → 0.85 → 1.6 → 1.0 m/s (46 s)")) : null;
  walk?.addEventListener("change", () => { speed.disabled = Boolean(walk.value); });
  const start = h("button", { id: "start-session" }, `Start session for ${device.patient.patient_code}`);
  start.addEventListener("click", async () => {
    error.textContent = "";
    const body = { device_id: deviceId };
    if (walk?.value) body.course = walk.value;
    else if (speed.value) body.speed_mps = Number(speed.value);
    try {
      await post(`/api/patients/${device.patient.patient_id}/sessions`, body);
      await renderSession(box, deviceId, patients, params);
    } catch (err) {
      error.textContent = err.message;
    }
  });
  box.append(h("div", { class: "inline" }, walk ? h("label", {}, "Walk ", walk) : null, h("label", {}, "Speed (m/s) ", speed), start), error);
}

// Who wears the device: sessions and pushes follow it, so it is changed deliberately (prosthetist, confirmed)
function assignment(box, device, patients, deviceId, params) {
  const who = device.patient ? `${device.patient.patient_code} (${fmt(device.patient.body_mass_kg, 0, "kg")})` : null;
  const out = h("div", { id: "assignment" }, h("p", {}, who ? ["Worn by ", h("strong", {}, who),
    `, assigned by ${device.patient.assigned_by} ${when(device.patient.assigned_at)}.`]
    : chip("not assigned: no session can be recorded and no table pushed until a patient is assigned", "warn")));
  if (app.me.role !== "prosthetist" || !patients.length) return out;
  const wanted = params.get("patient");
  const pick = h("select", { id: "assign-patient", "aria-label": "Patient wearing the device" },
    patients.map((p) => h("option", { value: p.id, selected: String(p.id) === wanted || (!wanted && p.id === device.patient?.patient_id) },
      `${p.code_name} (${fmt(p.body_mass_kg, 0, "kg")})`)));
  const change = h("button", { id: "assign-button", class: "secondary" }, device.patient ? "Change patient…" : "Assign…");
  change.addEventListener("click", async () => {
    const p = patients.find((x) => String(x.id) === pick.value);
    const ok = await confirmDialog({ id: "assign-dialog", title: `${deviceId} worn by ${p.code_name}?`,
      facts: [["Worn now by", who || "nobody"], ["Will be worn by", `${p.code_name} (${fmt(p.body_mass_kg, 0, "kg")})`],
        ["Table on the leg", tableName(device.active_table, true)],
        ["Then", device.active_table && device.active_table.patient_id !== p.id
          ? `push one of ${p.code_name}'s approved tables before recording` : "sessions record this patient"]],
      confirm: "Assign" });
    if (!ok) return;
    try {
      await put(`/api/devices/${deviceId}/assignment`, { patient_id: p.id });
      await renderSession(box, deviceId, patients, params);
      window.dispatchEvent(new CustomEvent("quasitune:device-changed"));
    } catch (err) {
      notice(err.message);
    }
  });
  const clear = device.patient ? h("button", { id: "unassign-button", class: "secondary", onclick: async () => {
    try {
      await del(`/api/devices/${deviceId}/assignment`);
      await renderSession(box, deviceId, patients, params);
    } catch (err) {
      notice(err.message);
    }
  } }, "Taken off") : null;
  out.append(h("div", { class: "inline" }, h("label", {}, "Patient ", pick), change, clear));
  return out;
}

function summaryTable(s) {
  const m = s.summary;
  return h("div", { id: "session-summary" },
    offTable(m),
    headline(m.headline),
    table(["Strides on the table / counted", "Cadence on the table (steps/min)", "Missing samples"],
      [h("tr", {}, h("td", { class: "num" }, `${m.strides_scored ?? m.strides} / ${m.strides}`), h("td", { class: "num" }, fmt(m.cadence_steps_per_min, 1)),
        h("td", { class: "num" }, m.missing_samples))]),
    h("p", {}, h("a", { href: `#/sessions/${s.id}/report`, id: "report-link" }, "Open the session report")));
}

