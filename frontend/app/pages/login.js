import { signIn } from "../api.js";
import { app } from "../main.js";
import { get } from "../api.js";
import { h } from "../ui.js";

export async function loginPage(view) {
  const error = h("p", { class: "error", role: "alert", id: "login-error" });
  const form = h("form", { class: "card narrow", id: "login-form" },
    h("h1", {}, "Sign in"),
    h("label", {}, "User name", h("input", { name: "username", autocomplete: "username", required: true, autofocus: true })),
    h("label", {}, "Password", h("input", { name: "password", type: "password", autocomplete: "current-password",
      required: true })),
    h("button", { type: "submit" }, "Sign in"), error);
  form.addEventListener("submit", async (ev) => {
    ev.preventDefault();
    error.textContent = "";
    const data = new FormData(form);
    try {
      await signIn(data.get("username"), data.get("password"));
      app.me = await get("/api/auth/me");
      location.hash = "#/patients";
    } catch (err) {
      error.textContent = err.message;
    }
  });
  view.replaceChildren(form);
  form.querySelector("input").focus();
}
