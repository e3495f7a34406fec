// Live monitoring of a device: status, safe mode, walking session start/stop, telemetry charts, the 3D view.
import { get, post, token } from "../api.js";
import { app, onLeave } from "../main.js";
import { liveChart } from "../charts.js";
import { chip, fmt, FSM_STATES, h, notice, table, when } from "../ui.js";

export async function monitorPage(view, deviceId, params) {
  const [device, patients] = await Promise.all([get(`/api/devices/${deviceId}`), get("/api/patients")]);
  const canCommand = app.me.role === "prosthetist";
  const statusBox = h("div", { id: "device-status", "aria-live": "polite" });
  const readout = h("dl", { class: "readout", id: "readout" });
  const sessionBox = h("section", { class: "card", id: "session" });
  const viewerBox = h("figure", { class: "viewer", id: "viewer3d" });
  // The 3D scene is WebGL: on a machine without a GPU it is rendered in software and costs the charts their
  // frame rate, so it opens on request (and the choice is remembered).
  const viewerToggle = h("details", { id: "viewer3d-toggle", open: localStorage.getItem("quasitune.show3d") === "1" },
    h("summary", {}, "3D view of the leg (viser, WebGL)"), viewerBox);
  const charts = h("div", { class: "three" });
  view.replaceChildren(
    h("p", { class: "crumbs" }, h("a", { href: "#/patients" }, "Patients"), " / live monitor"),
    h("h1", {}, `Live monitor · ${deviceId}`),
    h("section", { class: "card" }, h("h2", {}, "Device"), statusBox,
      canCommand ? h("div", { class: "inline" },
        h("button", { class: "danger", id: "enter-safe", onclick: () => command("enter_safe_mode") }, "Enter safe mode"),
        h("button", { class: "secondary", id: "leave-safe", onclick: () => command("leave_safe_mode") }, "Leave safe mode")) : null),
    sessionBox,
    h("section", { class: "card" }, h("h2", {}, "Telemetry (last 5 s, 100 Hz)"), readout, charts),
    h("section", { class: "card" }, viewerToggle));

  const figs = [0, 1, 2].map(() => h("figure", { class: "chart" }));
  charts.append(...figs);
  const angle = liveChart(figs[0], { title: "joint angles (deg)", yLabel: "deg",
    lines: [{ label: "knee (flexion +)", color: "#0072B2" }, { label: "ankle (dorsiflexion +)", color: "#D55E00" }] });
  const torque = liveChart(figs[1], { title: "joint torques (N·m)", yLabel: "N·m",
    lines: [{ label: "knee", color: "#0072B2" }, { label: "ankle", color: "#D55E00" }] });
  const fsm = liveChart(figs[2], { title: "FSM state and pylon load", yLabel: "state / load (kN)",
    lines: [{ label: "FSM state (0 SF, 1 SE, 2 WF, 3 WE)", color: "#009E73" }, { label: "load (kN)", color: "#555555" }],
    yRange: [-0.2, 3.2] });

  renderStatus(statusBox, device);
  await renderSession(sessionBox, deviceId, patients, params);

  // telemetry over the WebSocket; charts redraw once per animation frame
  const ws = new WebSocket(`${location.protocol === "https:" ? "wss" : "ws"}://${location.host}/api/devices/${deviceId}/telemetry?token=${token()}`);
  const stats = { samples: 0, frames: 0, since: performance.now(), lastSeq: null, gaps: 0 };
  app.monitor = stats;
  let t0 = null;
  let latest = null;
  ws.onmessage = (ev) => {
    const m = JSON.parse(ev.data);
    if (m.type === "status") {
      renderStatus(statusBox, m);
      return;
    }
    if (stats.lastSeq !== null && m.seq !== stats.lastSeq + 1) stats.gaps += 1;
    stats.lastSeq = m.seq;
    stats.samples += 1;
    t0 ??= m.received_unix_s;
    const t = m.received_unix_s - t0;
    angle.push(t, [m.knee_angle_deg, m.ankle_angle_deg]);
    torque.push(t, [m.knee_torque_Nm, m.ankle_torque_Nm]);
    fsm.push(t, [m.fsm_state, m.load_N / 1000]);
    latest = m;
  };
  ws.onclose = (ev) => { if (ev.code === 1008) notice(`Telemetry refused: ${ev.reason}`); };
  let raf = 0;
  const frame = () => {
    if (angle.draw() | torque.draw() | fsm.draw()) {
      stats.frames += 1;
      const dt = (performance.now() - stats.since) / 1000;
      stats.fps = stats.frames / dt;
      if (latest) renderReadout(readout, latest, stats);
    }
    raf = requestAnimationFrame(frame);
  };
  raf = requestAnimationFrame(frame);
  onLeave(() => { cancelAnimationFrame(raf); ws.close(); });

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
        h("figcaption", { class: "muted small" }, `viser on ${v.host}:${v.port} (loopback). Thigh drawn upright: the `,
          "device measures knee and ankle only. Foot colour: pylon load (grey unloaded → orange at body weight)."));
    } catch (err) {
      viewerBox.replaceChildren(h("p", { class: "error" }, `3D view unavailable: ${err.message}`));
    }
  };
  viewerToggle.addEventListener("toggle", show3d);
  if (viewerToggle.open) show3d();

  async function command(name) {
    try {
      renderStatus(statusBox, await post(`/api/devices/${deviceId}/commands`, { command: name }));
      notice(`${name.replaceAll("_", " ")} sent`, "ok");
    } catch (err) {
      notice(err.message);
    }
  }
}

function renderStatus(box, d) {
  box.replaceChildren(h("p", { class: "chips" },
    chip(d.online ? "online" : "offline", d.online ? "ok" : "bad"),
    chip(d.safe_mode ? "SAFE MODE" : `mode: ${d.mode || "—"}`, d.safe_mode ? "bad" : "ok"),
    d.faults.length ? chip(`faults: ${d.faults.join(", ")}`, "bad") : null),
  h("dl", { class: "facts" },
    h("dt", {}, "Active table"), h("dd", { id: "active-version" }, d.active_version === null ? "none" : `version ${d.active_version}`),
    h("dt", {}, "CRC-32 read back"), h("dd", { class: "mono" }, d.active_crc32 || "—"),
    h("dt", {}, "Waiting for heel strike"), h("dd", {}, d.pending_version === null ? "—" : `version ${d.pending_version}`),
    h("dt", {}, "FSM state"), h("dd", {}, d.fsm_state === null ? "—" : FSM_STATES[d.fsm_state]),
    h("dt", {}, "Last heartbeat"), h("dd", { id: "heartbeat" }, d.last_heartbeat_age_s === null ? "never" : `${fmt(d.last_heartbeat_age_s, 2)} s ago`),
    h("dt", {}, "Temperature"), h("dd", {}, d.temperature_degC === null ? "not measured" : fmt(d.temperature_degC, 1, "°C"))));
}

function renderReadout(box, m, stats) {
  const item = (label, value, id) => [h("dt", {}, label), h("dd", { id }, value)];
  box.replaceChildren(
    ...item("Knee angle", fmt(m.knee_angle_deg, 1, "deg"), "knee-angle"),
    ...item("Knee torque", fmt(m.knee_torque_Nm, 1, "N·m"), "knee-torque"),
    ...item("Ankle angle", fmt(m.ankle_angle_deg, 1, "deg"), "ankle-angle"),
    ...item("Ankle torque", fmt(m.ankle_torque_Nm, 1, "N·m"), "ankle-torque"),
    ...item("Load", fmt(m.load_N, 0, "N"), "load"),
    ...item("FSM state", m.fsm_state === null ? "—" : FSM_STATES[m.fsm_state], "fsm-state"),
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
      try {
        const done = await post(`/api/sessions/${s.id}/stop`);
        notice(`Session #${done.id} stopped: ${done.summary.strides} strides`, "ok");
        await renderSession(box, deviceId, patients, params);
        box.append(summaryTable(done));
      } catch (err) {
        error.textContent = err.message;
      }
    });
    box.append(h("p", {}, chip("recording", "ok"), ` session #${s.id} since ${when(s.started_at)} at ${fmt(s.task.speed_mps, 2, "m/s")}, `,
      `incline ${fmt(s.task.incline_deg, 1, "°")}, table ${s.table_version ?? "none"}`), stop, error);
    return;
  }
  const wanted = params.get("patient");
  const patient = h("select", { name: "patient", id: "session-patient", "aria-label": "Patient" },
    patients.map((p) => h("option", { value: p.id, selected: String(p.id) === wanted }, p.code_name)));
  const speed = h("input", { type: "number", name: "speed", min: 0.1, max: 3, step: 0.01, placeholder: "from the active table",
    "aria-label": "Speed (m/s), empty = the active table's task" });
  const start = h("button", { id: "start-session" }, "Start session");
  start.addEventListener("click", async () => {
    error.textContent = "";
    const body = { device_id: deviceId };
    if (speed.value) body.speed_mps = Number(speed.value);
    try {
      await post(`/api/patients/${patient.value}/sessions`, body);
      await renderSession(box, deviceId, patients, params);
    } catch (err) {
      error.textContent = err.message;
    }
  });
  box.append(patients.length ? h("div", { class: "inline" }, h("label", {}, "Patient ", patient),
    h("label", {}, "Speed (m/s) ", speed), start) : h("p", { class: "muted" }, "Create a patient first."), error);
}

function summaryTable(s) {
  const m = s.summary;
  return h("div", { id: "session-summary" },
    table(["Strides", "Cadence (steps/min)", "Knee angle RMSE (deg)", "Ankle angle RMSE (deg)", "Missing samples"],
      [h("tr", {}, h("td", { class: "num" }, m.strides), h("td", { class: "num" }, fmt(m.cadence_steps_per_min, 1)),
        h("td", { class: "num" }, fmt(m.knee_angle_rmse_deg, 1)), h("td", { class: "num" }, fmt(m.ankle_angle_rmse_deg, 1)),
        h("td", { class: "num" }, m.missing_samples))]),
    h("p", {}, h("a", { href: `#/sessions/${s.id}/report`, id: "report-link" }, "Open the session report")));
}
