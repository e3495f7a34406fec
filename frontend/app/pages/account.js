// Your own password: changed here, and first of all when someone else chose it (the printed one-time password, or
// one an admin typed): until then the server refuses everything else.
import { post } from "../api.js";
import { app } from "../state.js";
import { h, notice } from "../ui.js";

export async function passwordPage(view) {
  const forced = app.me.must_change_password;
  const error = h("p", { class: "error", role: "alert", id: "password-error" });
  const field = (name, text, autocomplete) => h("label", {}, text, h("input", { name, type: "password", autocomplete,
    required: true, minlength: name === "current_password" ? 1 : 8, maxlength: 1024 }));
  const form = h("form", { class: "card narrow", id: "password-form" },
    h("h1", {}, forced ? "Choose your own password" : "Change your password"),
    forced ? h("p", { class: "notice-inline warn" }, `${app.me.username}: the password you signed in with was chosen for you. `,
      "Choose your own before anything else; it is never shown to anyone.") : null,
    field("current_password", "Current password", "current-password"),
    field("new_password", "New password (at least 8 characters, spaces count)", "new-password"),
    field("again", "New password again", "new-password"),
    h("button", { type: "submit" }, "Change password"), error);
  form.addEventListener("submit", async (ev) => {
    ev.preventDefault();
    error.textContent = "";
    const d = new FormData(form);
    if (d.get("new_password") !== d.get("again")) {
      error.textContent = "the two new passwords differ";
      return;
    }
    try {
      app.me = await post("/api/auth/password", { current_password: d.get("current_password"),
        new_password: d.get("new_password") });
      // said on the page itself, not only in a passing notice: the one-time password no longer works
      const home = app.me.role === "admin" ? "#/users" : "#/patients";
      const go = h("a", { class: "button", href: home, id: "password-continue" }, app.me.role === "admin" ? "Continue to the accounts" : "Continue to the patients");
      view.replaceChildren(h("section", { class: "card narrow", id: "password-changed", role: "status" },
        h("h1", {}, "Password changed"),
        h("p", {}, `${app.me.username}: your own password is set${forced ? "; the one-time password no longer works" : ""}. `,
          "Every other session of this account has ended; this one goes on."), go));
      notice("Password changed", "ok");
      go.focus();
    } catch (err) {
      error.textContent = err.message;
    }
  });
  view.replaceChildren(form);
  form.querySelector("input").focus();
}
