// Plotly with one look for every chart, and the charts more than one page draws.
//
// Legends sit to the right of the plot area (Plotly moves the right margin to fit them)
// and every axis has `automargin`, so a legend never covers tick labels and an axis
// title is never cut, at any width. Conventions shared with the HTML report
// (inertia_id/evaluation/report.py): thrusters are numbered from 1, bands run from the
// 10th to the 90th percentile of the realisations.

import { h } from "../ui.js";

export const COLORS = ["#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b", "#e377c2", "#17becf", "#7f7f7f", "#bcbd22"];

// Light for 0, dark blue for 1 (plotly's "Blues" runs the other way).
export const HEAT_SCALE = [
  [0, "#f4f7fb"],
  [1, "#1f4e8c"],
];

export const BAND = { low: 10, high: 90, label: "10–90 %" };

// Not Plotly's `responsive`: the charts follow the window's width by fitChartsToCells.
export const PLOT_CONFIG = { responsive: false, displaylogo: false, modeBarButtonsToRemove: ["lasso2d", "select2d"] };

const LEGEND_RIGHT = { orientation: "v", x: 1.02, xanchor: "left", y: 1, yanchor: "top", font: { size: 12 } };

// A layout: titled axes with automargin, the legend at the right, `extra` merged on top
// (an axis given in `extra` keeps automargin unless it says otherwise).
export function layout(xTitle, yTitle, extra = {}) {
  const base = {
    margin: { l: 60, r: 10, t: extra.title ? 40 : 16, b: 50 },
    font: { family: "system-ui, sans-serif", size: 13 },
    xaxis: { title: { text: xTitle }, automargin: true, zeroline: false },
    yaxis: { title: { text: yTitle }, automargin: true, zeroline: false },
    legend: LEGEND_RIGHT,
    // A hover's trace name in full: Plotly cut it at 15 characters, counted on the
    // escaped text (plotText), so "Tank AB & C" showed as "Tank AB &amp...".
    hoverlabel: { namelength: -1 },
    hovermode: "closest",
    height: 380,
  };
  const out = { ...base, ...extra };
  for (const [name, value] of Object.entries(extra)) {
    if (/^[xy]axis\d*$/.test(name)) out[name] = { automargin: true, zeroline: false, ...value };
  }
  if (extra.legend) out.legend = { ...LEGEND_RIGHT, ...extra.legend };
  return out;
}

// Text a user wrote (a candidate, job or scenario name) as Plotly must be given it:
// Plotly reads its text as markup (<a href>, <span style>, <b>) and a hover template's
// %{...} as a substitution, so a name could draw a link or hide another label. Entities
// are what Plotly decodes back to the characters (&#37; for %), so the name shows as
// written.
export function plotText(text) {
  return String(text).replace(/&/g, "&amp;").replace(/</g, "&lt;").replace(/>/g, "&gt;").replace(/%/g, "&#37;");
}

export function title(text, size = 14) {
  return { text, font: { size }, x: 0, xanchor: "left", xref: "paper" };
}

export function plotDiv(id, extraClass = "") {
  return h("div", { class: `plot ${extraClass}`, id });
}

export function withAlpha(hex, alpha) {
  const n = parseInt(hex.slice(1), 16);
  return `rgba(${(n >> 16) & 255}, ${(n >> 8) & 255}, ${n & 255}, ${alpha})`;
}

// Traces that extend a plot with new points of several series: `fresh` maps a key to
// {steps, values} (MetricFollower.poll), `keys[i]` is the series of trace i.
export function extendWith(plot, fresh, keys) {
  const indices = [];
  const xs = [];
  const ys = [];
  keys.forEach((key, i) => {
    if (key && fresh[key]) {
      indices.push(i);
      xs.push(fresh[key].steps);
      ys.push(fresh[key].values);
    }
  });
  if (indices.length) Plotly.extendTraces(plot, { x: xs, y: ys }, indices);
  return indices.length;
}

// Plotly autoscales a series that never changes to v - 1 .. v + 1, where a residual rate
// of 0.0015 rad/s reads as 0: such a series gets the axis 0 .. 2v instead, and the axis
// autoscales again once the series varies.
export function fitFlatSeries(plot) {
  const values = (plot.data || []).flatMap((trace) => Array.from(trace.y || [])).filter((v) => typeof v === "number" && Number.isFinite(v));
  if (!values.length) return;
  const low = Math.min(...values);
  const high = Math.max(...values);
  if (high === low && high !== 0) {
    plot.dataset.flat = "1";
    Plotly.relayout(plot, { "yaxis.range": high > 0 ? [0, 2 * high] : [2 * high, 0] });
  } else if (plot.dataset.flat) {
    delete plot.dataset.flat;
    Plotly.relayout(plot, { "yaxis.autorange": true });
  }
}

// Rate axes in deg/s beside rad/s. A flight team reads deg/s: each rate axis gets a
// twin on the other side (Plotly's `overlaying`) in the other unit, whose range is kept
// exactly the first's times the factor. The twin's range is set, not autoscaled: it
// holds no data (one empty trace makes Plotly draw it). Hover text alone would be right
// at any zoom but shows one point at a time; a twin axis reads the whole plot, and it
// stays right on zoom because keepTwins sets its range after every draw and relayout
// (a zoom, a pan, a double-click's autorange, a live curve's extendTraces rescale).
export const DEG_PER_RAD = 180 / Math.PI;

// `twins`: [{ of: "yaxis", twin: "yaxis4", factor, title }]; the twin axes for a layout.
export function twinAxes(twins, extra = {}) {
  const out = {};
  for (const { of, twin, title: text } of twins) {
    const side = of.startsWith("x") ? "top" : "right";
    out[twin] = { overlaying: of.replace("axis", ""), side, title: { text }, automargin: true, showgrid: false, zeroline: false, tickmode: "auto", autorange: false, ...extra };
  }
  return out;
}

// The empty traces that make Plotly draw the twin axes.
export function twinTraces(twins) {
  return twins.map(({ twin }) => ({ x: [], y: [], [twin.startsWith("x") ? "xaxis" : "yaxis"]: twin.replace("axis", ""), showlegend: false, hoverinfo: "skip", name: twin }));
}

// Keeps each twin's range the factor times its axis's, now and after every draw or
// relayout of `plot`.
export function keepTwins(plot, twins) {
  plot.twins = twins;
  if (!plot.twinsKept) {
    plot.twinsKept = true;
    const sync = () => {
      const update = {};
      for (const { of, twin, factor } of plot.twins || []) {
        const range = plot.layout && plot.layout[of] && plot.layout[of].range;
        if (!range || range.length !== 2) continue;
        const want = range.map((v) => Number(v) * factor);
        const have = plot.layout[twin] && plot.layout[twin].range;
        if (!have || have[0] !== want[0] || have[1] !== want[1]) update[`${twin}.range`] = want;
      }
      if (Object.keys(update).length) Plotly.relayout(plot, update);
    };
    plot.on("plotly_afterplot", sync);
    plot.on("plotly_relayout", sync);
  }
  const update = {};
  for (const { of, twin, factor } of twins) {
    const range = plot.layout && plot.layout[of] && plot.layout[of].range;
    if (range) update[`${twin}.range`] = range.map((v) => Number(v) * factor);
  }
  if (Object.keys(update).length) Plotly.relayout(plot, update);
}

// The legend where a twin axis sits at the right: at the figure's right edge, beyond the
// twin's tick labels and title (at the plot area's edge it covered them).
export const LEGEND_PAST_TWIN = { xref: "container", x: 1, xanchor: "right" };

// The response plots' twins: ω_x, ω_y, ω_z in deg/s at the right.
export function responseTwins(view = "absolute") {
  const unit = view === "difference" ? "− mean (deg/s)" : "(deg/s)";
  return ["x", "y", "z"].map((axis, a) => ({ of: a === 0 ? "yaxis" : `yaxis${a + 1}`, twin: `yaxis${a + 4}`, factor: DEG_PER_RAD, title: `ω_${axis} ${unit}` }));
}

const AXES = ["x", "y", "z"];

// What a response view subtracts at each sample and axis: nothing ("absolute"), or the
// mean of the candidates' mean responses ("difference"): what separates them is then
// what is drawn.
function reference(response, view) {
  if (view !== "difference") return null;
  const k = response.candidates.length;
  return response.time_s.map((_, t) => [0, 1, 2].map((a) => response.candidates.reduce((sum, c) => sum + c.mean_rad_s[t][a], 0) / k));
}

// Plotly traces drawing each candidate's ω response per axis: a mean line and a
// 10–90 % band, one colour per candidate, one subplot per axis; `view` "difference"
// draws each minus the mean over candidates.
export function responseTraces(response, { only = null, view = "absolute" } = {}) {
  const ref = reference(response, view);
  const minus = (rows, a) => rows.map((row, t) => row[a] - (ref ? ref[t][a] : 0));
  const traces = [];
  response.candidates.forEach((candidate, k) => {
    if (only !== null && k !== only) return;
    const color = COLORS[k % COLORS.length];
    AXES.forEach((axis, a) => {
      const yaxis = a === 0 ? "y" : `y${a + 1}`;
      const name = plotText(candidate.name);
      const common = { x: response.time_s, xaxis: "x", yaxis, legendgroup: `candidate ${k}`, hoverinfo: "skip" };
      traces.push({ ...common, y: minus(candidate.low_rad_s, a), mode: "lines", line: { width: 0 }, showlegend: false, name: `${name} ${BAND.low} %` });
      traces.push({ ...common, y: minus(candidate.high_rad_s, a), mode: "lines", line: { width: 0 }, fill: "tonexty", fillcolor: withAlpha(color, 0.2), showlegend: false, name: `${name} ${BAND.high} %` });
      traces.push({ ...common, y: minus(candidate.mean_rad_s, a), mode: "lines", line: { color, width: 2 }, name, showlegend: a === 0, hoverinfo: "x+y+name" });
    });
  });
  return [...traces, ...twinTraces(responseTwins(view))];
}

export function responseLayout(text, view = "absolute") {
  const unit = view === "difference" ? "− mean (rad/s)" : "(rad/s)";
  return layout("time from sequence start (s)", "", {
    title: title(text),
    xaxis: { title: { text: "time from sequence start (s)" }, anchor: "y3" },
    yaxis: { title: { text: `ω_x ${unit}` }, domain: [0.7, 1], anchor: "x" },
    yaxis2: { title: { text: `ω_y ${unit}` }, domain: [0.36, 0.64], anchor: "x" },
    yaxis3: { title: { text: `ω_z ${unit}` }, domain: [0, 0.3], anchor: "x" },
    ...twinAxes(responseTwins(view), { anchor: "x" }),
    legend: LEGEND_PAST_TWIN,
    height: 560,
  });
}

// Every candidate's response in a plot with a switch between the differences from the
// mean over candidates (what separates them; the default) and the absolute rates.
export function responseView(response, { id, titleText, view = "difference" } = {}) {
  const plot = plotDiv(id);
  const buttons = {};
  const draw = (which) => {
    view = which;
    for (const [name, button] of Object.entries(buttons)) button.setAttribute("aria-pressed", String(name === which));
    const what = which === "difference" ? `${titleText}: each candidate minus the mean over candidates` : titleText;
    Plotly.react(plot, responseTraces(response, { view: which }), responseLayout(what, which), PLOT_CONFIG);
    keepTwins(plot, responseTwins(which));
    plot.dataset.view = which;
  };
  buttons.difference = h("button", { type: "button", class: "secondary toggle", "data-view": "difference", onclick: () => draw("difference") }, "differences from the mean");
  buttons.absolute = h("button", { type: "button", class: "secondary toggle", "data-view": "absolute", onclick: () => draw("absolute") }, "absolute rates");
  const node = h("div", {}, h("div", { class: "toolbar", role: "group", "aria-label": "response view" }, h("span", { class: "hint" }, "show"), buttons.difference, buttons.absolute), plot);
  return { node, plot, draw: () => draw(view) };
}

// The sequence as duty per thruster over time: a heat map, one row per thruster
// (numbered from 1).
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
      yaxis: { autorange: "reversed" },
    }),
    PLOT_CONFIG,
  );
}

// A confusion matrix: counts as text, colour the fraction of the true candidate's row.
export function confusionPlot(element, confusion, names, text) {
  const totals = confusion.map((row) => row.reduce((a, b) => a + b, 0) || 1);
  Plotly.newPlot(
    element,
    [
      {
        type: "heatmap",
        z: confusion.map((row, i) => row.map((v) => v / totals[i])),
        x: names.map(plotText),
        y: names.map(plotText),
        text: confusion.map((row) => row.map((v) => String(v))),
        texttemplate: "%{text}",
        colorscale: HEAT_SCALE,
        zmin: 0,
        zmax: 1,
        colorbar: { title: { text: "fraction of row" }, tickformat: ".0%" },
        hovertemplate: "true %{y}, predicted %{x}: %{text} series<extra></extra>",
      },
    ],
    layout("predicted candidate", "true candidate", {
      title: title(text),
      yaxis: { title: { text: "true candidate" }, autorange: "reversed" },
      height: 400,
    }),
    PLOT_CONFIG,
  );
}

// The y range of values that differ by a few per cent: padded around them, never from 0.
export function tightRange(values, pad = 0.15) {
  const finite = values.filter((v) => Number.isFinite(v));
  if (!finite.length) return undefined;
  const low = Math.min(...finite);
  const high = Math.max(...finite);
  const span = high - low || Math.abs(high) * 0.05 || 1;
  return [low - pad * span, high + pad * span];
}

// Where an NSGA-II search's curve leaves its generations for its polish rounds, once the
// result says: { timesteps (the last generation's point), generations, rounds }, or null
// (another method, no result yet, or no polish round on the curve). The generations are
// the curve's first points (fewer when the search stopped in them).
export function polishStart(job) {
  const result = job.result;
  const curve = (result && result.curve) || [];
  if (job.params.method !== "nsga2" || !curve.length) return null;
  const generations = Math.min(curve.length, result.settings?.nsga2?.generations ?? job.params.nsga2?.generations ?? curve.length);
  return { timesteps: curve[generations - 1].timesteps, generations, rounds: curve.length - generations };
}

// A dashed vertical line at each search's polish start, labelled: Plotly shapes and
// annotations for a plot's layout. `marks`: [{ x, label, color }].
export function polishMarks(marks) {
  return {
    shapes: marks.map((m) => ({ type: "line", xref: "x", yref: "paper", x0: m.x, x1: m.x, y0: 0, y1: 1, line: { color: m.color || "#555", width: 1, dash: "dash" } })),
    annotations: marks.map((m, i) => ({
      xref: "x",
      yref: "paper",
      x: m.x,
      y: 1 - 0.08 * i,
      xanchor: "left",
      yanchor: "top",
      showarrow: false,
      text: plotText(m.label),
      font: { size: 11, color: m.color || "#555" },
      bgcolor: "rgba(255,255,255,0.8)",
    })),
  };
}

// An NSGA-II search's "most accurate feasible so far" line, drawn from its metrics as
// they come (`apply(fresh)` returns them changed). A search stored before its curve held
// the best so far (19f0737) logged each generation's, then each polish round's, best: the
// line dipped (0.795 down to 0.326 through the polish) under a name that says it cannot.
// Without constraints every sequence is feasible, so the running maximum of best_f1 is
// exact for such a search and the identity for one stored since; its residual rate is
// the one logged at the step that set the maximum. With constraints the stored line is
// drawn as it is: it may fall where the first feasible sequence displaces more accurate
// infeasible ones, and an old point's feasibility is not stored, so no running best can
// be drawn from it. The best so far falls there once at most: a line that falls twice is
// one stored before, and `predates` says so (the page says what the line is).
export class BestSoFar {
  constructor(job) {
    const nsga2 = job.params.method === "nsga2";
    const constrained = Object.keys(job.params.constraints || {}).length > 0;
    this.on = nsga2 && !constrained;
    this.watched = nsga2 && constrained;
    this.best = -Infinity;
    this.rate = undefined;
    this.rateAt = new Map();
    this.last = undefined;
    this.falls = 0;
    this.flagged = false;
  }

  // A constrained NSGA-II search stored before its curve held the best feasible so far
  // (one stored since says which points were feasible: its best falls once, where the
  // first feasible sequence takes over from the most accurate of all).
  get predates() {
    return this.falls >= 2 && !this.flagged;
  }

  apply(fresh) {
    if (fresh.best_feasible) this.flagged = true;
    const f1 = fresh.best_f1;
    if (this.watched && f1) {
      for (const v of f1.values) {
        if (typeof v !== "number") continue;
        if (this.last !== undefined && v < this.last) this.falls += 1;
        this.last = v;
      }
    }
    if (!this.on || !f1) return fresh;
    const rates = fresh.best_residual_rate_rad_s;
    const logged = new Map(rates ? rates.steps.map((s, i) => [s, rates.values[i]]) : []);
    const values = f1.values.map((v, i) => {
      if (typeof v === "number" && v > this.best) {
        this.best = v;
        this.rate = logged.get(f1.steps[i]);
      }
      this.rateAt.set(f1.steps[i], this.rate);
      return Number.isFinite(this.best) ? this.best : v;
    });
    const out = { ...fresh, best_f1: { steps: f1.steps, values } };
    if (rates) out.best_residual_rate_rad_s = { steps: rates.steps, values: rates.steps.map((s, i) => this.rateAt.get(s) ?? rates.values[i]) };
    return out;
  }
}

// A constrained search's best so far breaks its constraints until some sequence meets
// them (it is the most accurate of all till then). Its `best_feasible` metric says which
// points those are: each of `keys` is split, the points marked 0 going to
// `${key}_infeasible` (a series of their own, drawn apart), the others staying.
export function splitInfeasible(fresh, keys) {
  const flags = fresh.best_feasible;
  if (!flags) return fresh;
  const broken = new Set(flags.steps.filter((_, i) => flags.values[i] === 0));
  const out = { ...fresh };
  for (const key of keys) {
    const series = fresh[key];
    if (!series) continue;
    const part = (infeasible) => {
      const at = series.steps.map((_, i) => i).filter((i) => broken.has(series.steps[i]) === infeasible);
      return at.length ? { steps: at.map((i) => series.steps[i]), values: at.map((i) => series.values[i]) } : undefined;
    };
    out[key] = part(false);
    out[`${key}_infeasible`] = part(true);
  }
  return out;
}

// Every chart fits its figure at any width, a phone's too: Plotly does not wrap a title,
// and at 375 px the search page's titles ran 120 px past the figure's edge, its legends
// covered the plot. After every draw (a resize too) each title too long for its room is
// broken into lines at spaces (the page's own text is kept and rejoined when the room
// comes back), a legend wider than a third of the figure goes under the plot, in rows,
// and a colour bar that wide is narrowed.
const TITLE_ROOM_PAD = 8;
const TITLE_TOP = 6;
// A figure narrower than LEGEND_NARROW_PX (a phone's, a tablet's) keeps a legend at its side
// up to a third of its width; a wider one up to 45 % (the desktop's legends stay put).
const LEGEND_NARROW_PX = 900;
const legendShare = (width) => (width < LEGEND_NARROW_PX ? 1 / 3 : 0.45);
const COLOUR_BAR_TITLE_ROOM = 56;
const measureContext = document.createElement("canvas").getContext("2d");

function textWidth(text, font) {
  measureContext.font = `${font.size}px ${font.family}`;
  return measureContext.measureText(text.replace(/&[a-z#0-9]+;/gi, "&")).width;
}

// `text` broken at spaces into lines no wider than `room` px ("<br>" between them); a
// word longer than the room keeps a line of its own.
function wrapText(text, room, font) {
  if (textWidth(text, font) <= room) return text;
  const lines = [];
  let line = "";
  for (const word of text.split(" ")) {
    const longer = line ? `${line} ${word}` : word;
    if (line && textWidth(longer, font) > room) {
      lines.push(line);
      line = word;
    } else {
      line = longer;
    }
  }
  if (line) lines.push(line);
  return lines.join("<br>");
}

// The room (px) of each title of `plot`: [path, text, room, font] for those that have text.
// A title the page left out holds Plotly's placeholder in the full layout ("Click to enter
// Y axis title"), which Plotly draws only in an editable chart; wrapped, it was no longer
// the placeholder and was drawn: the thruster duty chart's left edge read "Click to enter
// Y axis / title".
function titleRooms(plot) {
  const full = plot._fullLayout;
  const placeholders = full._dfltTitle || {};
  const rooms = [];
  const title = full.title;
  if (title && title.text && title.text !== placeholders.plot) rooms.push(["title.text", title.text, full.width - full._size.l - TITLE_ROOM_PAD, title.font]);
  for (const name of Object.keys(full)) {
    if (!/^[xy]axis\d*$/.test(name)) continue;
    const axis = full[name];
    if (!axis || !axis.title || !axis.title.text || !axis.visible) continue;
    if (axis.title.text === placeholders[name[0]]) continue;
    // Centred on its axis: within the figure, and within the axis's own length (side by
    // side subplots' titles ran into each other).
    const span = name.startsWith("x") ? full.width : full.height;
    const centre = axis._offset + axis._length / 2;
    const room = Math.min(2 * Math.min(centre, span - centre), axis._length) - TITLE_ROOM_PAD;
    rooms.push([`${name}.title.text`, axis.title.text, room, axis.title.font]);
  }
  return rooms;
}

function get(layout, path) {
  return path.split(".").reduce((node, key) => (node == null ? undefined : node[key]), layout);
}

// A title of several lines hangs from the figure's top and the top margin grows to hold
// them: the page's margin held one line (Plotly's title automargin left it as it was),
// and Plotly lifts a block of lines by about a line, so where it landed is measured and
// the pad set from it.
function titlePlace(plot, fit, wrapped, font) {
  const moved = get(plot.layout, "title.yanchor") === "top";
  if (!moved) fit.ownTop = get(plot.layout, "margin.t") ?? plot._fullLayout.margin.t;
  const lines = wrapped.split("<br>").length;
  if (lines > 1) {
    if (!moved || wrapped !== get(plot.layout, "title.text")) {
      const pad = TITLE_TOP + (lines - 1) * font.size;
      return { "title.yref": "container", "title.y": 1, "title.yanchor": "top", "title.pad.t": pad, "margin.t": Math.max(fit.ownTop, Math.ceil(TITLE_TOP + lines * 1.4 * font.size + 8)) };
    }
    const text = plot.querySelector(".g-gtitle text");
    if (!text) return {};
    const figure = plot.querySelector("svg.main-svg").getBoundingClientRect();
    const box = text.getBoundingClientRect();
    const shift = TITLE_TOP - (box.top - figure.top);
    const top = Math.max(fit.ownTop, Math.ceil(box.bottom + shift - figure.top + 8));
    const update = {};
    if (Math.abs(shift) > 1) update["title.pad.t"] = get(plot.layout, "title.pad.t") + shift;
    if (get(plot.layout, "margin.t") !== top) update["margin.t"] = top;
    return update;
  }
  if (!moved) return {};
  return { "title.yref": null, "title.y": null, "title.yanchor": null, "title.pad.t": null, "margin.t": fit.ownTop };
}

const LEGEND_BELOW = { orientation: "h", xref: "container", x: 0, xanchor: "left", yref: "container", y: 0, yanchor: "bottom" };

function fitToWidth(plot) {
  const full = plot._fullLayout;
  if (!full || !full._size || !plot.layout) return;
  const fit = (plot.fitted ||= { texts: {}, passes: 0, width: 0 });
  if (fit.width !== full.width) {
    fit.width = full.width;
    fit.passes = 0;
  }
  // A draw that changes the margins changes the room: a few passes settle it, never a loop
  // (a legend moved under the plot takes two: it moves, then the foot margin is fitted to
  // it as drawn).
  if (fit.busy) return;
  if (fit.passes >= 8) {
    plot.dataset.fitted = String(full.width);
    return;
  }
  const update = {};
  for (const [path, shown, room, font] of titleRooms(plot)) {
    const kept = fit.texts[path];
    // The page's own text, unless what is shown is the text this wrapped.
    const own = kept && kept.wrapped === shown ? kept.own : shown;
    const wrapped = wrapText(own, room, font);
    fit.texts[path] = { own, wrapped };
    if (wrapped !== shown) update[path] = wrapped;
    if (path === "title.text") Object.assign(update, titlePlace(plot, fit, wrapped, font));
  }
  Object.assign(update, legendPlace(plot, fit));
  Object.assign(update, categoryLabelsPlace(plot, fit));
  // A bar hidden or shown again in this pass is placed in the next, as drawn.
  const shown = colourBarsShown(plot, fit);
  const restyles = [...shown, ...colourBarPlaces(plot, fit).filter(([index]) => !shown.some(([i]) => i === index))];
  // The figure width it was fitted to, once nothing is left to change (what a test waits for).
  if (!Object.keys(update).length && !restyles.length) {
    plot.dataset.fitted = String(full.width);
    return;
  }
  delete plot.dataset.fitted;
  // One change at a time (two at once failed in Plotly: "Something went wrong with axis
  // scaling"); the draws they make are fitted once they are all done.
  fit.passes += 1;
  fit.busy = true;
  (async () => {
    try {
      for (const [index, change] of restyles) await Plotly.restyle(plot, change, [index]);
      if (Object.keys(update).length) await Plotly.relayout(plot, update);
    } finally {
      fit.busy = false;
    }
    fitToWidth(plot);
  })();
}

// A legend wider than legendShare of the figure goes under the plot, in rows, and the figure
// grows by its height (the plot keeps its own); it goes back once the room is there.
function legendPlace(plot, fit) {
  const full = plot._fullLayout;
  const legend = plot.querySelector("g.legend");
  if (!full.showlegend || !legend) return {};
  if (!legendIsBelow(plot, fit)) {
    const width = legend.getBBox().width;
    if (width <= legendShare(full.width) * full.width) return {};
    return { legend: moveLegendBelow(plot, fit, width) };
  }
  if (fit.legendWidth <= legendShare(full.width) * full.width) {
    const own = { legend: fit.legendOwn, height: fit.ownHeight, "margin.b": fit.ownMarginB ?? null };
    fit.legendOwn = undefined;
    return own;
  }
  // Plotly reserves the legend's height at the figure's foot and lifts an x-axis title
  // that reaches into it up onto the legend's top edge, so the title sat flush on the
  // legend (0 px apart at 375 px, its descenders on the first row). The foot margin is set
  // to hold the axis's tick labels and title where Plotly draws them when it has the
  // room, a gap, then the legend (Plotly never makes a margin smaller than the layout's):
  // the legend at the figure's foot clears them. The figure grows by what the margin
  // gained over the page's own, so the plot keeps its height.
  const foot = Math.ceil(xAxisDepth(plot) + LEGEND_GAP + Math.max(legend.getBBox().height, full.legend._effHeight || 0));
  const margin = Math.max(fit.ownFoot, foot);
  const height = fit.ownHeight + margin - fit.ownFoot;
  if (Math.abs(margin - (get(plot.layout, "margin.b") ?? 0)) <= 1 && Math.abs(height - (plot.layout.height ?? 0)) <= 1) return {};
  return { "margin.b": margin, height };
}

// Whether fitToWidth has put the legend under the plot.
function legendIsBelow(plot, fit) {
  return fit.legendOwn !== undefined && get(plot.layout, "legend.yref") === "container";
}

// The legend under the plot, the page's own kept to go back to: what the layout's legend
// becomes. `width`: the legend's as drawn at the side (px).
function moveLegendBelow(plot, fit, width) {
  const full = plot._fullLayout;
  fit.legendOwn = plot.layout.legend || {};
  fit.legendWidth = width;
  fit.ownHeight = plot.layout.height ?? full.height;
  fit.ownMarginB = get(plot.layout, "margin.b");
  fit.ownFoot = full.margin.b;
  return { ...fit.legendOwn, ...LEGEND_BELOW };
}

// A legend at the side that a figure `width` px wide cannot hold goes under the plot, as
// legendPlace would put it after a draw at that width: the update for Plotly.relayout.
function legendForWidth(plot, width) {
  const full = plot._fullLayout;
  const fit = plot.fitted;
  const legend = plot.querySelector("g.legend");
  if (!fit || !full.showlegend || !legend || legendIsBelow(plot, fit)) return {};
  const legendWidth = legend.getBBox().width;
  if (legendWidth <= legendShare(width) * width) return {};
  return { legend: moveLegendBelow(plot, fit, legendWidth) };
}

// Each chart on view drawn again at its cell's width, once the window's width or a chart's
// cell's size changed.
// Plotly's own resize (the `responsive` config) deleted each chart's height, and redrew it
// at its div's: after any change of the window's width the front's chart was 320 px tall,
// not 440 (its plot area 128 px, not 245), a confusion matrix 320, not 400. It kept the
// legend where it was: a legend at the side that the narrower figure cannot hold left the
// plot area below 0 px (a response plot from 1,280 to 375 px: 101 px of left margin and
// 237 of right in a 325 px figure), Plotly threw "Something went wrong with axis scaling"
// and the chart stayed 1,212 px wide, cut at its cell's edge. And a chart whose legend
// went under it was never resized: its height given to Plotly.relayout set its width too
// (599 px wide in a 325 px cell). Here the width is set, the height kept, and the legend
// moved under the plot in the same draw where the new width cannot hold it at the side.
function fitChartsToCells() {
  for (const plot of document.querySelectorAll(".js-plotly-plot")) {
    const full = plot._fullLayout;
    if (!plot.offsetParent || !full || !plot.layout) continue;
    const width = plot.getBoundingClientRect().width;
    if (width < 10 || Math.abs(width - full.width) <= 1) continue;
    Plotly.relayout(plot, { ...legendForWidth(plot, width), width });
  }
}

// Between an x axis's title (or tick labels) and a legend under the plot (px).
const LEGEND_GAP = 8;

// How far the x axes at the plot's foot reach below the plot area (px): their tick labels,
// and their titles (a title broken into lines too) where Plotly draws them with room to
// spare. A title short of room is lifted by a translate on its group, undone here: it
// comes down again once the margin grows, and measured where it was lifted to, each
// margin let it down by the gap, a pass at a time.
function xAxisDepth(plot) {
  const full = plot._fullLayout;
  const figure = plot.querySelector("svg.main-svg").getBoundingClientRect();
  const plotFoot = full._size.t + full._size.h;
  let depth = 0;
  for (const name of Object.keys(full)) {
    const axis = full[name];
    if (!/^xaxis\d*$/.test(name) || !axis || !axis.visible || axis.side === "top") continue;
    for (const text of plot.querySelectorAll(`.${axis._id}tick text, .g-${axis._id}title text`)) {
      if (!text.textContent) continue;
      const group = text.closest(`.g-${axis._id}title`);
      let lift = 0;
      const moves = group ? group.transform.baseVal : null;
      for (let i = 0; moves && i < moves.numberOfItems; i++) lift += moves.getItem(i).matrix.f;
      lift = Math.min(0, lift);
      depth = Math.max(depth, text.getBoundingClientRect().bottom - lift - figure.top - plotFoot);
    }
  }
  return depth;
}

// The least length (px) of a horizontal colour bar beside its title, and what Plotly
// leaves between the two (px).
const HORIZONTAL_BAR_MIN = 140;
const HORIZONTAL_TITLE_GAP = 30;

// Each colour bar of `plot`: [trace index, its attribute's path, the bar as drawn].
function colourBars(plot) {
  return (plot.data || []).flatMap((trace, i) => {
    const drawn = (plot._fullData || [])[i] || {};
    if (trace.colorbar && drawn.showscale) return [[i, "colorbar", trace.colorbar]];
    if (trace.marker && trace.marker.colorbar && drawn.marker && drawn.marker.showscale) return [[i, "marker.colorbar", trace.marker.colorbar]];
    return [];
  });
}

// A colour bar at the plot's side as wide as a quarter of the figure is made narrow, its
// title over it (a confusion matrix of 375 px had 64 px left for its cells, its axis
// title over its tick labels); a bar at the figure's foot goes above a legend that went
// there.
function colourBarPlaces(plot, fit) {
  const full = plot._fullLayout;
  const legend = plot.querySelector("g.legend");
  const legendBelow = fit.legendOwn !== undefined && legend ? legend.getBBox().height : 0;
  const drawnBars = [...plot.querySelectorAll(".colorbar")];
  fit.bars ||= {};
  const changes = [];
  colourBars(plot).forEach(([index, path, bar], n) => {
    const kept = fit.bars[index];
    const own = kept && JSON.stringify(kept.placed) === JSON.stringify(bar) ? kept.own : bar;
    const box = drawnBars[n] && drawnBars[n].getBBox();
    const side = own.orientation !== "h";
    // The page's own bar's width, measured where it is drawn as the page gave it (not
    // narrowed), and weighed against the figure's width at each fit: a bar judged once,
    // at the width the page was opened at, kept its 1,280 px verdict at 375 px (the
    // confusion matrix's bar and title took its plot area down to 60 px, "true candidate"
    // broken over its tick labels).
    const ownWidth = JSON.stringify(bar) === JSON.stringify(own) && box ? box.width : kept && kept.ownWidth;
    const wide = side && ownWidth > full.width / 4;
    let placed = own;
    if (wide) {
      const heading = own.title || {};
      const text = heading.text ? wrapText(heading.text, COLOUR_BAR_TITLE_ROOM, { size: 12, ...heading.font, family: full.font.family }) : heading.text;
      placed = { ...own, thickness: 10, title: { ...heading, text, side: "top" } };
    }
    // A bar along the figure's foot, its title at its right, lengthened (up to the
    // plot's width) so the bar keeps HORIZONTAL_BAR_MIN px beside its title: at 375 to
    // 600 px the front's bar (0.45 of the plot) was about 0 px long, its five tick labels
    // stacked at one x.
    if (!side && drawnBars[n]) {
      const heading = drawnBars[n].querySelector(".cbtitle");
      const titleWidth = heading && (own.title || {}).side === "right" ? heading.getBBox().width + HORIZONTAL_TITLE_GAP : 0;
      const plotWidth = full._size.w;
      const need = titleWidth + HORIZONTAL_BAR_MIN;
      if (plotWidth > 0 && (own.len ?? 1) * plotWidth < need) placed = { ...placed, len: Math.min(1, need / plotWidth) };
    }
    if (legendBelow && placed.yref === "container" && (placed.y ?? 0) < 0.3) {
      placed = { ...placed, y: (placed.y ?? 0) + (legendBelow + 8) / full.height };
    }
    fit.bars[index] = { own, placed, ownWidth };
    if (JSON.stringify(placed) !== JSON.stringify(bar)) changes.push([index, { [path]: [placed] }]);
  });
  return changes;
}

// The narrow layout (style.css's, up to 899 px of window): a phone's, a tablet's.
const NARROW_LAYOUT = window.matchMedia("(max-width: 899px)");

// A heatmap that writes its value in every cell (a confusion matrix's counts, a sequence's
// duties) drops its colour bar in the narrow layout, and gets it back once the window is
// wide: the cells say what the bar would. At 375 px an eight-candidate confusion matrix's
// bar, narrowed by colourBarPlaces, and its title kept 83 px of the figure's 325 at its
// right, the names 178 at its left: the cells had 64 px and Plotly wrote 4 of the 8 names
// under them. (A bar laid along the foot instead made Plotly throw "Something went wrong
// with axis scaling" at 414 px.) `fit.hiddenBars`: the traces whose bar this hid (a page's
// own showscale: false is left alone). Each change: [trace index, restyle].
function colourBarsShown(plot, fit) {
  fit.hiddenBars ||= new Set();
  const changes = [];
  (plot.data || []).forEach((trace, index) => {
    if (trace.type !== "heatmap" || !trace.texttemplate) return;
    // Hidden by this unless the page has drawn the trace again since.
    const hidden = fit.hiddenBars.has(index) && trace.showscale === false;
    if (!hidden) fit.hiddenBars.delete(index);
    if (NARROW_LAYOUT.matches && !hidden && trace.showscale !== false) {
      fit.hiddenBars.add(index);
      changes.push([index, { showscale: false }]);
    } else if (!NARROW_LAYOUT.matches && hidden) {
      fit.hiddenBars.delete(index);
      changes.push([index, { showscale: null }]);
    }
  });
  return changes;
}

// A y axis's category names in the narrow layout: broken into lines once one is wider than
// CATEGORY_LABEL_SHARE of the figure, each line up to that share or CATEGORY_LABEL_MIN_PX,
// whichever is wider. Plotly spaces lines of text by 1.3 of the font's size; a name is
// given CATEGORY_LABEL_GAP px more above or below it.
const CATEGORY_LABEL_SHARE = 0.2;
const CATEGORY_LABEL_MIN_PX = 80;
const CATEGORY_LINE = 1.3;
const CATEGORY_LABEL_GAP = 2;

// A y axis of categories (a confusion matrix's candidates) whose longest name is too wide
// for the narrow layout: each name broken into lines at spaces (ticktext; the categories,
// hovers and the page's own layout keep the names whole), and the figure made taller
// where its rows cannot hold the lines (the plot area keeps its height otherwise); the
// names on one line and the page's own height again once the window is wide. At 375 px
// the names and axis title took 178 of the figure's 325 px. An axis whose ticks the page
// set itself is left alone. `fit.ticks`: the ticktext this set, by axis; `fit.tickHeight`:
// { own, set }, the page's height and the one this set.
function categoryLabelsPlace(plot, fit) {
  const full = plot._fullLayout;
  fit.ticks ||= {};
  const update = {};
  let wrappedAny = false;
  // The px the plot area lacks (less than 0: has to spare) to hold the names' lines.
  let lacking = -Infinity;
  for (const name of Object.keys(full)) {
    if (!/^yaxis\d*$/.test(name)) continue;
    const axis = full[name];
    if (!axis || !axis.visible || axis.type !== "category" || !axis._categories) continue;
    const own = (plot.layout && plot.layout[name]) || {};
    const ours = fit.ticks[name] !== undefined && JSON.stringify(own.ticktext) === JSON.stringify(fit.ticks[name]);
    if (!ours) delete fit.ticks[name];
    if (!ours && (own.tickmode !== undefined || own.tickvals !== undefined || own.ticktext !== undefined)) continue;
    const names = axis._categories.map(String);
    const font = { size: 12, family: full.font.family, ...axis.tickfont };
    const widest = Math.max(...names.map((text) => textWidth(text, font)));
    if (NARROW_LAYOUT.matches && widest > CATEGORY_LABEL_SHARE * full.width) {
      const wrapped = names.map((text) => wrapText(text, Math.max(CATEGORY_LABEL_SHARE * full.width, CATEGORY_LABEL_MIN_PX), font));
      wrappedAny = true;
      const lines = Math.max(...wrapped.map((text) => text.split("<br>").length));
      lacking = Math.max(lacking, names.length * (lines * CATEGORY_LINE * font.size + 2 * CATEGORY_LABEL_GAP) - axis._length);
      if (ours && JSON.stringify(own.tickvals) === JSON.stringify(names) && JSON.stringify(own.ticktext) === JSON.stringify(wrapped)) continue;
      fit.ticks[name] = wrapped;
      Object.assign(update, { [`${name}.tickmode`]: "array", [`${name}.tickvals`]: names, [`${name}.ticktext`]: wrapped });
    } else if (ours) {
      delete fit.ticks[name];
      Object.assign(update, { [`${name}.tickmode`]: null, [`${name}.tickvals`]: null, [`${name}.ticktext`]: null });
    }
  }
  // An x axis of categories hangs its names straight down in the narrow layout where they
  // do not fit flat: at 30 degrees the last name ran past the plot's right edge and the
  // margin Plotly made for it left the cells 128 px of a 364 px figure, too few for
  // Plotly to write every name (it wrote every other one). `fit.angles`: the axes set so.
  fit.angles ||= {};
  for (const name of Object.keys(full)) {
    if (!/^xaxis\d*$/.test(name)) continue;
    const axis = full[name];
    if (!axis || !axis.visible || axis.type !== "category") continue;
    const own = (plot.layout && plot.layout[name]) || {};
    const ours = fit.angles[name] && JSON.stringify(own.autotickangles) === JSON.stringify(HANGING);
    if (!ours) delete fit.angles[name];
    if (NARROW_LAYOUT.matches && !ours && own.autotickangles === undefined && own.tickangle === undefined) {
      fit.angles[name] = true;
      update[`${name}.autotickangles`] = HANGING;
    } else if (!NARROW_LAYOUT.matches && ours) {
      delete fit.angles[name];
      update[`${name}.autotickangles`] = null;
    }
  }
  // The height: the page's own unless this set it (a page's draw since sets its own). A
  // legend under the plot sets the height itself (legendPlace): left to it.
  const height = plot.layout.height ?? full.height;
  if (fit.tickHeight && fit.tickHeight.set !== height) fit.tickHeight = undefined;
  if (legendIsBelow(plot, fit)) return update;
  if (wrappedAny) {
    const own = fit.tickHeight ? fit.tickHeight.own : height;
    const want = Math.max(own, Math.ceil(height + lacking));
    if (Math.abs(want - height) > 1) {
      fit.tickHeight = { own, set: want };
      update.height = want;
    }
  } else if (fit.tickHeight) {
    update.height = fit.tickHeight.own;
    fit.tickHeight = undefined;
  }
  return update;
}

// The angles Plotly may give an x axis's names in the narrow layout: flat, or straight down.
const HANGING = [0, 90];

// Every newPlot and react of the dashboard fits its chart to the width (fitToWidth), once
// drawn and after every later draw; called once, by the shell.
export function fitChartsToWidth() {
  let resized = null;
  const refit = () => {
    clearTimeout(resized);
    resized = setTimeout(fitChartsToCells, 100);
  };
  window.addEventListener("resize", refit);
  // A chart's cell can change its size while the window keeps its own: a collapsed
  // section (display: none) opened after the window's width changed (its charts had no
  // box then and were skipped: one drawn at 1,280 px stayed 1,244 px wide in its 357 px
  // cell once opened at 375), a grid given its second cell. Each chart's div is watched.
  const cells = new ResizeObserver(refit);
  for (const method of ["newPlot", "react"]) {
    const draw = Plotly[method];
    Plotly[method] = async (plot, ...rest) => {
      const drawn = await draw(plot, ...rest);
      if (!plot.cellWatched) {
        plot.cellWatched = true;
        cells.observe(plot);
      }
      plot.fitListener ||= () => fitToWidth(plot);
      plot.removeListener("plotly_afterplot", plot.fitListener);
      plot.on("plotly_afterplot", plot.fitListener);
      fitToWidth(plot);
      return drawn;
    };
  }
}
