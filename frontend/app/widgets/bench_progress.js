// A walk on the bench as the server's job list shows it (GET /api/jobs): a progress bar with the time left, the walks
// it waits behind, and Cancel for its owner or an admin (DELETE /api/jobs/{id}: the waiting request then answers 409,
// and nothing is stored). The time left is the server's estimate, and it says what from.
import { del, get } from "../api.js";
import { app, onLeave } from "../state.js";
import { h } from "../ui.js";

const POLL_MS = 500;

// Watch the job walking `path` (e.g. "/api/envelopes/12") for `kind` ("envelope preview", "refinement") inside `box`
// until the returned stop() is called. Nothing is drawn until the server lists such a job.
export function watchBench(box, path, kind) {
  let stopped = false, timer = null;
  const bar = h("progress", { max: 1, value: 0, id: "bench-progress", "aria-label": `${kind} on the bench` });
  const words = h("span", { class: "small", id: "bench-progress-words" });
  const cancel = h("button", { type: "button", id: "bench-cancel", class: "secondary" }, "Cancel");
  const row = h("div", { class: "inline bench-progress", hidden: true }, bar, words, cancel);
  box.append(row);
  let current = null;
  cancel.addEventListener("click", async () => {
    if (!current) return;
    cancel.disabled = true;
    try {
      await del(`/api/jobs/${current.id}`);
      words.textContent = "cancelling…";
    } catch (err) {
      words.textContent = err.message;
      cancel.disabled = false;
    }
  });
  const poll = async () => {
    if (stopped) return;
    try {
      const jobs = await get("/api/jobs");
      const job = jobs.find((j) => j.path === path && j.kind === kind && (j.state === "queued" || j.state === "walking"));
      if (job && !stopped) {
        current = job;
        row.hidden = false;
        bar.value = job.fraction;
        words.textContent = ` ${job.words} (estimated from ${job.estimate_basis})`;
        const mine = app.me && (job.user === app.me.username || app.me.role === "admin");
        cancel.hidden = !mine;
      }
    } catch {
      // the list is a courtesy: the walk goes on and its answer comes regardless
    }
    if (!stopped) timer = setTimeout(poll, POLL_MS);
  };
  timer = setTimeout(poll, 100);
  const stop = () => {
    stopped = true;
    clearTimeout(timer);
    row.remove();
  };
  onLeave(stop);
  return stop;
}
