// The "Decision" card of a table or an envelope: approve or reject a draft once, with the reason (audited). A version
// outside the parameter limits cannot be approved. Approval rests on the bench: with its preview not walked yet, or
// showing an unsafe figure, Approve needs a written override (20 characters at least; audited and shown wherever the
// version is shown). The card follows the preview when it finishes, without losing what was typed.
import { get, post } from "../api.js";
import { fmt, h, notice, table, when } from "../ui.js";

export const BENCH_CHIP = { clean: "ok", warnings: "warn", unsafe: "bad", not_walked: "" };

// The bench's safety figures, compact, beside Approve and Push: this version's and the FSMIC's on the same walk, each
// flagged on its own bound (the preview card below has the tracking errors)
export function benchFigures(bench, id) {
  if (!bench.figures?.length) {
    return h("p", { class: "muted small", id }, "Bench safety figures: the preview has not finished walking.");
  }
  const value = (v, unit) => (v === null || v === undefined ? "—" : `${fmt(v, unit === "BW" ? 1 : 0)} ${unit}`);
  return table(["Bench safety figure", "This version", "FSMIC"], bench.figures.map((f) => h("tr",
    { class: f.severity ? `flag-${f.severity}` : "", dataset: { figure: f.figure } },
    h("td", {}, f.label), h("td", { class: `num${f.severity ? ` ${f.severity}` : ""}` }, value(f.value, f.unit)),
    h("td", { class: "num" }, value(f.fsmic_value, f.unit)))), { id, class: "compact" });
}
const MIN_OVERRIDE = 20;

// item: the proposal or envelope (status, decision, safety, bench); name: its one name; path: its API path;
// reload: redraw the page after a decision
export function renderDecision(box, { item, name, path, canDecide, reload }) {
  box.replaceChildren(h("h2", {}, "Decision"));
  if (item.status !== "draft") {
    box.append(h("p", {}, `${item.decision.status} by ${item.decision.by} ${when(item.decision.at)}`,
      item.decision.comment ? ` — “${item.decision.comment}”` : "", ". An approved or rejected version never changes; edit it into a new draft instead."));
    if (item.decision.override_reason) {
      box.append(h("p", { class: "banner warn", id: "decision-override" }, h("strong", {}, "Approved without a clean bench preview: "),
        `“${item.decision.override_reason}”`));
    }
    return;
  }
  if (!canDecide) {
    box.append(h("p", { class: "muted" }, "Draft. Only a prosthetist can approve or reject it."));
    return;
  }
  let bench = item.bench || { status: "not_walked", words: "bench preview not walked yet", flags: [] };
  const error = h("p", { class: "error", role: "alert" });
  const comment = h("input", { name: "comment", maxlength: 2000, size: 50, "aria-label": "Decision comment" });
  const override = h("textarea", { name: "override_reason", id: "override-reason", rows: 2, cols: 60, maxlength: 2000,
    "aria-label": "Why approve without a clean bench preview" });
  const gate = h("div", { id: "bench-gate" });
  const needsOverride = () => bench.status === "unsafe" || bench.status === "not_walked";
  let unsaved = false;   // cells typed into the table and not saved: Approve would approve the stored values
  const unsavedNote = h("p", { class: "banner warn", id: "unsaved-edits", hidden: true },
    "The table has unsaved edits: save them as a new version, or discard them, before deciding.");
  const decide = (what) => async () => {
    error.textContent = "";
    try {
      const body = { comment: comment.value };
      if (what === "approve" && needsOverride()) body.override_reason = override.value.trim();
      await post(`${path}/${what}`, body);
      notice(`${name} ${what === "approve" ? "approved" : "rejected"}`, "ok");
      await reload();
    } catch (err) {
      if (err.status === 409) {     // the version changed under a stale tab (decided elsewhere, bench walked): redraw
        await reload();
        notice(err.message, "warn");
        return;
      }
      error.textContent = err.message;
    }
  };
  const approve = h("button", { id: "approve", onclick: decide("approve"), disabled: true }, "Approve");
  const reject = h("button", { id: "reject", class: "secondary", onclick: decide("reject"), disabled: true,
    title: "say why first" }, "Reject");
  const update = () => {       // a decision needs its reason, like an edit; an unclean bench needs a written override
    const said = comment.value.trim().length > 0;
    const overridden = !needsOverride() || override.value.trim().length >= MIN_OVERRIDE;
    approve.disabled = !said || !item.safety.ok || !overridden || unsaved;
    unsavedNote.hidden = !unsaved;
    approve.title = unsaved ? "unsaved edits in the table: save them as a new version, or discard them"
      : !item.safety.ok ? "outside the parameter limits: cannot be approved"
      : !overridden ? `the bench preview is ${bench.status === "unsafe" ? "unsafe" : "not walked yet"}: write why you approve anyway`
        : "say why first (what you reviewed)";
    reject.disabled = !said;
    const warnings = bench.flags.filter((f) => f.severity === "warn").map((f) => f.message);
    gate.replaceChildren(benchFigures(bench, "decision-figures"), h("p", { id: "decision-bench" }, h("strong", {}, "Bench: "),
      bench.status === "clean" ? "the preview walked clean: no safety figure outside its bound."
        : bench.status === "warnings" ? `the preview walked with warnings: ${warnings.join("; ")}.`
          : bench.status === "unsafe" ? "the preview shows an unsafe figure (below)." : "the preview has not finished walking."),
    ...(needsOverride() ? [
      h("p", { class: `banner ${bench.status === "unsafe" ? "bad" : "warn"}` }, h("strong", {}, "Approval rests on the bench: "),
        bench.status === "unsafe" ? bench.flags.filter((f) => f.severity === "bad").map((f) => f.message).join("; ")
          : "its preview is still walking (or has not been walked). Wait for it, or write why you approve without it."),
      h("label", {}, `Approve anyway because (at least ${MIN_OVERRIDE} characters; audited and shown with this version) `, override)]
      : []));
  };
  comment.addEventListener("input", update);
  override.addEventListener("input", update);
  // the preview finished (on this page): follow the bench's verdict in place
  const walked = async (ev) => {
    if (!box.isConnected) { window.removeEventListener("quasitune:bench-walked", walked); return; }   // page left
    if (ev.detail?.path !== path) return;
    const now = await get(path).catch(() => null);
    if (now?.bench) { bench = now.bench; update(); }
  };
  window.addEventListener("quasitune:bench-walked", walked);
  const edited = (ev) => {
    if (!box.isConnected) { window.removeEventListener("quasitune:unsaved-edits", edited); return; }
    unsaved = Boolean(ev.detail?.unsaved);
    update();
  };
  window.addEventListener("quasitune:unsaved-edits", edited);
  update();
  box.append(gate, h("div", { class: "inline" }, h("label", {}, "Why (required, audited) ", comment), approve, reject),
    unsavedNote, error);
}
