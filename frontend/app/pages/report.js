// The printable session report (Print → the browser's PDF, or the server's PDF export).
import { get, post, token } from "../api.js";
import { phaseChart } from "../widgets/charts.js";
import { headline, offTable } from "../widgets/session_views.js";
import { app } from "../state.js";
import { refinementView } from "../widgets/refine_panel.js";
import { chip, fmt, h, notice, referenceLabel, table, when } from "../ui.js";

const MIN_STRIDES = 5;   // the server's (controller_core.session_regions.MIN_STRIDES_TO_JUDGE): fewer are too few to judge
const CHANNELS = [["knee_angle_deg", "knee angle (deg, flexion +)", "knee_angle_rmse_deg", "deg"],
  ["ankle_angle_deg", "ankle angle (deg, dorsiflexion +)", "ankle_angle_rmse_deg", "deg"],
  ["knee_moment_Nm_per_kg", "knee moment (N·m/kg, flexor +)", "knee_moment_rmse_Nm_per_kg", "N·m/kg"],
  ["ankle_moment_Nm_per_kg", "ankle moment (N·m/kg, dorsiflexor +)", "ankle_moment_rmse_Nm_per_kg", "N·m/kg"]];

export async function reportPage(view, id) {
  const s = await get(`/api/sessions/${id}`);
  const patient = await get(`/api/patients/${s.patient_id}`);
  const m = s.summary;
  // files through the signed-in fetch (a plain link would carry no token): the PDF, and the raw telemetry for engineers
  const download = (button, path, filename, what) => button.addEventListener("click", async () => {
    const r = await fetch(path, { headers: { Authorization: `Bearer ${token()}` } });
    if (!r.ok) {
      notice((await r.json().catch(() => ({}))).detail || `${what} failed (${r.status})`);
      return;
    }
    const url = URL.createObjectURL(await r.blob());
    const a = h("a", { href: url, download: filename });
    document.body.append(a);
    a.click();
    a.remove();
    setTimeout(() => URL.revokeObjectURL(url), 10000);
  });
  const pdf = h("button", { id: "pdf", class: "secondary" }, "Download PDF");
  download(pdf, `/api/sessions/${id}/report.pdf`, `quasitune-session-${id}.pdf`, "PDF");
  const exports = ["csv", "parquet"].map((fmtName) => {
    const b = h("button", { id: `samples-${fmtName}`, class: "secondary",
      title: "every recorded sample: time, mode, state, joint angles (deg), velocities (deg/s), torques (N·m), load (N)" },
    `Telemetry (${fmtName === "csv" ? "CSV" : "Parquet"})`);
    download(b, `/api/sessions/${id}/samples.${fmtName}`, `quasitune-session-${id}-samples.${fmtName}`, "Export");
    return b;
  });
  const head = [
    h("p", { class: "crumbs no-print" }, h("a", { href: `#/patients/${patient.id}` }, patient.code_name), " / ", `session #${id}`),
    h("h1", {}, `Session report #${id}`, s.simulated ? h("span", { id: "report-simulated" }, " ", chip("SIMULATED WALK", "bad")) : ""),
    ...(s.simulated ? [h("p", { class: "banner warn", id: "simulated-banner" }, h("strong", {}, "Simulated: "),
      "the simulated patient walked the simulated leg (the bench); no person walked this session.")] : []),
    h("div", { class: "inline no-print" }, h("button", { onclick: () => print() }, "Print"), pdf, ...exports),
    h("dl", { class: "facts", id: "report-facts" },
      h("dt", {}, "Patient"), h("dd", {}, `${patient.code_name} · ${fmt(patient.body_mass_kg, 1, "kg")} · ${patient.side}`),
      h("dt", {}, "Task"), h("dd", { id: "report-task" }, s.course ? `the bench's ${s.task_words} (speed and incline change)` : s.task_words),
      h("dt", {}, s.envelope_id !== null ? "Envelope on the leg" : "Active table"), h("dd", { id: "report-table" }, s.table_label === null ? "none from this server"
        : h("span", {}, h("a", { href: s.envelope_id !== null ? `#/envelopes/${s.envelope_id}` : `#/proposals/${s.proposal_id}` }, s.table_label),
          ` · CRC-32 ${s.table_crc32} · device version ${s.table_version}`,
          s.approval_override ? h("span", { id: "report-override" }, " ", chip(`approved without a clean bench preview, signed off by ${s.approval_override}`, "warn")) : null,
          s.extrapolation_reason ? h("span", { id: "report-extrapolated" }, " ", chip(`extrapolated beyond the data: “${s.extrapolation_reason}”`, "bad")) : null)),
      h("dt", {}, "Device"), h("dd", {}, s.device_id),
      h("dt", {}, "Recorded"), h("dd", {}, `${when(s.started_at)} → ${when(s.stopped_at)} by ${s.started_by}`)),
  ];
  if (!m) {
    view.replaceChildren(...head, h("p", { class: "muted" }, "Still recording: stop the session for its summary."));
    return;
  }
  const metrics = table(["Strides on the table / counted", "Cadence on the table (steps/min)", "Stride time on the table (s)", "Reference stride time (s)", "Samples",
    "Missing samples"], [h("tr", {}, h("td", { class: "num", id: "report-strides" }, `${m.strides_scored ?? m.strides} / ${m.strides}`),
    h("td", { class: "num", id: "report-cadence" }, fmt(m.cadence_steps_per_min, 1)), h("td", { class: "num" }, fmt(m.stride_time_s, 3)),
    h("td", { class: "num" }, fmt(m.reference_stride_time_s, 3)), h("td", { class: "num" }, m.samples),
    h("td", { class: "num" }, m.missing_samples))]);
  const standing = m.walking_s === undefined ? null : h("p", { id: "report-walking" }, `${fmt(m.walking_s, 1)} s walking (the strides) and `
    + `${fmt(m.standing_s, 1)} s standing or paused, of ${fmt(m.duration_s, 1)} s recorded.`);
  // the angles' error is the headline's (each stride at its own task), given once; the mean stride adds the moments
  const errors = s.course ? null : h("div", {}, h("h3", {}, `Moments: the mean stride against the reference at ${s.task_words}`),
    table(["Channel", "RMSE of the mean stride"], CHANNELS.filter(([, , , unit]) => unit !== "deg").map(([, label, key, unit]) =>
      h("tr", {}, h("td", {}, label), h("td", { class: "num" }, fmt(m[key], unit === "deg" ? 1 : 3, unit)))), { id: "report-errors" }));
  const charts = h("div", { class: "two", id: "report-charts" });
  view.replaceChildren(...[...head, h("h2", {}, "Strides and errors"), headline(m.headline), offTable(m), metrics, standing, errors,
    h("p", { class: "muted small", id: "report-reference" }, `Reference: ${referenceLabel(m)} (${m.reference_source})${m.reference_extrapolation ? " (extrapolated)" : ""}. `,
      "Strides between heel strikes (load above 10 % of body weight), averaged on the gait-cycle grid."),
    m.adaptive ? adaptiveSection(m.adaptive) : null,
    refineSection(s, m),
    // a course's strides are at several tasks: their mean is drawn alone, never against one task's reference
    h("h2", {}, s.course ? "Joint trajectories: the mean of the strides across the course's tasks (each stride's error "
      + "against its own task is the headline above)" : "Joint trajectories against the reference"), charts].filter(Boolean));
  const x = m.phase_grid.map((p) => p * 100);
  for (const [key, label, , unit] of CHANNELS) {
    const el = h("figure", { class: "chart" });
    charts.append(el);
    const measured = { label: s.course ? "measured (mean of the strides across tasks)" : "measured (stride mean)",
      values: m.mean_curves[key] || x.map(() => null), color: "#0072B2" };
    phaseChart(el, { title: label, yLabel: unit, x, height: 200, lines: s.course ? [measured] : [
      { label: `reference: ${referenceLabel(m)}`, values: m.reference_curves[key], color: "#222222" }, measured] });
  }
}


// Where in its envelope the leg walked (its own estimate of the task), and how well, per node's region
function adaptiveSection(a) {
  const inclinesTopDown = a.inclines_deg.map((g, j) => [g, j]).reverse();
  const total = a.time_s.flat().reduce((x, y) => x + y, 0);
  const cellTable = (id, caption, cell) => h("table", { id, class: "histogram" },
    h("caption", {}, caption),
    h("thead", {}, h("tr", {}, h("th", { scope: "col" }, "incline \\ speed"), a.speeds_mps.map((v) => h("th", { scope: "col" }, fmt(v, 2, "m/s"))))),
    h("tbody", {}, inclinesTopDown.map(([g, j]) => h("tr", {}, h("th", { scope: "row" }, `${g > 0 ? "+" : ""}${fmt(g, 1, "°")}`),
      a.speeds_mps.map((_, i) => cell(i, j))))));
  const timeCell = (i, j) => {
    const t = a.time_s[i][j], n = a.strides[i][j];
    const td = h("td", { class: `num${t > 0 ? " filled" : ""}`, dataset: { cell: `${i},${j}` } }, t > 0 ? `${fmt(t, 0, "s")} · ${n}` : "—");
    if (t > 0) td.style.setProperty("--f", String(total ? t / Math.max(...a.time_s.flat()) : 0));
    return td;
  };
  const errCell = (i, j) => {
    const k = a.errors_by_region.knee_angle_per_stride_rmse_deg[i][j], an = a.errors_by_region.ankle_angle_per_stride_rmse_deg[i][j];
    return h("td", { class: "num" }, k === null ? "—" : `${fmt(k, 1)} / ${fmt(an, 1)}`);
  };
  const modes = a.adaptive_mode_s || {};
  const overall = a.errors_by_region.overall || {};
  return h("section", { id: "report-adaptive" }, h("h2", {}, "Where in the envelope the patient walked"),
    h("p", { id: "report-overall" }, h("strong", {}, "Each stride at the task the leg estimated: "), !overall.strides ? "no stride scored."
      : overall.strides < MIN_STRIDES ? `too few strides to judge (${overall.strides} scored, at least ${MIN_STRIDES} needed).`
        : `knee angle RMSE ${fmt(overall.knee_angle_per_stride_rmse_deg, 1, "deg")}, ankle ${fmt(overall.ankle_angle_per_stride_rmse_deg, 1, "deg")} `
          + `per stride over ${overall.strides} strides (against the reference at each stride's estimated task: what the leg `
          + "itself could know; where the estimate is wrong, so is the reference)."),
    h("p", { class: "small" }, `Estimated for ${fmt(total, 0, "s")} (not yet estimated: ${fmt(a.unestimated_s, 0, "s")}, `,
      `${a.unestimated_strides} strides); beyond the envelope's edge (rows clamped): ${fmt(a.outside_s, 0, "s")}. Rows: `,
      Object.entries(modes).map(([k, v]) => `${k} ${fmt(v, 0, "s")}`).join(", "), "."),
    h("div", { class: "two" },
      cellTable("report-histogram", "Time · strides per node's region (the leg's own estimate of its task)", timeCell),
      cellTable("report-errors-by-task", "Knee / ankle angle RMSE per stride (deg), each stride at its estimated task", errCell)),
    h("p", { class: "muted small" }, "A region is the set of tasks nearer to its node than to any other. Errors by task: ",
      `${a.errors_reference}; where the estimate is wrong the reference is too, so read them with the estimate's accuracy.`));
}


// "Refine from walking" with this session's strides: a new draft of the version it ran, decided like any
function refineSection(s, m) {
  if (app.me?.role !== "prosthetist" || s.table_label === null) return null;
  const kind = s.envelope_id !== null ? "envelope" : "proposal";
  const id = s.envelope_id ?? s.proposal_id;
  const comment = h("input", { id: "report-refine-comment", required: true, size: 40, maxlength: 2000, "aria-label": "Why" });
  const out = h("div", { id: "report-refine-result" });
  const form = h("form", { id: "report-refine", class: "no-print" },
    h("div", { class: "inline" }, h("label", {}, "Why (required, audited) ", comment),
      h("button", { type: "submit" }, `Refine ${s.table_label} from these strides`)),
    h("p", { class: "muted small" }, "The strides of this session against the model's targets at each stride's task; where they agree, the ",
      "rows move a damped step towards the targets in a new draft (never a push). Several sessions: the version's own page."), out);
  form.addEventListener("submit", async (ev) => {
    ev.preventDefault();
    out.replaceChildren(h("p", { class: "muted" }, "Reading the strides and walking the changed nodes on the bench…"));
    try {
      const r = await post(`/api/${kind}s/${id}/refinements`, { session_ids: [s.id], comment: comment.value });
      const made = kind === "envelope" ? r.envelope_id : r.proposal_id;
      out.replaceChildren(h("p", {}, h("a", { href: `#/${kind}s/${made}` }, `Open the refined draft v${r.version.version}`)),
        refinementView(r, m.adaptive ? { speeds: m.adaptive.speeds_mps, inclines: m.adaptive.inclines_deg } : {}));
    } catch (err) {
      out.replaceChildren(h("p", { class: "error", role: "alert" }, err.message));
    }
  });
  return h("section", { id: "report-refine-section" }, h("h2", { class: "no-print" }, "Refine from walking"), form);
}
