// The "Device" card of a table or an envelope: its pushes, the device to send it to (assigned to the patient, or
// assign it here), a confirmation that names what the leg runs now and what replaces it, then the live steps:
// sent → CRC read back → running at the next heel strike.
import { get, post, put } from "../api.js";
import { benchFigures } from "./decision_panel.js";
import { chip, confirmDialog, fmt, h, table, tableName, when } from "../ui.js";

// item: the proposal or envelope; kind "table" | "envelope"; name: its one name; what: its name with its task in
// words; path: its API path (…/push, …/pushes); patient: its patient.
export async function renderPush(box, { item, kind, name, what, path, canPush, patient }) {
  box.replaceChildren(h("h2", {}, "Device"));
  const [pushes, devices] = await Promise.all([get(`${path}/pushes`), get("/api/devices")]);
  const status = h("div", { id: "push-status", "aria-live": "polite" });
  if (pushes.length) {
    status.append(table(["Push", "Device", "CRC-32", "Status", "Requested", "Acknowledged", "Active"],
      pushes.map((x) => h("tr", {}, h("td", {}, `#${x.id}`), h("td", {}, x.device_id), h("td", { class: "mono" }, x.crc32),
        h("td", {}, chip(x.status, ["failed", "lost"].includes(x.status) ? "bad"
          : x.status === "unconfirmed" ? "warn" : x.status === "superseded" ? "" : "ok")),
        h("td", {}, when(x.requested_at)), h("td", {}, when(x.acknowledged_at)), h("td", {}, when(x.active_at))))));
  }
  if (item.status !== "approved" || item.withdrawal || !canPush || !devices.length) {
    box.append(h("p", { class: "muted" }, item.status !== "approved" ? "Only an approved version can be pushed to a device."
      : item.withdrawal ? "Withdrawn: it is never pushed again."
        : !devices.length ? "No device on this server." : "Only a prosthetist can push."), status);
    return;
  }
  const wearer = (d) => (d.patient ? `worn by ${d.patient.patient_code}` : "assigned to nobody");
  const optionText = (d) => `${d.id} (${d.online ? "online" : "offline"}, ${wearer(d)})`;
  const select = h("select", { id: "push-device", "aria-label": "Device" },
    devices.map((d) => h("option", { value: d.id }, optionText(d))));
  const error = h("p", { class: "error", role: "alert" });
  const steps = h("ol", { class: "steps", id: "push-steps" });
  const button = h("button", { id: "push-button" }, "Push to device…");
  const assignBox = h("p", { id: "push-assignment" });
  let unsaved = false;   // cells typed into the table and not saved: a push would send the stored values
  const edited = (ev) => {
    if (!box.isConnected) { window.removeEventListener("quasitune:unsaved-edits", edited); return; }
    unsaved = Boolean(ev.detail?.unsaved);
    showAssignment();
  };
  window.addEventListener("quasitune:unsaved-edits", edited);
  const showAssignment = () => {
    for (const opt of select.options) opt.textContent = optionText(devices.find((x) => x.id === opt.value));
    const d = devices.find((x) => x.id === select.value);
    const mine = d.patient && d.patient.patient_id === item.patient_id;
    // a leg worn by nobody is assigned in the push's own dialog; one worn by another patient is changed deliberately
    button.disabled = Boolean(d.patient && !mine) || unsaved;
    button.title = unsaved ? "unsaved edits in the table: save them as a new version, or discard them" : "";
    assignBox.replaceChildren(mine ? chip(`${d.id} is assigned to ${patient.code_name}`, "ok")
      : !d.patient ? h("span", {}, chip(`${d.id} is assigned to nobody`, "warn"),
        ` The push assigns it to ${patient.code_name} first (said in its dialog).`)
        : h("span", {}, chip(`${d.id} is ${wearer(d)}`, "warn"), ` A ${kind} goes only to the leg of its patient. `,
          h("button", { id: "assign-device", class: "secondary", onclick: assign }, `Assign ${d.id} to ${patient.code_name}…`)));
  };
  async function assign() {
    const d = devices.find((x) => x.id === select.value);
    const ok = await confirmDialog({ id: "assign-dialog", title: `Assign ${d.id} to ${patient.code_name}?`,
      facts: [["Worn now by", d.patient ? `${d.patient.patient_code} (${fmt(d.patient.body_mass_kg, 0, "kg")})` : "nobody"],
        ["Will be worn by", `${patient.code_name} (${fmt(patient.body_mass_kg, 0, "kg")})`],
        ["On the leg", tableName(d.active_table, true)]],
      confirm: "Assign" });
    if (!ok) return;
    try {
      Object.assign(d, await put(`/api/devices/${d.id}/assignment`, { patient_id: item.patient_id }));
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
    const bench = item.bench || { status: "not_walked", words: "bench preview not walked yet", flags: [] };
    const builtFor = item.body_mass_kg ?? item.task?.body_mass_kg;
    const massOff = builtFor && Math.abs(patient.body_mass_kg - builtFor) > 0.05 * builtFor;
    const unclean = bench.status === "unsafe" || bench.status === "not_walked" || massOff;
    const toAssign = !d.patient;   // worn by nobody: this one dialog assigns it to the patient, then pushes
    const ok = await confirmDialog({ id: "push-dialog", title: `Replace what runs on ${d.id}?`,
      facts: [["Patient", `${patient.code_name} (${fmt(patient.body_mass_kg, 0, "kg")})`],
        ...(toAssign ? [["Device", `${d.id} is worn by nobody: confirming assigns it to ${patient.code_name}, then pushes`]] : []),
        ["On the leg now", tableName(current, true)],
        ["Replaced by", what],
        ["Bench preview", bench.status === "unsafe" ? `UNSAFE: ${bench.flags.filter((f) => f.severity === "bad").map((f) => f.message).join("; ")}`
          : bench.words],
        ...(item.decision?.override_reason ? [["Approved without a clean preview, signed off by", item.decision.override_reason]] : []),
        ...(item.extrapolation_reason ? [["Extrapolated", `requested beyond what the model knows: “${item.extrapolation_reason}”`]]
          : item.extrapolation ? [["Extrapolation", outsideWords(item)]] : []),
        ...(massOff ? [["Body mass", `built for ${fmt(builtFor, 0, "kg")}; ${patient.code_name} now weighs ${fmt(patient.body_mass_kg, 0, "kg")} (more than 5 % apart)`]] : []),
        ["When", kind === "envelope" ? "at the next heel strike after the device re-checks every node; from then on the "
          + "leg changes its rows with the task it estimates, at heel strikes only" : "at the next heel strike after the device verifies it"]],
      requires: "The patient is seated or standing in the parallel bars.", confirm: "Push now",
      reason: unclean ? { label: "Push anyway because", min: 20 } : null });
    if (!ok) return;
    button.disabled = true;
    steps.replaceChildren(h("li", { class: "doing" }, `sending the ${kind} over CAN…`));
    try {
      if (toAssign) {
        Object.assign(devices.find((x) => x.id === d.id), await put(`/api/devices/${d.id}/assignment`, { patient_id: item.patient_id }));
      }
      const push = await post(`${path}/push`, { device_id: d.id, patient_ready: true,
        replaces_proposal_id: current ? current.proposal_id : null, replaces_envelope_id: current ? current.envelope_id : null,
        ...(unclean ? { override_reason: ok } : {}) });
      steps.replaceChildren(h("li", { class: "done" }, `device read back CRC-32 ${push.crc32} (matches) in ${fmt(push.elapsed_ms, 1, "ms")}`),
        h("li", { class: "doing", id: "push-active" }, "waiting for the device to switch at the next heel strike…"));
      const deadline = Date.now() + 15000;
      while (Date.now() < deadline) {
        const now = await get(`/api/devices/${d.id}`);
        if (now.active_crc32 === push.crc32 && now.active_version === push.table_version) {
          steps.lastChild.className = "done";
          steps.lastChild.textContent = `active on ${now.id}: ${push.label}, CRC-32 ${now.active_crc32}, mode ${now.mode}`;
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
  box.append(benchFigures(item.bench || { figures: [] }, "push-figures"),
    h("p", { class: "muted small" }, `Sends ${name} to the leg.`), h("div", { class: "inline" }, select, button),
    assignBox, steps, error, status);
}

// how far outside the walking data a version lies, counted: an envelope's nodes, or the one task of a table
function outsideWords(item) {
  if (!item.nodes) return "its task lies outside the walking data the model was trained on, within the margin it predicts (flagged on its page)";
  const out = item.nodes.filter((n) => n.extrapolation).length;
  return `${out} of ${item.nodes.length} nodes lie outside the walking data the model was trained on (hatched on its maps)`;
}
