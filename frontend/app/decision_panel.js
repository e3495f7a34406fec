// The "Decision" card of a table or an envelope: approve or reject a draft once, with the reason (audited). A version
// outside the safety limits cannot be approved; a decided version never changes.
import { post } from "./api.js";
import { h, notice, when } from "./ui.js";

// item: the proposal or envelope (status, decision, safety); name: its one name; path: its API path; reload: redraw
export function renderDecision(box, { item, name, path, canDecide, reload }) {
  box.replaceChildren(h("h2", {}, "Decision"));
  if (item.status !== "draft") {
    box.append(h("p", {}, `${item.decision.status} by ${item.decision.by} ${when(item.decision.at)}`,
      item.decision.comment ? ` — “${item.decision.comment}”` : "", ". An approved or rejected version never changes; edit it into a new draft instead."));
    return;
  }
  if (!canDecide) {
    box.append(h("p", { class: "muted" }, "Draft. Only a prosthetist can approve or reject it."));
    return;
  }
  const error = h("p", { class: "error", role: "alert" });
  const comment = h("input", { name: "comment", maxlength: 2000, size: 50, "aria-label": "Decision comment" });
  const decide = (what) => async () => {
    error.textContent = "";
    try {
      await post(`${path}/${what}`, { comment: comment.value });
      notice(`${name} ${what === "approve" ? "approved" : "rejected"}`, "ok");
      await reload();
    } catch (err) {
      error.textContent = err.message;
    }
  };
  const approve = h("button", { id: "approve", onclick: decide("approve"), disabled: true,
    title: item.safety.ok ? "say why first (what you reviewed)" : "outside the safety limits: cannot be approved" }, "Approve");
  const reject = h("button", { id: "reject", class: "secondary", onclick: decide("reject"), disabled: true,
    title: "say why first" }, "Reject");
  comment.addEventListener("input", () => {       // a decision needs its reason, like an edit
    const said = comment.value.trim().length > 0;
    approve.disabled = !said || !item.safety.ok;
    reject.disabled = !said;
  });
  box.append(h("div", { class: "inline" }, h("label", {}, "Why (required, audited) ", comment), approve, reject), error);
}
