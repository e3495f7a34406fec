// How every setting of a version is shown, the same on every page (table, diff, maps, node pages, live panel, edits).
// Stiffness is shown as resistance, K = −k: a larger K is firmer, as C-Soft, Össur's Logic and the Open Source Leg
// SDK's τ = −K(θ − θe) − b·θ̇ present it. The API keeps the paper's signed k_Nm_per_rad (τ = k(θ − θe), negative
// resists); only the screen turns it. Loads are % body weight in the clinical view, N in the engineering view.
import { bodyWeightN, fmt } from "./ui.js";

const RAD = Math.PI / 180;

// kept across versions and visits: the stiffness unit (per rad or per deg) and the clinical / engineering view
export const tableView = {
  kUnit: localStorage.getItem("quasitune.kUnit") || "rad",
  view: localStorage.getItem("quasitune.view") || "clinical",
};

export const EQUATION = "τ = −K·(θ − θe) − b·θ̇";
export const EQUATION_WORDS = "K is the resistance to moving away from θe (K = −k of the paper's τ = k(θ − θe)): a "
  + "larger K is firmer, a negative K would push the joint instead of resisting it. b is damping.";

// scale from SI to the shown unit, the unit, digits, and what kind of quantity it is (angles get no percent change)
export function units(field, mass) {
  const deg = tableView.kUnit === "deg";
  const clinical = tableView.view === "clinical";
  if (field.endsWith("k_Nm_per_rad")) {
    return deg ? { scale: -RAD, unit: "N·m/deg", digits: 3, kind: "stiffness" }
      : { scale: -1, unit: "N·m/rad", digits: 1, kind: "stiffness" };
  }
  if (field.endsWith("b_Nm_s_per_rad")) {
    return deg ? { scale: RAD, unit: "N·m·s/deg", digits: 4, kind: "damping" } : { scale: 1, unit: "N·m·s/rad", digits: 2, kind: "damping" };
  }
  if (field.endsWith("_deg_per_s")) return { scale: 1, unit: "deg/s", digits: 0, kind: "rate" };
  if (field.endsWith("_deg")) return { scale: 1, unit: "deg", digits: 1, kind: "angle" };
  if (field.endsWith("_load_N")) {
    return clinical && mass ? { scale: 100 / bodyWeightN(mass), unit: "% body weight", digits: 1, kind: "load" }
      : { scale: 1, unit: "N", digits: 0, kind: "load" };
  }
  if (field.endsWith("_Nm")) return { scale: 1, unit: "N·m", digits: 1, kind: "moment" };
  if (field.endsWith("_s")) return { scale: 1, unit: "s", digits: 3, kind: "time" };
  if (field.endsWith("_pct")) return { scale: 1, unit: "%", digits: 0, kind: "share" };
  return { scale: 1, unit: "", digits: 3, kind: "other" };
}

// the shown value of an SI value, as text without its unit
export function shownNumber(field, si, mass) {
  if (si === null || si === undefined || typeof si !== "number") return si ?? "—";
  const u = units(field, mass);
  return fmt(si * u.scale + 0, u.digits);   // + 0: never "-0.0"
}

// a limit {low, high} (SI) in the shown unit, lowest first (the resistance turns k's bounds around)
export function shownRange(lim, u) {
  const [a, b] = [lim.low * u.scale, lim.high * u.scale].sort((x, y) => x - y);
  return `${fmt(a + 0, u.digits)} … ${fmt(b + 0, u.digits)}`;
}

// a shown value typed back into SI (edits)
export function toSI(field, shown, mass) {
  return shown / units(field, mass).scale;
}

// a change between two SI values as shown: the difference in the shown unit, and its percent of the shown value
// before (with the change's own sign; none for angles, whose zero is a posture, not "none", nor from zero)
export function shownChange(field, before, after, mass) {
  const u = units(field, mass);
  const a = before * u.scale, b = after * u.scale;
  const percent = u.kind === "angle" || a === 0 ? null : (100 * (b - a)) / Math.abs(a);
  return { change: b - a, percent, unit: u.unit, digits: u.digits };
}

// a change with its sign ("+2.0", "-1.5", "0.0" for what rounds to nothing; "—" for none)
export function signed(v, digits = 1) {
  if (v === null || v === undefined) return "—";
  const s = fmt(v + 0, digits);
  return v > 0 && s !== fmt(0, digits) ? `+${s}` : s;
}
