// The "Decision" card of a table or an envelope: approve or reject a draft once, with the reason (audited). A version
// outside the parameter limits cannot be approved. Approval rests on the bench: a preview not walked yet, or any safety
// figure beyond its bound, is overridden only by two prosthetists' sign-offs from two accounts, each with its written
// reason (20 characters at least; audited and shown wherever the version is shown): the first signs off here, the
// second approves with theirs. An approved version can be withdrawn (never pushed again; a leg running it is sent back
// to the last version it ran, or to safe mode). The card follows the preview when it finishes, without losing what was
// typed.
import { get, post } from "../api.js";
import { app } from "../state.js";
import { confirmDialog, fmt, h, notice, table, when } from "../ui.js";

export const BENCH_CHIP = { clean: "ok", unsafe: "bad", not_walked: "" };

// The bench's safety figures, compact, beside Approve and Push: this version's and the FSMIC's on the same walk, each
// flagged on its own bound (the preview card below has the tracking errors)
export function benchFigures(bench, id) {
  if (!bench.figures?.length) {
    return h("p", { class: "muted small", id }, "Bench safety figures: the preview has not finished walking.");
  }
  const value = (v, unit) => (v === null || v === undefined ? "—" : `${fmt(v, unit === "BW" ? 2 : 0)} ${unit}`);
  return table(["Bench safety figure", "This version", "FSMIC"], bench.figures.map((f) => h("tr",
    { class: f.severity ? `flag-${f.severity}` : "", dataset: { figure: f.figure } },
    h("td", {}, f.label), h("td", { class: `num${f.severity ? ` ${f.severity}` : ""}` }, value(f.value, f.unit)),
    h("td", { class: "num" }, value(f.fsmic_value, f.unit)))), { id, class: "compact" });
}
const MIN_OVERRIDE = 20;

// The bench's findings in words: the course's or the table's walk in full, an envelope's node walks counted (the
// preview's "Each node alone" names every one)
export function flagWords(flags) {
  const nodes = flags.filter((f) => f.node_speed_mps !== null && f.node_speed_mps !== undefined);
  const at = new Set(nodes.map((f) => `${f.node_speed_mps},${f.node_incline_deg}`)).size;
  return [...flags.filter((f) => !nodes.includes(f)).map((f) => f.message),
    ...(nodes.length ? [`${nodes.length} figure(s) beyond a bound at ${at} node(s) walked alone at their own task (listed in the preview's “Each node alone”)`] : [])];
}
// what a prosthetist typed in a version's reason box, by who and the version's API path: a redraw of the card (the
// preview finishing, a sign-off elsewhere) or of the page never loses it
const typedReasons = new Map();

// A version the bench finds worse than the one it was made from (an edit or a refinement) says so before anything
// else: each safety figure it makes worse, parent → this
export function worseBanner(bench) {
  const w = bench?.worse_than_parent;
  if (!w?.figures?.length) return null;
  const value = (v, unit) => `${fmt(v, unit === "BW" ? 2 : 0)} ${unit}`;
  return h("div", { class: "banner bad", role: "alert", id: "worse-than-parent" },
    h("strong", {}, `Worse on the bench than v${w.parent_version}, the version it was made from: `),
    w.figures.map((f) => `${f.label} ${value(f.parent_value, f.unit)} → ${value(f.value, f.unit)}`).join("; "),
    ". It is not an improvement on these; look at them before anything else.");
}

// item: the proposal or envelope (status, decision, safety, bench); name: its one name; path: its API path;
// reload: redraw the page after a decision
export function renderDecision(box, { item, name, path, canDecide, reload, worseSlot = null }) {
  box.replaceChildren(h("h2", {}, "Decision"));
  const sayWorse = (bench) => worseSlot?.replaceChildren(...[worseBanner(bench)].filter(Boolean));
  sayWorse(item.bench);
  if (item.status !== "draft") {
    box.append(h("p", {}, `${item.decision.status} by ${item.decision.by} ${when(item.decision.at)}`,
      item.decision.comment ? ` — “${item.decision.comment}”` : "", ". An approved or rejected version never changes; edit it into a new draft instead."));
    if (item.decision.override_reason) {
      box.append(h("p", { class: "banner warn", id: "decision-override" },
        h("strong", {}, "Approved without a clean bench preview, signed off by two prosthetists: "), item.decision.override_reason));
    }
    if (item.withdrawal) {
      box.append(h("p", { class: "banner bad", id: "withdrawn" }, h("strong", {}, "Withdrawn "),
        `by ${item.withdrawal.by} ${when(item.withdrawal.at)}: “${item.withdrawal.reason}”. It is never pushed again.`));
    } else if (item.status === "approved" && canDecide) {
      box.append(withdrawControl({ name, path, reload }));
    }
    return;
  }
  if (!canDecide) {
    box.append(h("p", { class: "muted" }, "Draft. Only a prosthetist can approve or reject it."));
    return;
  }
  let bench = item.bench || { status: "not_walked", words: "bench preview not walked yet", flags: [] };
  const error = h("p", { class: "error", role: "alert" });
  // one reason box: what was reviewed (a clean bench), or the sign-off's reason (an unclean one), or why it is rejected
  const reason = h("textarea", { name: "comment", id: "decision-reason", rows: 2, cols: 60, maxlength: 2000 });
  const typedKey = `${app.me?.username}|${path}`;    // one person's words, never shown to the next who signs in here
  reason.value = typedReasons.get(typedKey) ?? "";    // kept across a redraw of the card or the page
  reason.addEventListener("input", () => typedReasons.set(typedKey, reason.value));
  const reasonLabel = h("span", {});
  const gate = h("div", { id: "bench-gate" });
  const needsOverride = () => bench.status === "unsafe" || bench.status === "not_walked";
  const signed = () => bench.signoffs || [];
  const mine = () => signed().some((x) => x.by === app.me?.username);
  const others = () => signed().filter((x) => x.by !== app.me?.username);
  const complete = () => signed().length >= (bench.signoffs_needed || 2);
  // what this prosthetist may do about an unclean bench: sign off first, approve as the second, or wait for a colleague
  const step = () => (!needsOverride() || complete() ? "approve" : mine() ? "wait" : others().length ? "second" : "first");
  let unsaved = false;   // cells typed into the table and not saved: Approve would approve the stored values
  const unsavedNote = h("p", { class: "banner warn", id: "unsaved-edits", hidden: true },
    "The table has unsaved edits: save them as a new version, or discard them, before deciding.");
  const decide = (what) => async () => {
    error.textContent = "";
    try {
      const text = reason.value.trim();
      const body = { comment: text };
      if (what === "approve" && step() === "second") body.override_reason = text;   // the second sign-off is its reason
      await post(`${path}/${what}`, body);
      typedReasons.delete(typedKey);
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
  const signOff = async () => {
    error.textContent = "";
    try {
      await post(`${path}/signoffs`, { reason: reason.value.trim() });
      typedReasons.delete(typedKey);
      notice(`${name}: your sign-off is recorded; a second prosthetist must sign off from their own account`, "warn");
      await reload();
    } catch (err) {
      error.textContent = err.message;
    }
  };
  const signOffButton = h("button", { id: "signoff", onclick: signOff, disabled: true }, "Sign off (first of two)");
  const approve = h("button", { id: "approve", onclick: decide("approve"), disabled: true }, "Approve");
  const reject = h("button", { id: "reject", class: "secondary", onclick: decide("reject"), disabled: true,
    title: "say why first" }, "Reject");
  const LABELS = {
    approve: "Why (required, audited): what you reviewed ",
    first: `Why go ahead without a clean bench preview: your sign-off, the first of two (at least ${MIN_OVERRIDE} characters; audited and shown with this version) `,
    second: `Why approve anyway: your sign-off, the second of two (at least ${MIN_OVERRIDE} characters; audited and shown with this version) `,
    wait: "Why reject (required, audited) ",
  };
  const update = () => {       // a decision needs its reason, like an edit; an unclean bench needs two sign-offs
    const said = reason.value.trim().length > 0;
    const written = reason.value.trim().length >= MIN_OVERRIDE;
    const now = step();
    reasonLabel.textContent = LABELS[now];
    approve.hidden = now === "first" || now === "wait";
    approve.disabled = !said || !item.safety.ok || unsaved || (now === "second" && !written);
    approve.textContent = now === "second" ? "Sign off and approve (second of two)" : "Approve";
    signOffButton.hidden = now !== "first";
    signOffButton.disabled = !written || !item.safety.ok;
    unsavedNote.hidden = !unsaved;
    approve.title = unsaved ? "unsaved edits in the table: save them as a new version, or discard them"
      : !item.safety.ok ? "outside the parameter limits: cannot be approved"
      : now === "second" && !written ? `write why you go ahead anyway (at least ${MIN_OVERRIDE} characters): your sign-off is the second`
        : "say why first (what you reviewed)";
    signOffButton.title = !item.safety.ok ? "outside the parameter limits: cannot be approved"
      : `write why you go ahead anyway (at least ${MIN_OVERRIDE} characters)`;
    reject.disabled = !said;
    const badFlags = flagWords(bench.flags);
    const signatures = signed().length ? h("ul", { id: "signoffs" }, signed().map((x) => h("li", {},
      h("strong", {}, x.by), ` ${when(x.at)}: “${x.reason}”`))) : null;
    gate.replaceChildren(benchFigures(bench, "decision-figures"), h("p", { id: "decision-bench" }, h("strong", {}, "Bench: "),
      bench.status === "clean" ? "the preview walked clean: no safety figure beyond its bound."
        : bench.status === "unsafe" ? `the preview shows ${bench.flags.length} figure(s) beyond their bounds (below).`
          : "the preview has not finished walking."),
    ...(needsOverride() ? [
      h("p", { class: `banner ${bench.status === "unsafe" ? "bad" : "warn"}` }, h("strong", {}, "Approval rests on the bench: "),
        bench.status === "unsafe" ? badFlags.join("; ")
          : "its preview is still walking (or has not been walked). Wait for it, or two prosthetists sign off going ahead without it",
        ". Going ahead anyway takes two prosthetists' sign-offs, each from their own account with their own reason."),
      ...(signatures ? [signatures] : []),
      now === "wait" ? h("p", { class: "banner warn", id: "signoff-wait" }, "You signed off. A second prosthetist must sign off from their own account before this version can be approved.")
        : now === "approve" ? h("p", { id: "signoff-complete" }, "Two prosthetists signed off: it can be approved.") : null]
      : []).filter(Boolean));
  };
  reason.addEventListener("input", update);
  // the preview finished (on this page): follow the bench's verdict in place
  const walked = async (ev) => {
    if (!box.isConnected) { window.removeEventListener("quasitune:bench-walked", walked); return; }   // page left
    if (ev.detail?.path !== path) return;
    const now = await get(path).catch(() => null);
    if (now?.bench) { bench = now.bench; sayWorse(bench); update(); }
  };
  window.addEventListener("quasitune:bench-walked", walked);
  const edited = (ev) => {
    if (!box.isConnected) { window.removeEventListener("quasitune:unsaved-edits", edited); return; }
    unsaved = Boolean(ev.detail?.unsaved);
    update();
  };
  window.addEventListener("quasitune:unsaved-edits", edited);
  update();
  box.append(gate, h("label", { class: "block" }, reasonLabel, reason),
    h("div", { class: "inline" }, approve, signOffButton, reject), unsavedNote, error);
}

// Withdraw an approved version (prosthetist): asks why, then says what happened to every leg that ran it
function withdrawControl({ name, path, reload }) {
  const error = h("p", { class: "error", role: "alert" });
  const go = async () => {
    const reason = await confirmDialog({ id: "withdraw-dialog", title: `Withdraw ${name}?`, danger: true, confirm: "Withdraw",
      facts: [["What it does", "It is never pushed again. A leg running it is sent back to the last version it ran that was not withdrawn, or put in safe mode."],
        ["The approval", "stays as it was decided; the withdrawal is recorded beside it (audited)."]],
      reason: { label: "Why it is withdrawn", min: 10 } });
    if (!reason) return;
    error.textContent = "";
    try {
      const out = await post(`${path}/withdraw`, { reason });
      const legs = out.legs.map((l) => `${l.device_id}: ${l.detail}`).join("; ");
      notice(`${name} withdrawn${legs ? ` — ${legs}` : " (no leg ran it)"}`, "warn");
      await reload();
    } catch (err) {
      error.textContent = err.message;
    }
  };
  return h("div", { id: "withdraw-box" }, h("p", { class: "muted small" },
    "Withdraw it if it should not be worn any more (a fault found, a patient's report): every leg running it goes back."),
  h("button", { id: "withdraw", class: "danger", onclick: go }, "Withdraw…"), error);
}
