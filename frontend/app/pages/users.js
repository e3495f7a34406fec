// Accounts (admin): who may sign in, with which role; disable an account (its sessions end at once), give a
// forgotten password a one-time replacement, add a user with a one-time password.
import { get, patch, post, put } from "../api.js";
import { app } from "../state.js";
import { chip, confirmDialog, h, notice, table, when } from "../ui.js";

export async function usersPage(view) {
  if (app.me.role !== "admin") {
    view.replaceChildren(h("h1", {}, "Accounts"), h("p", { class: "muted" }, "Only an admin manages accounts."));
    return;
  }
  const users = await get("/api/users");
  const again = () => usersPage(view);
  const rows = users.map((u) => h("tr", { dataset: { user: u.username } },
    h("td", {}, u.username), h("td", {}, u.role),
    h("td", {}, u.disabled ? chip("disabled", "bad") : chip("active", "ok"),
      u.must_change_password ? chip("must change password", "warn") : null),
    h("td", {}, when(u.created_at)), h("td", {}, when(u.password_changed_at)),
    h("td", {}, u.id === app.me.id ? h("span", { class: "muted" }, "you") : h("div", { class: "inline" },
      h("button", { class: u.disabled ? "secondary" : "danger", onclick: () => toggle(u, again) },
        u.disabled ? "Enable" : "Disable…"),
      resetForm(u, again)))));
  view.replaceChildren(h("h1", {}, "Accounts"),
    table(["User", "Role", "State", "Created", "Password changed", ""], rows, { id: "users" }),
    newUserForm(again));
}

async function toggle(u, again) {
  if (!u.disabled && !await confirmDialog({ id: "disable-dialog", title: `Disable ${u.username}?`, danger: true,
    facts: [["Role", u.role], ["Then", "they cannot sign in, and every open session (telemetry included) ends at once"]],
    confirm: "Disable" })) return;
  try {
    await patch(`/api/users/${u.id}`, { disabled: !u.disabled });
    notice(`${u.username} ${u.disabled ? "enabled" : "disabled"}`, "warn");
    await again();
  } catch (err) {
    notice(err.message);
  }
}

function resetForm(u, again) {
  const input = h("input", { type: "password", minlength: 8, maxlength: 1024, required: true, autocomplete: "new-password",
    "aria-label": `one-time password for ${u.username}`, placeholder: "one-time password" });
  const form = h("form", { class: "inline" }, input, h("button", { type: "submit", class: "secondary" }, "Reset password"));
  form.addEventListener("submit", async (ev) => {
    ev.preventDefault();
    try {
      await put(`/api/users/${u.id}/password`, { password: input.value });
      notice(`${u.username}: sessions ended; they choose their own password at the next sign-in`, "warn");
      await again();
    } catch (err) {
      notice(err.message);
    }
  });
  return form;
}

function newUserForm(again) {
  const error = h("p", { class: "error", role: "alert" });
  const form = h("form", { class: "card", id: "new-user" }, h("h2", {}, "New account"),
    h("div", { class: "inline" },
      h("label", {}, "User name", h("input", { name: "username", required: true, maxlength: 64, pattern: "[A-Za-z0-9][A-Za-z0-9._@\\-]*" })),
      h("label", {}, "Role", h("select", { name: "role" }, ["prosthetist", "viewer", "admin"].map((r) => h("option", { value: r }, r)))),
      h("label", {}, "One-time password", h("input", { name: "password", type: "password", minlength: 8, maxlength: 1024,
        required: true, autocomplete: "new-password" })),
      h("button", { type: "submit" }, "Add")),
    h("p", { class: "muted small" }, "Give the one-time password to the person in person; they must choose their own at the first sign-in."),
    error);
  form.addEventListener("submit", async (ev) => {
    ev.preventDefault();
    const d = new FormData(form);
    try {
      await post("/api/users", { username: d.get("username"), role: d.get("role"), password: d.get("password") });
      notice(`${d.get("username")} added`, "ok");
      await again();
    } catch (err) {
      error.textContent = err.message;
    }
  });
  return form;
}
