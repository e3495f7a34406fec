// What a stopped session's summary says first, on the monitor and in the report: the time the leg did not run its
// table, and the headline errors (each stride at its own task), or that the strides are too few to judge.
import { fmt, h } from "../ui.js";

// Time the leg did not run its table during a session, said before any error figure
export function offTable(m) {
  if (!m.strides_off_table && !m.off_table_s) return null;
  const modes = m.mode_s || {};
  return h("p", { class: "notice-inline bad", id: "off-table" }, `The leg did not run its table for ${fmt(m.off_table_s, 1, "s")}`,
    modes.safe ? ` (safe mode ${fmt(modes.safe, 1, "s")})` : "", modes.no_table ? ` (no table ${fmt(modes.no_table, 1, "s")})` : "",
    `: ${m.strides_off_table} of ${m.strides} strides are left out of the errors and the cadence below, which describe `,
    "the table only (in safe mode the load flickers, so those \"strides\" are not steps a patient took).");
}

// The session's headline: each stride's angle error against the reference at its own task, averaged; too few
// strides are said to be too few instead of shown as a figure
export function headline(head) {
  if (!head) return null;
  if (!head.enough_strides) {
    return h("p", { class: "banner warn", id: "report-headline" }, h("strong", {}, "Too few strides to judge: "),
      `${head.strides_scored} scored, at least ${head.min_strides} needed for the errors to mean anything.`);
  }
  return h("div", { class: "headline", id: "report-headline" },
    h("p", {}, h("strong", {}, "Angle error per stride: "), `knee ${fmt(head.knee_angle_rmse_deg, 1, "deg")}, `
      + `ankle ${fmt(head.ankle_angle_rmse_deg, 1, "deg")}`),
    h("p", { class: "muted small" }, `RMSE of each of ${head.strides_scored} strides against the able-bodied reference `
      + `at ${head.against}, averaged.${notScored(head)}`));
}

// why the headline scores fewer strides than ran on the table (no task estimate for some), so the counts agree
export function notScored(head) {
  const onTable = head.strides_on_table;
  if (onTable === undefined || onTable === head.strides_scored) return "";
  const unknown = head.strides_without_task || 0;
  return ` Of the ${onTable} strides on the table, ${onTable - head.strides_scored} are not scored`
    + (unknown ? ` (${unknown} without a task estimate)` : "") + ".";
}
