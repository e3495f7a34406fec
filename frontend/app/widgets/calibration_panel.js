// Guided calibration of a real leg from the monitor: the leg's own prompts, the leg measuring each step and saying what
// it measured or why it refused (POST /api/devices/{id}/calibration), then kept on the leg or cancelled.
import { post } from "../api.js";
import { chip, confirmDialog, fmt, h, notice } from "../ui.js";

const STEPS = [
  ["joint_zero", "Joint zero"],
  ["direction", "Direction"],
  ["loadcell_zero", "Load cell zero"],
  ["loadcell_sign", "Load cell sign"],
];

export function calibrationPanel(box, deviceId) {
  let session = null;            // { results: {step: answer}, current: index } while a calibration runs
  let status = null;
  const stateLine = h("p", { id: "calibration-state" });
  const start = h("button", { id: "calibration-start", onclick: () => begin() }, "Start calibration…");
  const list = h("ol", { id: "calibration-steps", class: "steps" });
  const measure = h("button", { id: "calibration-measure", onclick: () => measureStep() }, "Measure");
  const keep = h("button", { id: "calibration-keep", onclick: () => finish("keep") }, "Keep this calibration on the leg");
  const cancel = h("button", { id: "calibration-cancel", class: "secondary", onclick: () => finish("cancel") }, "Cancel calibration");
  const running = h("div", { id: "calibration-running", hidden: true }, list, h("div", { class: "inline" }, measure, keep, cancel));
  box.replaceChildren(h("h2", {}, "Calibration"), stateLine,
    h("p", { class: "muted small" }, "The leg measures each step itself from its own sensors and refuses a result that ",
      "cannot be right (a joint that moved, a reversed or offset sensor beyond its range, an unloaded or overloaded cell), ",
      "saying what it measured. It gives no torque at all while it calibrates: start only with the leg in its stand and in ",
      "safe mode (or with no table). Kept, the calibration is written on the leg and used from then on; cancelled, the ",
      "leg keeps the one it had. Either way it ends in safe mode."),
    start, running);

  const render = () => {
    const leg = status?.leg;
    const parts = leg ? [["knee", leg.knee_calibrated], ["ankle", leg.ankle_calibrated], ["load cell", leg.loadcell_calibrated]] : [];
    const missing = parts.filter(([, ok]) => !ok).map(([name]) => name);
    stateLine.replaceChildren("On the leg now: ", missing.length ? chip(`not calibrated: ${missing.join(", ")}`, "bad")
      : chip("knee, ankle and load cell calibrated", "ok"),
      status?.mode === "calibrating" ? h("span", {}, " ", chip("calibrating: no torque", "warn")) : "");
    const startable = status?.online && ["safe", "no_table", "calibrating"].includes(status.mode);
    start.disabled = !startable || session !== null;
    start.title = !status?.online ? "the device is offline" : startable ? "" : "put the leg in safe mode first (it runs a table)";
    running.hidden = session === null;
    if (session === null) return;
    list.replaceChildren(...STEPS.map(([step, name], i) => {
      const a = session.results[step];
      const now = i === session.current;
      return h("li", { id: `calibration-${step}`, class: now ? "current" : "" },
        h("strong", {}, name), " ",
        a ? chip(a.outcome === "accepted" ? "accepted" : "refused", a.outcome === "accepted" ? "ok" : "bad") : "",
        now && session.prompt ? h("p", { class: "prompt" }, "Do this, then measure: ", h("em", {}, session.prompt)) : "",
        a ? h("ul", { class: "measured" }, ...(a.outcome === "accepted" ? a.measured : []).map((m) => h("li", {}, m.words)),
          a.outcome === "refused" ? h("li", { class: "error" }, a.refused_words) : "",
          step === "loadcell_sign" && a.body_mass_kg !== null ? h("li", { class: "muted" }, `read against the patient's ${fmt(a.body_mass_kg, 1, "kg")}`) : "") : "");
    }));
    const done = STEPS.every(([step]) => session.results[step]?.outcome === "accepted");
    const current = STEPS[session.current];
    measure.hidden = done || !current;
    if (current) measure.textContent = session.results[current[0]]?.outcome === "refused" ? `Measure ${current[1].toLowerCase()} again` : `Measure ${current[1].toLowerCase()}`;
    keep.disabled = !done;
  };

  async function send(body) {
    try {
      return await post(`/api/devices/${deviceId}/calibration`, body);
    } catch (err) {
      notice(err.message);
      return null;
    }
  }

  async function begin() {
    const ok = await confirmDialog({ id: "calibration-dialog", title: `Calibrate ${deviceId}?`,
      facts: [["What changes", "the leg gives no torque at all until the calibration is kept or cancelled"],
        ["Steps", "joint zero, direction (moved by hand), load cell unloaded, the patient standing on it"]],
      requires: "The leg is in its stand, in safe mode; the patient holds the parallel bars for the last step.",
      confirm: "Start calibration" });
    if (!ok) return;
    const a = await send({ action: "start" });
    if (!a) return;
    if (a.outcome === "refused") { notice(`The leg refused to calibrate: ${a.refused_words}`); return; }
    session = { results: {}, current: 0, prompt: a.next_prompt };
    render();
  }

  async function measureStep() {
    const [step] = STEPS[session.current];
    measure.disabled = true;
    const a = await send({ action: "measure", step });
    measure.disabled = false;
    if (!a || session === null) return;
    if (a.refused_reason === "not_started") {     // the calibration ended on the leg meanwhile
      session = null;
      notice(`The leg: ${a.refused_words}`);
      render();
      return;
    }
    session.results[step] = a;
    // accepted: later steps are measured again (the leg dropped them: they were read from this one)
    STEPS.slice(session.current + 1).forEach(([later]) => { if (a.outcome === "accepted") delete session.results[later]; });
    if (a.outcome === "accepted" && a.next_step) {
      session.current += 1;
      session.prompt = a.next_prompt;
    } else if (a.outcome === "accepted") {
      session.current = STEPS.length;
      session.prompt = null;
    } else {
      session.prompt = a.prompt;
    }
    render();
  }

  async function finish(action) {
    const a = await send({ action });
    if (!a) return;
    if (a.outcome === "refused") { notice(`The leg: ${a.refused_words}`); return; }
    session = null;
    notice(action === "keep" ? "Calibration kept on the leg and used from now on; the leg is in safe mode."
      : "Calibration cancelled: the leg keeps the calibration it had; it is in safe mode.", "warn");
    render();
  }

  return {
    update(d) {
      const left = session !== null && status?.mode === "calibrating" && d.mode !== "calibrating";
      status = d;
      if (left) {
        session = null;
        notice(`The calibration ended on the leg without being kept (it is now ${d.safe_mode ? "in safe mode" : d.mode}: `
          + "a lost link, a hardware fault or a safe-mode command); start again.");
      }
      render();
    },
  };
}
