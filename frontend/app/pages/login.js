import { signIn } from "../api.js";
import { app } from "../state.js";
import { get } from "../api.js";
import { h } from "../ui.js";

// where to go once signed in: the page asked for (a hash route of this app only), else the patient list
function nextPage(params) {
  const next = params?.get("next") || "";
  return /^#\/[\w/?=&.-]*$/.test(next) && !next.startsWith("#/login") ? next : "#/patients";
}

export async function loginPage(view, params) {
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
      location.hash = nextPage(params);
    } catch (err) {
      error.textContent = err.message;
    }
  });
  view.replaceChildren(form);
  form.querySelector("input").focus();
}
