// A map of one envelope value over speed × incline (SVG): a cell per node coloured by its value, the value printed
// with its unit, nodes outside the training data hatched, the measured walking conditions as dots, and (live
// monitor) the leg's estimated task as a moving point with a short trail. Speed runs left → right (m/s), incline
// bottom → top (deg, + uphill).
import { fmt } from "../ui.js";

const NS = "http://www.w3.org/2000/svg";
const W = 300, H = 262, L = 44, R = 8, T = 24, B = 64;

function s(tag, attrs = {}, text) {
  const el = document.createElementNS(NS, tag);
  for (const [k, v] of Object.entries(attrs)) if (v !== undefined && v !== null) el.setAttribute(k, v);
  if (text !== undefined) el.textContent = text;
  return el;
}

// Colour of a value between lo and hi: light to dark blue (one hue: the map shows size, not good or bad). Darkness
// reads the same way on every map: ``darker`` "low" makes the lowest value darkest, "high" the highest (resistance K
// and damping: the firmest; angles: the most flexed or dorsiflexed)
function darkness(v, lo, hi, darker) {
  const f = hi > lo ? (v - lo) / (hi - lo) : 0.5;
  return darker === "low" ? 1 - f : f;
}

function shade(f) {
  return `hsl(214, 60%, ${(92 - 52 * f).toFixed(0)}%)`;
}

// Cell edges halfway between nodes, the outer ones half a spacing beyond the edge nodes
function edges(axis) {
  const mids = axis.slice(1).map((x, k) => (x + axis[k]) / 2);
  const first = axis.length > 1 ? axis[0] - (mids[0] - axis[0]) : axis[0] - 0.5;
  const last = axis.length > 1 ? axis.at(-1) + (axis.at(-1) - mids.at(-1)) : axis[0] + 0.5;
  return [first, ...mids, last];
}

export function envelopeMap(el, { title, speeds, inclines, values, unit, digits = 0, extrapolated = null,
  measured = [], onPick = null, selected = null, id = null, darker = "high", keyWords = "darker = higher",
  marks = null }) {
  const ex = edges(speeds), ey = edges(inclines);
  const x = (v) => L + (v - ex[0]) / (ex.at(-1) - ex[0]) * (W - L - R);
  const y = (g) => H - B - (g - ey[0]) / (ey.at(-1) - ey[0]) * (H - T - B);
  const flat = values.flat().filter((v) => v !== null && Number.isFinite(v));
  const lo = Math.min(...flat), hi = Math.max(...flat);
  const svg = s("svg", { viewBox: `0 0 ${W} ${H}`, class: "envelope-map", role: "img", id,
    "aria-label": `${title}: ${fmt(lo, digits)} to ${fmt(hi, digits)} ${unit} over ${speeds.length} speeds × ${inclines.length} inclines` });
  const defs = s("defs");
  const hatch = s("pattern", { id: `hatch-${id || title.replace(/\W/g, "")}`, width: 6, height: 6, patternUnits: "userSpaceOnUse",
    patternTransform: "rotate(45)" });
  hatch.append(s("line", { x1: 0, y1: 0, x2: 0, y2: 6, stroke: "#b35c00", "stroke-width": 1.5 }));
  defs.append(hatch);
  svg.append(defs, s("text", { x: L, y: 15, class: "map-title" }, title));
  const cellText = [];
  speeds.forEach((v, i) => inclines.forEach((g, j) => {
    const val = values[i][j];
    const g0 = s("g", { class: "node", dataset: null, "data-node": `${i},${j}`, tabindex: onPick ? 0 : null,
      role: onPick ? "button" : null, "aria-label": `${fmt(v, 2)} m/s, ${fmt(g, 1)}°: ${fmt(val, digits)} ${unit}` });
    const rect = { x: x(ex[i]), y: y(ey[j + 1]), width: x(ex[i + 1]) - x(ex[i]), height: y(ey[j]) - y(ey[j + 1]) };
    const f = val === null ? null : darkness(val, lo, hi, darker);
    g0.append(s("rect", { ...rect, fill: f === null ? "#eee" : shade(f), stroke: "#fff", "stroke-width": 1 }));
    if (extrapolated?.[i]?.[j]) g0.append(s("rect", { ...rect, fill: `url(#hatch-${id || title.replace(/\W/g, "")})`, opacity: 0.55, class: "extrapolated" }));
    if (selected && selected[0] === i && selected[1] === j) {
      g0.append(s("rect", { ...rect, fill: "none", stroke: "#111", "stroke-width": 2.5, class: "selected" }));
    }
    const mark = marks?.[i]?.[j];
    if (mark?.held) {   // a value held at a limit, the support floor or the neighbour rule: a corner flag
      const x1 = rect.x + rect.width, y1 = rect.y;
      const flag = s("path", { d: `M${x1 - 9},${y1} L${x1},${y1} L${x1},${y1 + 9} Z`, class: "held-mark" });
      flag.append(s("title", {}, `held: ${mark.held}`));
      g0.append(flag);
    }
    if (mark?.weak) {   // a weak fit (R² below the threshold): a dashed outline
      g0.append(s("rect", { x: rect.x + 2, y: rect.y + 2, width: rect.width - 4, height: rect.height - 4, fill: "none",
        class: "weak-mark" }));
    }
    cellText.push([g0, x(v), y(g), val, f]);
    if (onPick) {
      g0.addEventListener("click", () => onPick(i, j));
      g0.addEventListener("keydown", (ev) => { if (ev.key === "Enter" || ev.key === " ") { ev.preventDefault(); onPick(i, j); } });
    }
    svg.append(g0);
  }));
  for (const m of measured) {
    if (m.speed_mps === null || m.incline_deg === null) continue;
    if (m.speed_mps < ex[0] || m.speed_mps > ex.at(-1) || m.incline_deg < ey[0] || m.incline_deg > ey.at(-1)) continue;
    const dot = s("circle", { cx: x(m.speed_mps), cy: y(m.incline_deg), r: 3.2, class: "measured" });
    dot.append(s("title", {}, `measured: ${m.label}`));
    svg.append(dot);
  }
  // values last, over the dots, with a halo of their cell's colour
  for (const [, cx, cy, val, f] of cellText) {
    const dark = f !== null && f > 0.55;
    // the value sits just above the node's centre and a measured condition's dot at its task (level walking and the
    // ramps lie on the node rows' centres), so a dot never covers a digit
    const text = s("text", { x: cx, y: cy - 3, class: `cell-value${dark ? " on-dark" : ""}`, "text-anchor": "middle",
      stroke: f === null ? "#eee" : shade(f) }, fmt(val, digits));
    svg.append(text);
  }
  // axes: node positions as ticks
  speeds.forEach((v) => svg.append(s("text", { x: x(v), y: H - B + 14, class: "tick", "text-anchor": "middle" }, fmt(v, 2))));
  // each node's own incline (an 8-node axis over ±10° has −7.1°, not "−7")
  inclines.forEach((g) => svg.append(s("text", { x: L - 4, y: y(g) + 4, class: "tick", "text-anchor": "end" }, String(Number(g.toFixed(1))))));
  // the colour key: the map's range, its unit, and which way darker reads
  const gid = `key-${id || title.replace(/\W/g, "")}`;
  const grad = s("linearGradient", { id: gid, x1: 0, x2: 1, y1: 0, y2: 0 });
  for (let k = 0; k <= 4; k += 1) {
    grad.append(s("stop", { offset: `${k * 25}%`, "stop-color": shade(darker === "low" ? 1 - k / 4 : k / 4) }));
  }
  defs.append(grad);
  const keyY = H - 24;
  svg.append(s("rect", { x: L, y: keyY, width: W - L - R, height: 7, fill: `url(#${gid})`, stroke: "#999", "stroke-width": 0.5,
    class: "colour-key" }),
  s("text", { x: L, y: keyY + 17, class: "tick key-lo", "text-anchor": "start" }, fmt(lo, digits)),
  s("text", { x: W - R, y: keyY + 17, class: "tick key-hi", "text-anchor": "end" }, fmt(hi, digits)),
  s("text", { x: (L + W - R) / 2, y: keyY + 17, class: "tick key-words", "text-anchor": "middle" }, `${unit} · ${keyWords}`));
  svg.append(s("text", { x: (L + W - R) / 2, y: H - B + 27, class: "axis", "text-anchor": "middle" }, "speed (m/s)"),
    s("text", { x: 10, y: (T + H - B) / 2, class: "axis", "text-anchor": "middle", transform: `rotate(-90 10 ${(T + H - B) / 2})` },
      "incline (deg)"));
  const trail = s("polyline", { class: "trail", fill: "none", points: "" });
  const point = s("circle", { class: "task-point", r: 6, visibility: "hidden" });
  svg.append(trail, point);
  el.replaceChildren(svg);
  // the live point: clamped to the drawn area; returns nothing
  const clampX = (v) => Math.min(Math.max(x(v), L), W - R), clampY = (g) => Math.min(Math.max(y(g), T), H - B);
  return {
    setTrail(tasks) {   // [[speed, incline], …], oldest first; the last is the point now
      if (!tasks.length) {
        point.setAttribute("visibility", "hidden");
        trail.setAttribute("points", "");
        return;
      }
      trail.setAttribute("points", tasks.map(([v, g]) => `${clampX(v).toFixed(1)},${clampY(g).toFixed(1)}`).join(" "));
      const [v, g] = tasks.at(-1);
      point.setAttribute("cx", clampX(v).toFixed(1));
      point.setAttribute("cy", clampY(g).toFixed(1));
      point.setAttribute("visibility", "visible");
    },
    svg,
  };
}

// The map's values for one envelope field: values[i][j] from nodes (speed-major), and the extrapolation flags
export function nodeGrid(envelope, pick) {
  const ni = envelope.inclines_deg.length;
  return envelope.speeds_mps.map((_, i) => envelope.inclines_deg.map((__, j) => pick(envelope.nodes[i * ni + j])));
}
