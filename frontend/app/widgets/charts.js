// Charts: uPlot (npm) for signals over the gait cycle or over time; an SVG of our own for torque-angle loops,
// which are closed x-y curves (uPlot wants x sorted).
import uPlot from "/vendor/uplot/uPlot.esm.js";
import { h } from "../ui.js";

const BAND_ALPHA = "33";

function sized(el, height) {
  return { width: Math.max(260, Math.floor(el.clientWidth || 400)), height };
}

function keepSized(el, plot, height) {
  const ro = new ResizeObserver(() => plot.setSize(sized(el, height)));
  ro.observe(el);
  return ro;
}

// Dotted vertical lines at given x (e.g. sub-phase boundaries in % of the gait cycle).
function markerHook(xs) {
  return (u) => {
    const { ctx } = u;
    ctx.save();
    ctx.strokeStyle = "#666";
    ctx.setLineDash([3, 4]);
    for (const x of xs) {
      const px = u.valToPos(x, "x", true);
      ctx.beginPath();
      ctx.moveTo(px, u.bbox.top);
      ctx.lineTo(px, u.bbox.top + u.bbox.height);
      ctx.stroke();
    }
    ctx.restore();
  };
}

// A signal over the gait cycle: lines, ±SD bands (mean, sd) and vertical markers.
export function phaseChart(el, { title, xLabel = "gait cycle (%)", yLabel, x, lines = [], bands = [], markers = [],
  height = 220 }) {
  const data = [x];
  const series = [{ label: xLabel }];
  const uBands = [];
  for (const b of bands) {
    const hi = b.mean.map((m, i) => m + b.sd[i]);
    const lo = b.mean.map((m, i) => m - b.sd[i]);
    data.push(hi, lo);
    series.push({ label: `${b.label} +1 SD`, stroke: b.color + "00", width: 0, points: { show: false } },
      { label: `${b.label} −1 SD`, stroke: b.color + "00", width: 0, points: { show: false } });
    uBands.push({ series: [data.length - 2, data.length - 1], fill: b.color + BAND_ALPHA });
  }
  for (const l of lines) {
    data.push(l.values);
    series.push({ label: l.label, stroke: l.color, width: l.width || 2, dash: l.dash, points: { show: false },
      spanGaps: true });
  }
  const opts = {
    title, ...sized(el, height), series, bands: uBands, legend: { show: false },
    scales: { x: { time: false } },
    axes: [{ label: xLabel }, { label: yLabel, size: 60 }],
    hooks: markers.length ? { draw: [markerHook(markers)] } : {},
  };
  const plot = new uPlot(opts, data, el);
  keepSized(el, plot, height);
  el.append(legend(lines.map((l) => [l.color, l.label, l.dash ? "dash" : "line"])
    .concat(bands.map((b) => [b.color, `${b.label} ±1 SD`, "band"]))));
  return plot;
}

// A live strip chart over the last `windowS` seconds; `push` appends, drawing happens once per animation frame.
export function liveChart(el, { title, yLabel, lines, windowS = 5, rateHz = 100, height = 200, yRange }) {
  const n = Math.round(windowS * rateHz);
  const buf = [[], ...lines.map(() => [])];
  const series = [{ label: "t (s)" }, ...lines.map((l) => ({ label: l.label, stroke: l.color, width: 1.5,
    points: { show: false }, ...(l.dash ? { dash: [6, 4] } : {}) }))];
  const opts = {
    title, ...sized(el, height), series, legend: { show: false },
    scales: { x: { time: false }, ...(yRange ? { y: { range: yRange } } : {}) },
    axes: [{ label: "time (s)" }, { label: yLabel, size: 60 }],
  };
  const plot = new uPlot(opts, buf, el);
  keepSized(el, plot, height);
  el.append(legend(lines.map((l) => [l.color, l.label, l.dash ? "dash" : "line"])));
  let dirty = false;
  return {
    plot,
    push(t, values) {
      buf[0].push(t);
      values.forEach((v, i) => buf[i + 1].push(v));
      if (buf[0].length > n) buf.forEach((a) => a.splice(0, a.length - n));
      dirty = true;
    },
    draw() {
      if (!dirty) return false;
      plot.setData(buf);
      dirty = false;
      return true;
    },
  };
}

const SVG = "http://www.w3.org/2000/svg";
function s(tag, attrs = {}, ...children) {
  const el = document.createElementNS(SVG, tag);
  for (const [k, v] of Object.entries(attrs)) if (v !== undefined && v !== null) el.setAttribute(k, v);
  for (const c of children.flat()) {
    if (c !== null && c !== undefined && c !== false) el.append(c instanceof Node ? c : document.createTextNode(String(c)));
  }
  return el;
}

function niceTicks(lo, hi, count = 6) {
  const step0 = (hi - lo) / count;
  const mag = 10 ** Math.floor(Math.log10(step0));
  const step = [1, 2, 5, 10].map((m) => m * mag).find((st) => st >= step0) || mag * 10;
  const out = [];
  for (let v = Math.ceil(lo / step) * step; v <= hi + 1e-9; v += step) out.push(+v.toFixed(6));
  return out;
}

// Torque-angle loop: reference loops (grey), the proposal with its ±1 SD band (moment SD drawn along the loop),
// via-points, and straight regression lines per sub-phase. Points are [angle_deg, moment].
export function loopChart(el, { title, xLabel, yLabel, reference = [], mean, band, vias = [], lines = [] }) {
  const W = 520, H = 380, L = 62, R = 12, T = 28, B = 46;
  const all = [...mean, ...reference.flatMap((r) => r.points), ...(band ? [...band.upper, ...band.lower] : []),
    ...vias.map((v) => v.point)];
  let [x0, x1] = [Math.min(...all.map((p) => p[0])), Math.max(...all.map((p) => p[0]))];
  let [y0, y1] = [Math.min(...all.map((p) => p[1])), Math.max(...all.map((p) => p[1]))];
  const px = (x1 - x0) * 0.05 || 1, py = (y1 - y0) * 0.06 || 1;
  x0 -= px; x1 += px; y0 -= py; y1 += py;
  const X = (v) => L + ((v - x0) / (x1 - x0)) * (W - L - R);
  const Y = (v) => T + (1 - (v - y0) / (y1 - y0)) * (H - T - B);
  const path = (pts) => pts.map((p, i) => `${i ? "L" : "M"}${X(p[0]).toFixed(1)},${Y(p[1]).toFixed(1)}`).join("");
  const svg = s("svg", { viewBox: `0 0 ${W} ${H}`, class: "loop", role: "img", "aria-label": title });
  svg.append(s("title", {}, title));
  const grid = s("g", { class: "grid" });
  for (const t of niceTicks(x0, x1)) {
    grid.append(s("line", { x1: X(t), x2: X(t), y1: T, y2: H - B }),
      s("text", { x: X(t), y: H - B + 16, "text-anchor": "middle" }, t));
  }
  for (const t of niceTicks(y0, y1)) {
    grid.append(s("line", { x1: L, x2: W - R, y1: Y(t), y2: Y(t) }),
      s("text", { x: L - 6, y: Y(t) + 4, "text-anchor": "end" }, t));
  }
  svg.append(grid,
    s("text", { x: (L + W - R) / 2, y: H - 8, "text-anchor": "middle", class: "axis-label" }, xLabel),
    s("text", { x: 14, y: (T + H - B) / 2, transform: `rotate(-90 14 ${(T + H - B) / 2})`, "text-anchor": "middle",
      class: "axis-label" }, yLabel),
    s("text", { x: L, y: 18, class: "chart-title" }, title));
  for (const r of reference) {
    svg.append(s("path", { d: path(r.points), class: r.nearest ? "ref ref-near" : "ref" },
      s("title", {}, r.label)));
  }
  if (band) {
    const g = s("g", { class: "band" });
    for (let i = 0; i + 1 < band.upper.length; i++) {
      g.append(s("path", { d: path([band.upper[i], band.upper[i + 1], band.lower[i + 1], band.lower[i]]) + "Z" }));
    }
    svg.append(g);
  }
  svg.append(s("path", { d: path(mean), class: "mean" }));
  for (const l of lines) {
    svg.append(s("path", { d: path(l.points), class: "fit", stroke: l.color }, s("title", {}, l.label)));
  }
  for (const v of vias) {
    svg.append(s("path", {
      d: `M${X(v.point[0])},${Y(v.point[1]) - 7}l2,5h5l-4,3l2,6l-5,-4l-5,4l2,-6l-4,-3h5z`, class: "via" },
    s("title", {}, v.label)));
  }
  el.replaceChildren(svg);
  return svg;
}

export function legend(items) {
  return h("ul", { class: "legend" }, items.map(([colour, label, kind = "line"]) =>
    h("li", {}, h("span", { class: `swatch ${kind}`, style: `--c:${colour}` }), label)));
}
