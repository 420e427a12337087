// A sweep's view: accuracy against each source of error with 95 % intervals, the other
// classifiers and the ceiling on the same test series, the confusion matrix at a chosen
// point, and how often bodies off the candidates get "matches none". Used by the job
// page of a sweep and by a classifier's view.

import { MetricFollower } from "../api.js";
import { classifierName, noiseInfo, vocabulary } from "../vocabulary.js";
import { clear, h, score, statusBadge } from "../ui.js";
import { COLORS, PLOT_CONFIG, confusionPlot, layout, plotDiv, plotText, title } from "../components/plots.js";

// Accuracy vs each source of error's multiple with 95 % intervals, the other
// classifiers scored on the same series (the ceiling dashed, least squares
// dotted), the confusion matrix at a chosen point, and how often bodies off the
// candidates get "matches none". While the sweep runs, the main classifier's points come
// from the job's metrics; the finished result brings the rest.
const OTHER_STYLE = {
  likelihood: { dash: "dashdot", color: "#555", name: "likelihood trained at 1×" },
  "least-squares": { dash: "dot", color: "#8c564b", name: "least squares (physics)" },
};

// The source of error is in the plot's title; the axis says what 1× is.
function axisTitle(noise, result) {
  const { unit } = noiseInfo(noise);
  const level = result && result.levels ? result.levels[noise] : null;
  if (level === null || level === undefined) return "multiple of the 1× level";
  return `multiple of the 1× level (1× = ${Number(level.toPrecision(2))} ${unit})`;
}

// The points of each classifier whose accuracy lies above the ceiling's 95 % interval at
// the same point: as the sweep states it per point (above_ceiling_interval), or, in a
// result stored before it did, from the intervals it holds.
function aboveCeiling(result, mainName) {
  const top = new Map((result.ceiling || []).map((c) => [`${c.noise}|${c.multiple}`, c.ci_high]));
  const lines = [[mainName, result.points || []], ...Object.entries(result.others || {})];
  return lines
    .map(([name, points]) => ({
      name,
      where: points.filter((p) => {
        if (typeof p.above_ceiling_interval === "boolean") return p.above_ceiling_interval;
        const high = top.get(`${p.noise}|${p.multiple}`);
        return high !== undefined && p.accuracy > high;
      }),
    }))
    .filter((line) => line.where.length);
}

// What the numbers say about the ceiling, never a fixed sentence.
function ceilingCheck(result, mainName) {
  const found = aboveCeiling(result, mainName);
  const how = "each accuracy against the ceiling's 95 % Wilson interval at the same point, not a paired test";
  if (!found.length) {
    return h("p", { class: "note", id: "sweep-ceiling-check", "data-above": "none" }, `No classifier above the ceiling's interval at any point (${how}).`);
  }
  const named = found.map(({ name, where }) => `${name} at ${where.map((p) => `${p.noise} ×${p.multiple}`).join(", ")}`);
  return h(
    "p",
    { class: "note dominated", id: "sweep-ceiling-check", "data-above": found.map((f) => f.name).join("|") },
    `Above the ceiling's interval (${how}): ${named.join("; ")}. A ceiling fitted on too few realisations, or sampling error, can put a classifier there.`,
  );
}

// Where the chance line runs: from the first multiple to the last, or, with one multiple
// m, from m/2 to 3m/2 (the axis is linear; no multiple is negative, so neither is the
// line: a pad of at least 0.5 had run ×0.001 from −0.499), and from 0 to 1 for a sweep
// at 0 alone. Drawn from the multiple to itself, a 1-point sweep's line had no length and
// did not show.
export function chanceSpan(x) {
  const low = Math.min(...x);
  const high = Math.max(...x);
  if (high > low) return [low, high];
  return low > 0 ? [low / 2, (3 * low) / 2] : [0, 1];
}

export async function sweepPanel(holder, job, classifier, context) {
  const noises = job.params.noises || vocabulary().default_noises;
  const plots = Object.fromEntries(noises.map((n) => [n, plotDiv(`accuracy-${n}`)]));
  const state = h("div", { id: "sweep-state" });
  const confusionHolder = h("div", { id: "sweep-confusion" });
  const inertiaHolder = h("div", { id: "sweep-inertia" });
  holder.append(state, h("div", { class: "grid2" }, noises.map((n) => plots[n])), confusionHolder, inertiaHolder);
  const names = classifier ? classifier.candidate_names : [];
  const chance = names.length ? 1 / names.length : null;
  const multiples = job.params.multiples || [];
  const follower = new MetricFollower(job.id);
  const live = Object.fromEntries(noises.map((n) => [n, { x: [], y: [] }]));
  const mainName = classifier ? classifierName(classifier) : "classifier";

  const draw = (noise, x, y, low, high, others = {}, result = null, limit = null) => {
    const trace = { x, y, mode: "lines+markers", name: mainName, line: { color: COLORS[0], width: 2.5 }, hovertemplate: "×%{x}: accuracy %{y:.3f}<extra>%{fullData.name}</extra>" };
    if (low) {
      trace.error_y = { type: "data", symmetric: false, array: high.map((v, i) => v - y[i]), arrayminus: low.map((v, i) => y[i] - v), color: COLORS[0] };
      trace.name += " (95 % interval)";
    }
    const traces = [trace];
    if (limit && limit.length) {
      // A result from before the ceiling holds only its old reference line: drawn, but not
      // called a ceiling (classifiers beat it).
      const name = result && result.ceiling && result.ceiling.length ? "ceiling" : "reference (not a ceiling)";
      traces.push({ x: limit.map((p) => p.multiple), y: limit.map((p) => p.accuracy), mode: "lines+markers", marker: { size: 5 }, name, line: { color: "#111", dash: "dash", width: 1.5 }, hovertemplate: `×%{x}: %{y:.3f}<extra>${name.split(":")[0]}</extra>` });
    }
    Object.entries(others).forEach(([label, points], i) => {
      const style = OTHER_STYLE[label] || { dash: "solid", color: COLORS[(i + 2) % COLORS.length], name: label };
      traces.push({ x: points.map((p) => p.multiple), y: points.map((p) => p.accuracy), mode: "lines+markers", marker: { size: 5 }, name: style.name, line: { color: style.color, dash: style.dash, width: 1.5 }, hovertemplate: "×%{x}: %{y:.3f}<extra>%{fullData.name}</extra>" });
    });
    if (chance !== null && x.length) {
      traces.push({ x: chanceSpan(x), y: [chance, chance], mode: "lines", name: "chance", line: { color: "#9a9a9a", dash: "longdash", width: 1 }, hoverinfo: "skip" });
    }
    Plotly.react(
      plots[noise],
      traces,
      layout(axisTitle(noise, result), "accuracy (fraction of test series)", {
        title: title(`Accuracy vs ${noiseInfo(noise).label}`),
        yaxis: { title: { text: "accuracy" }, range: [0, 1.03] },
        height: 420,
      }),
      PLOT_CONFIG,
    );
  };

  const showResult = (result) => {
    clear(state);
    const otherNames = Object.keys(result.others || {});
    state.append(
      h(
        "p",
        { class: "muted", id: "sweep-seeds" },
        `${result.n_test_per_candidate} test series per candidate and point. Seeds: the job's ${job.seed}; its test series come from ${result.seed}, a stream derived from it (the others' training and the bodies off the candidates use two more). Beside ${mainName}, on the same series: ${otherNames.join(", ") || "no other classifier"}${result.ceiling && result.ceiling.length ? `, and the ceiling (per-candidate Gaussians at each noise level, their covariance sampled from ${result.ceiling_realisations} realisations per candidate or written out by the scenario's noise model, whichever classified a validation draw better${result.ceiling_covariance && result.ceiling_covariance.length ? `: ${result.ceiling_covariance.filter((c) => c === "noise model").length} of ${result.ceiling_covariance.length} points took the noise model's` : ""})` : ""}.`,
      ),
    );
    if (result.ceiling && result.ceiling.length) state.append(ceilingCheck(result, mainName));
    for (const noise of noises) {
      const points = result.points.filter((p) => p.noise === noise);
      if (!points.length) continue;
      const others = Object.fromEntries(otherNames.map((label) => [label, result.others[label].filter((p) => p.noise === noise)]));
      const limit = ((result.ceiling && result.ceiling.length ? result.ceiling : result.limit) || []).filter((p) => p.noise === noise);
      draw(noise, points.map((p) => p.multiple), points.map((p) => p.accuracy), points.map((p) => p.ci_low), points.map((p) => p.ci_high), others, result, limit);
    }
    clear(confusionHolder);
    const noiseSelect = h("select", { id: "confusion-noise", "aria-label": "noise" }, [...new Set(result.points.map((p) => p.noise))].map((n) => h("option", { value: n }, n)));
    const multipleSelect = h("select", { id: "confusion-multiple", "aria-label": "noise multiple" });
    const whoSelect = h("select", { id: "confusion-classifier", "aria-label": "classifier" }, h("option", { value: "" }, mainName), otherNames.map((n) => h("option", { value: n }, n)));
    const plot = plotDiv("confusion-plot");
    const fillMultiples = () => {
      const chosen = multipleSelect.value;
      clear(multipleSelect);
      for (const p of result.points.filter((q) => q.noise === noiseSelect.value)) {
        multipleSelect.append(h("option", { value: String(p.multiple), selected: String(p.multiple) === chosen }, `×${p.multiple}`));
      }
    };
    const drawConfusion = () => {
      const source = whoSelect.value ? result.others[whoSelect.value] : result.points;
      const point = source.find((p) => p.noise === noiseSelect.value && String(p.multiple) === multipleSelect.value);
      const who = whoSelect.value || mainName;
      if (point) confusionPlot(plot, point.confusion, result.candidate_names, `${who}, ${point.noise} ×${point.multiple}: accuracy ${score(point.accuracy)} (95 % interval ${score(point.ci_low)}–${score(point.ci_high)})`);
    };
    noiseSelect.addEventListener("change", () => {
      fillMultiples();
      drawConfusion();
    });
    multipleSelect.addEventListener("change", drawConfusion);
    whoSelect.addEventListener("change", drawConfusion);
    fillMultiples();
    confusionHolder.append(
      h("h2", {}, "Confusion matrix at a noise level"),
      h("div", { class: "toolbar" }, h("label", { for: "confusion-classifier" }, "classifier"), whoSelect, h("label", { for: "confusion-noise" }, "noise"), noiseSelect, h("label", { for: "confusion-multiple" }, "multiple"), multipleSelect),
      plot,
    );
    drawConfusion();
    if (result.inertia) inertiaPlots(inertiaHolder, result.inertia);
  };

  let finished = false;
  const update = async (current) => {
    if (finished) return;
    if (current.result && current.result.points) {
      finished = true;
      showResult(current.result);
      return;
    }
    clear(state);
    state.append(h("div", { class: "toolbar" }, statusBadge(current.status), h("span", { class: "muted" }, current.status === "failed" ? current.error || "" : "points appear as the sweep measures them; intervals, the other classifiers and confusion matrices when it finishes")));
    const fresh = await follower.poll();
    if (!context.alive()) return;
    for (const noise of noises) {
      const series = fresh[`accuracy_${noise}`];
      if (!series) continue;
      series.steps.forEach((step, i) => {
        live[noise].x.push(multiples[step] ?? step);
        live[noise].y.push(series.values[i]);
      });
      draw(noise, live[noise].x, live[noise].y);
    }
  };
  await update(job);
  return { update };
}

// Bodies that are none of the candidates: how often the answer is "matches none".
function inertiaPlots(holder, inertia) {
  clear(holder);
  const names = inertia.candidate_names;
  const scaled = inertia.points.filter((p) => p.body === "scaled");
  const between = inertia.points.filter((p) => p.body === "between");
  const plot = plotDiv("inertia-plot");
  holder.append(
    h("h2", {}, "Bodies off the candidates: is the answer \"matches none\"?"),
    h("p", { class: "hint" }, `Scaled: ${names[inertia.base]}'s inertia times a factor (1 is the candidate itself). Between: from ${names[inertia.pair[0]]} (0) to ${names[inertia.pair[1]]} (1), the two closest candidates. Ideal: 0 at the candidates, 1 away from them.`),
    plot,
  );
  const trace = (points, axis, color, name) => ({
    x: points.map((p) => p.parameter),
    y: points.map((p) => p.matches_none_rate),
    xaxis: axis === 1 ? "x" : "x2",
    yaxis: axis === 1 ? "y" : "y2",
    mode: "lines+markers",
    name,
    line: { color },
    error_y: { type: "data", symmetric: false, array: points.map((p) => p.ci_high - p.matches_none_rate), arrayminus: points.map((p) => p.matches_none_rate - p.ci_low), color },
    text: points.map((p) => `nearest: ${p.predicted.map((c, k) => (c ? `${plotText(names[k])} ${c}` : "")).filter((t) => t).join(", ")}`),
    hovertemplate: "%{x}: matches none %{y:.2f}<br>%{text}<extra></extra>",
  });
  Plotly.newPlot(
    plot,
    [trace(scaled, 1, COLORS[4], "scaled body"), trace(between, 2, COLORS[5], "in-between body")],
    layout("", "", {
      height: 380,
      xaxis: { title: { text: `scale of ${plotText(names[inertia.base])}'s inertia (×)` }, domain: [0, 0.44], anchor: "y" },
      yaxis: { title: { text: "fraction flagged \"matches none\"" }, range: [0, 1.05], anchor: "x" },
      xaxis2: { title: { text: "position between the closest two" }, domain: [0.56, 1], anchor: "y2" },
      yaxis2: { range: [0, 1.05], anchor: "x2" },
    }),
    PLOT_CONFIG,
  );
}
