// Hash router: #/login(?next=…), #/audit, #/patients, #/patients/:id, #/proposals/:id, #/envelopes/:id(/nodes/:i/:j), #/monitor/:deviceId, #/sessions/:id/report
import { get, post, signOut, token } from "./api.js";
import { h, notice } from "./ui.js";
import { app, loginHash } from "./state.js";
import { loginPage } from "./pages/login.js";
import { auditPage } from "./pages/audit.js";
import { patientsPage } from "./pages/patients.js";
import { patientPage } from "./pages/patient.js";
import { proposalPage } from "./pages/proposal.js";
import { envelopePage } from "./pages/envelope.js";
import { envelopeNodePage } from "./pages/envelope_node.js";
import { monitorPage } from "./pages/monitor.js";
import { reportPage } from "./pages/report.js";
import { passwordPage } from "./pages/account.js";
import { usersPage } from "./pages/users.js";

const routes = [
  [/^#\/login$/, loginPage],
  [/^#\/patients$/, patientsPage],
  [/^#\/patients\/(\d+)$/, patientPage],
  [/^#\/proposals\/(\d+)$/, proposalPage],
  [/^#\/envelopes\/(\d+)$/, envelopePage],
  [/^#\/envelopes\/(\d+)\/nodes\/(\d+)\/(\d+)$/, envelopeNodePage],
  [/^#\/monitor$/, firstDevice],
  [/^#\/monitor\/([\w.-]+)$/, monitorPage],
  [/^#\/sessions\/(\d+)\/report$/, reportPage],
  [/^#\/password$/, passwordPage],
  [/^#\/users$/, usersPage],
  [/^#\/audit$/, auditPage],
];


async function whoAmI() {
  if (!token()) return null;
  try {
    return await get("/api/auth/me");
  } catch {
    return null;
  }
}

function renderChrome() {
  const nav = document.getElementById("nav");
  const who = document.getElementById("who");
  if (!app.me) {
    nav.replaceChildren();
    who.replaceChildren();
    return;
  }
  nav.replaceChildren(...(app.me.must_change_password ? [] : [h("a", { href: "#/patients" }, "Patients"),
    h("a", { href: "#/monitor", id: "nav-monitor" }, "Live monitor"),
    ["prosthetist", "admin"].includes(app.me.role) ? h("a", { href: "#/audit", id: "nav-audit" }, "Audit log") : null,
    app.me.role === "admin" ? h("a", { href: "#/users", id: "nav-users" }, "Accounts") : null].filter(Boolean)));
  who.replaceChildren(h("span", {}, `${app.me.username} · ${app.me.role}`),
    h("a", { href: "#/password", id: "change-password" }, "Change password"),
    h("button", { class: "link", id: "sign-out", onclick: async () => {
      await post("/api/auth/logout").catch(() => {});   // the server forgets the token, not just this tab
      signOut();
      app.me = null;
      location.hash = "#/login";
    } }, "Sign out"));
}

async function route() {
  for (const fn of app.cleanup.splice(0)) fn();
  notice("");
  const [hash, query = ""] = (location.hash || "#/patients").split("?");
  if (hash !== "#/login" && !app.me) app.me = await whoAmI();
  if (hash !== "#/login" && !app.me) {
    location.hash = loginHash();   // back to this page after signing in (a link opened in a new tab)
    return;
  }
  if (app.me?.must_change_password && hash !== "#/password" && hash !== "#/login") {   // the server refuses all else
    location.hash = "#/password";
    return;
  }
  renderChrome();
  const view = document.getElementById("view");
  for (const [re, page] of routes) {
    const m = hash.match(re);
    if (m) {
      view.replaceChildren(h("p", { class: "muted" }, "Loading…"));
      try {
        await page(view, ...m.slice(1), new URLSearchParams(query));
      } catch (err) {
        view.replaceChildren(h("p", { class: "error" }, err.message));
      }
      if (!view.contains(document.activeElement)) view.focus({ preventScroll: true });   // screen readers start here
      return;
    }
  }
  view.replaceChildren(h("p", {}, "No such page. "), h("a", { href: "#/patients" }, "Back to patients"));
}

async function firstDevice(view) {
  const devices = await get("/api/devices");
  if (devices.length) location.replace(`#/monitor/${devices[0].id}`);
  else view.replaceChildren(h("h1", {}, "Live monitor"), h("p", { class: "muted" },
    "No device is configured on this server (start it with quasitune serve --device sim or INTERFACE:CHANNEL)."));
}


window.addEventListener("hashchange", route);
route();
