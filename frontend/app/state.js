// What every page shares with the router: the signed-in user, the page's clean-up on leaving, the sign-in link that
// brings the reader back. Pages import this, never the router (main.js), so no module imports one that imports it.
export const app = { me: null, cleanup: [] };
window.quasitune = app;   // read by the browser tests and the UI benchmark (timings, frame rates)

// run when the page is left (the router calls them before drawing the next one)
export function onLeave(fn) {
  app.cleanup.push(fn);
}

// the sign-in page, remembering the page asked for (only pages of this app: a hash route, never a URL elsewhere)
export function loginHash() {
  const here = location.hash;
  return here && here.startsWith("#/") && !here.startsWith("#/login") ? `#/login?next=${encodeURIComponent(here)}` : "#/login";
}
