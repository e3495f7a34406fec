// The printable session report (Print → the browser's PDF, or the server's PDF export).
import { get, token } from "../api.js";
import { phaseChart } from "../charts.js";
import { offTable } from "./monitor.js";
import { fmt, h, notice, referenceLabel, table, when } from "../ui.js";

const CHANNELS = [["knee_angle_deg", "knee angle (deg, flexion +)", "knee_angle_rmse_deg", "deg"],
  ["ankle_angle_deg", "ankle angle (deg, dorsiflexion +)", "ankle_angle_rmse_deg", "deg"],
  ["knee_moment_Nm_per_kg", "knee moment (N·m/kg, flexor +)", "knee_moment_rmse_Nm_per_kg", "N·m/kg"],
  ["ankle_moment_Nm_per_kg", "ankle moment (N·m/kg, dorsiflexor +)", "ankle_moment_rmse_Nm_per_kg", "N·m/kg"]];

export async function reportPage(view, id) {
  const s = await get(`/api/sessions/${id}`);
  const patient = await get(`/api/patients/${s.patient_id}`);
  const m = s.summary;
  const pdf = h("button", { id: "pdf", class: "secondary" }, "Download PDF");
  pdf.addEventListener("click", async () => {
    const r = await fetch(`/api/sessions/${id}/report.pdf`, { headers: { Authorization: `Bearer ${token()}` } });
    if (!r.ok) {
      notice((await r.json().catch(() => ({}))).detail || `PDF failed (${r.status})`);
      return;
    }
    const url = URL.createObjectURL(await r.blob());
    const a = h("a", { href: url, download: `quasitune-session-${id}.pdf` });
    document.body.append(a);
    a.click();
    a.remove();
    setTimeout(() => URL.revokeObjectURL(url), 10000);
  });
  const head = [
    h("p", { class: "crumbs no-print" }, h("a", { href: `#/patients/${patient.id}` }, patient.code_name), " / ", `session #${id}`),
    h("h1", {}, `Session report #${id}`),
    h("div", { class: "inline no-print" }, h("button", { onclick: () => print() }, "Print"), pdf),
    h("dl", { class: "facts", id: "report-facts" },
      h("dt", {}, "Patient"), h("dd", {}, `${patient.code_name} · ${fmt(patient.body_mass_kg, 1, "kg")} · ${patient.side}`),
      h("dt", {}, "Task"), h("dd", {}, `${fmt(s.task.speed_mps, 2, "m/s")}, incline ${fmt(s.task.incline_deg, 1, "°")}`),
      h("dt", {}, "Active table"), h("dd", { id: "report-table" }, s.table_label === null ? "none from this server"
        : h("span", {}, h("a", { href: `#/proposals/${s.proposal_id}` }, s.table_label), ` · CRC-32 ${s.table_crc32}`)),
      h("dt", {}, "Device"), h("dd", {}, s.device_id),
      h("dt", {}, "Recorded"), h("dd", {}, `${when(s.started_at)} → ${when(s.stopped_at)} by ${s.started_by}`)),
  ];
  if (!m) {
    view.replaceChildren(...head, h("p", { class: "muted" }, "Still recording: stop the session for its summary."));
    return;
  }
  const metrics = table(["Strides scored / walked", "Cadence (steps/min)", "Stride time (s)", "Reference stride time (s)", "Samples",
    "Missing samples"], [h("tr", {}, h("td", { class: "num", id: "report-strides" }, `${m.strides_scored ?? m.strides} / ${m.strides}`),
    h("td", { class: "num", id: "report-cadence" }, fmt(m.cadence_steps_per_min, 1)), h("td", { class: "num" }, fmt(m.stride_time_s, 3)),
    h("td", { class: "num" }, fmt(m.reference_stride_time_s, 3)), h("td", { class: "num" }, m.samples),
    h("td", { class: "num" }, m.missing_samples))]);
  const errors = table(["Channel", "RMSE vs reference"], CHANNELS.map(([, label, key, unit]) =>
    h("tr", {}, h("td", {}, label), h("td", { class: "num" }, fmt(m[key], unit === "deg" ? 1 : 3, unit)))), { id: "report-errors" });
  const charts = h("div", { class: "two", id: "report-charts" });
  view.replaceChildren(...head, h("h2", {}, "Strides and errors"), offTable(m), metrics, errors,
    h("p", { class: "muted small", id: "report-reference" }, `Reference: ${referenceLabel(m)} (${m.reference_source})${m.reference_extrapolation ? " (extrapolated)" : ""}. `,
      "Strides between heel strikes (load above 10 % of body weight), averaged on the gait-cycle grid."),
    h("h2", {}, "Joint trajectories against the reference"), charts);
  const x = m.phase_grid.map((p) => p * 100);
  for (const [key, label, , unit] of CHANNELS) {
    const el = h("figure", { class: "chart" });
    charts.append(el);
    phaseChart(el, { title: label, yLabel: unit, x, height: 200, lines: [
      { label: `reference: ${referenceLabel(m)}`, values: m.reference_curves[key], color: "#222222" },
      { label: "measured (stride mean)", values: m.mean_curves[key] || x.map(() => null), color: "#0072B2" }] });
  }
}
