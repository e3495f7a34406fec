// The audit log for prosthetists and admins: every state change, newest first, who, when, what, and the values
// before and after; filtered by what it concerns and by whom, paged (the server's GET /api/audit).
import { get } from "../api.js";
import { app } from "../state.js";
import { h, table, when } from "../ui.js";

const ENTITIES = ["proposal", "envelope", "device", "session", "patient", "user"];
const LINKS = { proposal: (id) => `#/proposals/${id}`, envelope: (id) => `#/envelopes/${id}`,
  patient: (id) => `#/patients/${id}`, session: (id) => `#/sessions/${id}/report` };

// a value as people read it: "—" for none, lists and objects spelled out (never JSON's null)
function readable(v) {
  if (v === null || v === undefined) return "—";
  if (Array.isArray(v)) return `[${v.map(readable).join(", ")}]`;
  if (typeof v === "object") return `{${Object.entries(v).map(([k, x]) => `${k}: ${readable(x)}`).join(", ")}}`;
  return String(v);
}

// a stored value, short: scalars as they are, objects as "key: value" pairs (the full JSON on hover)
function brief(value) {
  if (value === null || value === undefined) return "";
  if (typeof value !== "object") return String(value);
  const text = Object.entries(value).map(([k, v]) => `${k}: ${readable(v)}`).join(" · ");
  return text.length > 220 ? `${text.slice(0, 220)}…` : text;
}

export async function auditPage(view, params) {
  if (!["prosthetist", "admin"].includes(app.me.role)) {
    view.replaceChildren(h("h1", {}, "Audit log"), h("p", { class: "muted" }, "The audit log is for prosthetists and administrators."));
    return;
  }
  const entity = ENTITIES.includes(params.get("entity")) ? params.get("entity") : "";
  const entityId = /^\d+$/.test(params.get("entity_id") || "") ? params.get("entity_id") : "";
  const actor = params.get("actor") || "";
  const query = new URLSearchParams({ limit: "50", ...(entity && { entity }), ...(entityId && { entity_id: entityId }),
    ...(actor && { actor }), ...(params.get("before_id") && { before_id: params.get("before_id") }) });
  const page = await get(`/api/audit?${query}`);
  const form = h("form", { class: "inline", id: "audit-filter" },
    h("label", {}, "Concerning ", h("select", { name: "entity" }, h("option", { value: "" }, "everything"),
      ENTITIES.map((e) => h("option", { value: e, selected: e === entity }, e)))),
    h("label", {}, "number ", h("input", { name: "entity_id", type: "number", min: 1, value: entityId, size: 6 })),
    h("label", {}, "by ", h("input", { name: "actor", value: actor, size: 12, maxlength: 64 })),
    h("button", { type: "submit" }, "Show"));
  form.addEventListener("submit", (ev) => {
    ev.preventDefault();
    const d = new FormData(form);
    const next = new URLSearchParams([...d.entries()].filter(([, v]) => v));
    location.hash = `#/audit${next.size ? `?${next}` : ""}`;
  });
  const rows = page.items.map((e) => h("tr", {},
    h("td", {}, when(e.at)), h("td", {}, e.actor), h("td", { class: "mono" }, e.action),
    h("td", {}, e.entity_id !== null && LINKS[e.entity]
      ? h("a", { href: LINKS[e.entity](e.now_version_id ?? e.entity_id) }, `${e.entity} ${e.entity_id}`,
        e.now_version_id ? ` (now version ${e.now_version_id})` : "")
      : `${e.entity}${e.entity_id === null ? "" : ` ${e.entity_id}`}`),
    h("td", { class: "small", title: JSON.stringify(e.before) }, brief(e.before)),
    h("td", { class: "small", title: JSON.stringify(e.after) }, brief(e.after))));
  const older = page.next_before_id === null ? null : h("a", { id: "audit-older",
    href: `#/audit?${new URLSearchParams({ ...Object.fromEntries(query), before_id: String(page.next_before_id) })}` }, "Older entries");
  view.replaceChildren(...[h("h1", {}, "Audit log"),
    h("p", { class: "muted small" }, "Every change, newest first: who, when, what, and the values before and after. ",
      "The log is append-only; nothing here can be edited."),
    h("section", { class: "card" }, form,
      rows.length ? table(["When", "Who", "What", "Concerning", "Before", "After"], rows, { id: "audit-table" })
        : h("p", { class: "muted" }, "No entries."), older)].filter(Boolean));
}
