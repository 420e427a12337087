// Small DOM, formatting and plotting helpers shared by the pages.

// h("div", {class: "card", onclick: fn}, child, "text", [more children])
export function h(tag, attrs = {}, ...children) {
  const node = document.createElement(tag);
  for (const [name, value] of Object.entries(attrs || {})) {
    if (value === undefined || value === null || value === false) continue;
    if (name.startsWith("on") && typeof value === "function") {
      node.addEventListener(name.slice(2), value);
    } else if (name === "dataset") {
      Object.assign(node.dataset, value);
    } else if (value === true) {
      node.setAttribute(name, "");
    } else {
      node.setAttribute(name, String(value));
    }
  }
  append(node, children);
  return node;
}

// Appends children, flattening arrays and skipping null, undefined and false.
export function put(node, ...children) {
  append(node, children);
  return node;
}

function append(node, children) {
  for (const child of children) {
    if (child === undefined || child === null || child === false) continue;
    if (Array.isArray(child)) append(node, child);
    else node.append(child instanceof Node ? child : document.createTextNode(String(child)));
  }
}

export function clear(node) {
  while (node.firstChild) node.removeChild(node.firstChild);
  return node;
}

export function fmt(value, digits = 3) {
  if (value === null || value === undefined || Number.isNaN(value)) return "–";
  if (typeof value !== "number") return String(value);
  if (Number.isInteger(value) && Math.abs(value) < 1e6) return value.toLocaleString("en");
  const abs = Math.abs(value);
  if (abs !== 0 && (abs < 1e-3 || abs >= 1e6)) return value.toExponential(digits - 1);
  return value.toFixed(digits);
}

// A score in [0, 1] (F1, accuracy) always with three decimals.
export function score(value) {
  return typeof value === "number" && Number.isFinite(value) ? value.toFixed(3) : "–";
}

export function duration(startIso, endIso) {
  if (!startIso) return "–";
  const end = endIso ? new Date(endIso) : new Date();
  let seconds = Math.max(0, (end - new Date(startIso)) / 1000);
  if (seconds < 60) return `${seconds.toFixed(seconds < 10 ? 1 : 0)} s`;
  const minutes = Math.floor(seconds / 60);
  seconds = Math.round(seconds - 60 * minutes);
  if (minutes < 60) return `${minutes} min ${seconds} s`;
  return `${Math.floor(minutes / 60)} h ${minutes % 60} min`;
}

export function when(iso) {
  return iso ? new Date(iso).toLocaleString() : "–";
}

export function statusBadge(status) {
  return h("span", { class: `badge status-${status}` }, status);
}

export function progressBar(fraction, status) {
  const percent = Math.round(100 * Math.min(1, Math.max(0, fraction || 0)));
  return h(
    "div",
    { class: `progress status-${status}`, role: "progressbar", "aria-valuenow": percent, "aria-valuemin": 0, "aria-valuemax": 100, title: `${percent} %` },
    h("div", { class: "progress-fill", style: `width: ${percent}%` }),
    h("span", { class: "progress-text" }, `${percent} %`),
  );
}

// A message box for an error or a notice; `errors` are the service's {loc, msg} items.
export function messageBox(kind, text) {
  return h("div", { class: `message ${kind}`, role: kind === "error" ? "alert" : "status" }, text);
}

export function showError(container, error) {
  clear(container);
  container.append(messageBox("error", error.message || String(error)));
}

// Puts each of the service's 422 messages next to the form field its `loc` names, and
// the rest (or all, when no field matches) into `general`. `fields` maps a dotted path
// suffix (e.g. "thrusters.levels" or "inertia_candidates.1") to the element to mark.
export function showFieldErrors(error, fields, general) {
  for (const old of document.querySelectorAll(".field-error")) old.remove();
  for (const old of document.querySelectorAll(".invalid")) old.classList.remove("invalid");
  clear(general);
  const unplaced = [];
  for (const item of error.errors && error.errors.length ? error.errors : [{ loc: [], msg: error.message }]) {
    const path = item.loc.filter((p) => p !== "body" && p !== "scenario" && p !== "overrides").join(".");
    let best = null;
    for (const [name, element] of Object.entries(fields)) {
      if (path === name || path.startsWith(`${name}.`) || path.endsWith(`.${name}`)) {
        if (!best || name.length > best[0].length) best = [name, element];
      }
    }
    if (best) {
      const element = best[1];
      element.classList.add("invalid");
      const note = h("div", { class: "field-error", role: "alert" }, item.msg);
      // A table row gets its message in a row of its own, under it.
      element.after(element.tagName === "TR" ? h("tr", { class: "field-error" }, h("td", { colspan: 99 }, note)) : note);
    } else {
      unplaced.push(item.msg);
    }
  }
  if (unplaced.length) general.append(messageBox("error", unplaced.join("\n")));
}

// Plotly: one look for every chart.
export const COLORS = ["#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b", "#e377c2", "#17becf", "#7f7f7f", "#bcbd22"];

// Light for 0, dark blue for 1 (plotly's "Blues" runs the other way).
export const HEAT_SCALE = [
  [0, "#f4f7fb"],
  [1, "#1f4e8c"],
];

export const PLOT_CONFIG = { responsive: true, displaylogo: false, modeBarButtonsToRemove: ["lasso2d", "select2d"] };

export function layout(xTitle, yTitle, extra = {}) {
  return {
    margin: { l: 70, r: 20, t: 30, b: 90 },
    font: { family: "system-ui, sans-serif", size: 13 },
    xaxis: { title: { text: xTitle }, automargin: true, zeroline: false },
    yaxis: { title: { text: yTitle }, automargin: true, zeroline: false },
    legend: { orientation: "h", x: 0, y: -0.32, yanchor: "top" },
    hovermode: "closest",
    height: 380,
    ...extra,
  };
}

export function plotDiv(id, extraClass = "") {
  return h("div", { class: `plot ${extraClass}`, id });
}

export function withAlpha(hex, alpha) {
  const n = parseInt(hex.slice(1), 16);
  return `rgba(${(n >> 16) & 255}, ${(n >> 8) & 255}, ${n & 255}, ${alpha})`;
}

export function sequenceText(sequence) {
  return JSON.stringify(sequence);
}

// A table from header names and rows of cells (cells may be nodes).
export function table(headers, rows, attrs = {}) {
  return h(
    "table",
    attrs,
    h("thead", {}, h("tr", {}, headers.map((name) => h("th", { scope: "col" }, name)))),
    h("tbody", {}, rows.map((cells) => h("tr", {}, cells.map((cell) => h("td", {}, cell))))),
  );
}

export function link(href, text, attrs = {}) {
  return h("a", { href, ...attrs }, text);
}

// Plotly traces drawing each candidate's ω response per axis: a mean line and a
// 10–90 % band, one colour per candidate, one subplot per axis.
export function responseTraces(response, { only = null } = {}) {
  const traces = [];
  const axes = ["x", "y", "z"];
  response.candidates.forEach((candidate, k) => {
    if (only !== null && k !== only) return;
    const color = COLORS[k % COLORS.length];
    axes.forEach((axis, a) => {
      const yaxis = a === 0 ? "y" : `y${a + 1}`;
      const common = { x: response.time_s, xaxis: "x", yaxis, legendgroup: candidate.name, hoverinfo: "skip" };
      traces.push({ ...common, y: candidate.low_rad_s.map((row) => row[a]), mode: "lines", line: { width: 0 }, showlegend: false, name: `${candidate.name} 10 %` });
      traces.push({ ...common, y: candidate.high_rad_s.map((row) => row[a]), mode: "lines", line: { width: 0 }, fill: "tonexty", fillcolor: withAlpha(color, 0.2), showlegend: false, name: `${candidate.name} 90 %` });
      traces.push({
        ...common,
        y: candidate.mean_rad_s.map((row) => row[a]),
        mode: "lines",
        line: { color, width: 2 },
        name: candidate.name,
        showlegend: a === 0,
        hoverinfo: "x+y+name",
      });
    });
  });
  return traces;
}

export function responseLayout(title) {
  return {
    ...layout("time from sequence start (s)", ""),
    title: { text: title, font: { size: 14 } },
    xaxis: { title: { text: "time from sequence start (s)" }, anchor: "y3" },
    yaxis: { title: { text: "ω_x (rad/s)" }, domain: [0.7, 1], anchor: "x" },
    yaxis2: { title: { text: "ω_y (rad/s)" }, domain: [0.36, 0.64], anchor: "x" },
    yaxis3: { title: { text: "ω_z (rad/s)" }, domain: [0, 0.3], anchor: "x" },
    height: 560,
    legend: { orientation: "h", y: -0.12 },
  };
}

// The sequence as duty per thruster over time: a heat map, one row per thruster.
export function sequencePlot(element, response) {
  const stepS = response.step_duration_s;
  const nThrusters = response.duties[0].length;
  const x = response.duties.map((_, i) => (i + 0.5) * stepS);
  const z = Array.from({ length: nThrusters }, (_, j) => response.duties.map((row) => row[j]));
  const text = z.map((row) => row.map((d) => `${Math.round(100 * d)} %`));
  Plotly.newPlot(
    element,
    [
      {
        type: "heatmap",
        x,
        y: Array.from({ length: nThrusters }, (_, j) => `thruster ${j + 1}`),
        z,
        zmin: 0,
        zmax: 1,
        text,
        texttemplate: "%{text}",
        colorscale: HEAT_SCALE,
        colorbar: { title: { text: "duty" }, tickformat: ".0%" },
        hovertemplate: "%{y}, t = %{x} s: duty %{z:.0%}<extra></extra>",
        xgap: 2,
        ygap: 2,
      },
    ],
    layout("time from sequence start (s)", "", {
      height: 130 + 32 * nThrusters,
      xaxis: { title: { text: "time from sequence start (s)" }, range: [0, response.duties.length * stepS], dtick: stepS },
      yaxis: { autorange: "reversed", automargin: true },
    }),
    PLOT_CONFIG,
  );
}
