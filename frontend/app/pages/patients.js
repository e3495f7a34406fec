import { get, post } from "../api.js";
import { app } from "../state.js";
import { h, table, when } from "../ui.js";

export async function patientsPage(view) {
  const patients = await get("/api/patients");
  const rows = patients.map((p) => h("tr", {},
    h("td", {}, h("a", { href: `#/patients/${p.id}` }, p.code_name)),
    h("td", { class: "num" }, p.body_mass_kg.toFixed(1)), h("td", {}, p.side), h("td", {}, p.k_level ?? "—"),
    h("td", {}, when(p.updated_at))));
  const parts = [h("h1", {}, "Patients"),
    patients.length ? table(["Code name", "Body mass (kg)", "Side", "K-level", "Updated"], rows, { id: "patients" })
      : h("p", { class: "muted" }, "No patients yet.")];
  if (app.me.role === "prosthetist") parts.push(newPatientForm());
  view.replaceChildren(...parts);
}

function newPatientForm() {
  const error = h("p", { class: "error", role: "alert" });
  const form = h("form", { class: "card", id: "new-patient" },
    h("h2", {}, "New patient"),
    h("div", { class: "grid4" },
      h("label", {}, "Code name (no real names)", h("input", { name: "code_name", required: true, maxlength: 40 })),
      h("label", {}, "Body mass (kg)", h("input", { name: "body_mass_kg", type: "number", min: 20, max: 200, step: 0.1,
        required: true })),
      h("label", {}, "Height (m)", h("input", { name: "height_m", type: "number", min: 0.5, max: 2.5, step: 0.01 })),
      h("label", {}, "Side", h("select", { name: "side" }, h("option", { value: "left" }, "left"),
        h("option", { value: "right" }, "right"))),
      h("label", {}, "K-level", h("select", { name: "k_level" }, h("option", { value: "" }, "—"),
        [0, 1, 2, 3, 4].map((k) => h("option", { value: k }, `K${k}`))))),
    h("label", {}, "Notes", h("textarea", { name: "notes", rows: 2, maxlength: 2000 })),
    h("button", { type: "submit" }, "Create patient"), error);
  form.addEventListener("submit", async (ev) => {
    ev.preventDefault();
    const d = new FormData(form);
    const body = { code_name: d.get("code_name"), body_mass_kg: Number(d.get("body_mass_kg")), side: d.get("side"),
      notes: d.get("notes") || "" };
    if (d.get("height_m")) body.height_m = Number(d.get("height_m"));
    if (d.get("k_level") !== "") body.k_level = Number(d.get("k_level"));
    try {
      const p = await post("/api/patients", body);
      location.hash = `#/patients/${p.id}`;
    } catch (err) {
      error.textContent = err.message;
    }
  });
  return form;
}
