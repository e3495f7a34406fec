// What a table's page and an envelope's page show alike about a version: its chips (status, where it runs, its limits,
// the bench's verdict, an override, a withdrawal, extrapolation, where it came from, the leg it was made for) and its
// bench preview fetched once with the bench's progress beside it. One place, so the two pages cannot drift apart.
import { get } from "../api.js";
import { onLeave } from "../state.js";
import { chip, extrapolationChip, h } from "../ui.js";
import { watchBench } from "./bench_progress.js";
import { BENCH_CHIP } from "./decision_panel.js";

const DEPLOYMENT_WORDS = { pushed: ["sent to a leg, waiting for heel strike", "warn"],
  active_on_device: ["running on a leg", "ok"], replaced: ["was on a leg, since replaced", ""],
  unconfirmed: ["push unconfirmed: waiting for the leg's status", "warn"],
  not_on_device: ["no longer on the leg (the leg reported it does not hold it)", "bad"],
  push_failed: ["last push failed", "bad"] };

// ``limitsWords``: what "within the limits" means for this kind of version; ``more``: chips of its own, last
export function versionChips(v, id, limitsWords, more = []) {
  const [words, kind] = DEPLOYMENT_WORDS[v.deployment] || [];
  return h("p", { class: "chips", id }, chip(v.status, v.status), words ? chip(words, kind) : null,
    chip(v.safety.ok ? limitsWords : "outside parameter limits", v.safety.ok ? "ok" : "bad"),
    v.bench ? h("span", { id: "bench-chip" }, chip(v.bench.words, BENCH_CHIP[v.bench.status])) : null,
    v.decision?.override_reason ? chip("approved without a clean bench preview", "warn") : null,
    v.withdrawal ? h("span", { id: "withdrawn-chip" }, chip("WITHDRAWN", "bad")) : null,
    v.extrapolation_reason ? extrapolationChip(v) : null,
    v.source === "edit" ? chip(`edited from v${v.parent_version}`) : chip("model"),
    v.leg ? h("span", { id: "leg-chip", title: "its swing rows are proposed for this leg and its bench preview walks it" },
      chip(`made for ${v.leg.words}`)) : null, ...more);
}

// the version's preview (``path`` its API path; ``job`` what the bench's queue calls the walk), walked on first
// request with its progress shown in ``box``; null when the page was left or the walk failed (said in the box)
export async function walkedPreview(box, path, job) {
  let alive = true;
  onLeave(() => { alive = false; });
  const stopWatching = watchBench(box, path, job);
  try {
    const pv = await get(`${path}/preview`);
    window.dispatchEvent(new CustomEvent("quasitune:bench-walked", { detail: { path } }));
    return alive ? pv : null;
  } catch (err) {
    if (alive) box.querySelector("#preview-status").textContent = err.status === 409 && /cancelled by/.test(err.message)
      ? `Preview not walked: ${err.message}. Open this page again to walk it.` : `Preview failed: ${err.message}`;
    return null;
  } finally {
    stopWatching();
  }
}
