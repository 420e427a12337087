// Classifiers and their noise sweeps: F1, fuel and final rate of the sequence, the
// confusion matrix, and accuracy against process and measurement noise with intervals.

import { MetricFollower, api } from "../api.js";
import { classifierName, isTerminal, noiseInfo, vocabulary } from "../vocabulary.js";
import {
  COLORS,
  HEAT_SCALE,
  PLOT_CONFIG,
  clear,
  fmt,
  h,
  layout,
  link,
  messageBox,
  plotDiv,
  responseLayout,
  responseTraces,
  score,
  sequencePlot,
  sequenceText,
  statusBadge,
  table,
  when,
} from "../ui.js";


export async function renderList(root) {
  root.append(h("h1", {}, "Classifiers"));
  const [page, scenarios] = await Promise.all([api.classifiers(), api.scenarios()]);
  const names = Object.fromEntries(scenarios.items.map((s) => [s.id, s.name]));
  if (!page.items.length) {
    root.append(messageBox("notice", "No classifier yet: submit a train job on the Jobs page."));
    return;
  }
  root.append(
    h(
      "div",
      { class: "card" },
      table(
        ["classifier", "scenario", "metric", "training F1", "accuracy", "sequence", "created", ""],
        page.items.map((c) => [
          link(`#/classifiers/${c.id}`, c.id.slice(0, 8), { title: c.id }),
          names[c.scenario_id] || c.scenario_id.slice(0, 8),
          c.metric,
          score(c.f1),
          score(c.accuracy),
          h("span", { class: "mono" }, sequenceText(c.sequence)),
          when(c.created_at),
          link(`#/identify?classifier=${c.id}`, "identify"),
        ]),
        { id: "classifier-table" },
      ),
    ),
  );
}

export async function renderOne(root, context) {
  const classifier = await api.classifier(context.params[0]);
  root.append(h("h1", {}, "Classifier ", h("code", {}, classifier.id.slice(0, 8))));
  await renderClassifier(root, classifier, context, context.query.sweep);
}

function confusionPlot(element, confusion, names, title) {
  const totals = confusion.map((row) => row.reduce((a, b) => a + b, 0) || 1);
  Plotly.newPlot(
    element,
    [
      {
        type: "heatmap",
        z: confusion.map((row, i) => row.map((v) => v / totals[i])),
        x: names,
        y: names,
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
      title: { text: title, font: { size: 14 } },
      yaxis: { title: { text: "true candidate" }, autorange: "reversed", automargin: true },
      height: 380,
    }),
    PLOT_CONFIG,
  );
}

export async function renderClassifier(container, classifier, context, sweepId = null) {
  const scenario = await api.scenario(classifier.scenario_id).catch(() => null);
  const summary = h("dl", { class: "kv", id: "classifier-summary" });
  const confusion = plotDiv("training-confusion");
  const seqPlot = plotDiv("classifier-sequence", "short");
  const responsePlot = plotDiv("classifier-response");
  const sweepCard = h("div", { class: "card", id: "sweep-card" });
  container.append(
    h(
      "div",
      { class: "toolbar" },
      link(`#/jobs?type=sweep&classifier=${classifier.id}`, "Run a noise sweep", { class: "button", id: "run-sweep" }),
      link(`#/identify?classifier=${classifier.id}`, "Identify telemetry", { class: "button secondary" }),
      link(`/classifiers/${classifier.id}/download`, "Download (JSON)", { class: "button secondary" }),
    ),
    h("div", { class: "row" }, h("div", { class: "card grow" }, h("h2", {}, "Classifier"), summary), h("div", { class: "card grow" }, h("h2", {}, "Training confusion"), confusion)),
    sweepCard,
    h("div", { class: "card" }, h("h2", {}, "The sequence"), seqPlot, h("h3", {}, "Each candidate's response (mean and 10–90 % band)"), responsePlot),
  );
  const rows = [
    ["classifier", h("code", {}, classifier.id)],
    ["scenario", link(`#/scenarios/${classifier.scenario_id}`, scenario ? scenario.name : classifier.scenario_id)],
    ["kind", h("span", { id: "classifier-kind" }, classifier.kind)],
    ["metric", classifier.metric],
    ["training F1", h("span", { id: "classifier-f1" }, score(classifier.f1))],
    ["training accuracy", score(classifier.accuracy)],
    ["sequence (level indices)", h("span", { class: "mono" }, sequenceText(classifier.sequence))],
    ["created", when(classifier.created_at)],
    ["trained by job", classifier.job_id ? link(`#/jobs/${classifier.job_id}`, classifier.job_id.slice(0, 8)) : "–"],
  ];
  const fuel = h("span", { id: "classifier-fuel" }, "…");
  const finalRate = h("span", {}, "…");
  rows.push(["fuel (commanded impulse)", fuel], ["mean final rate", finalRate]);
  for (const [name, value] of rows) summary.append(h("dt", {}, name), h("dd", {}, value));
  confusionPlot(confusion, classifier.confusion, classifier.candidate_names, "training series");

  await sweepsOf(sweepCard, classifier, context, sweepId);

  try {
    const response = await api.response(classifier.scenario_id, classifier.sequence, { n_realisations: 20 });
    if (!context.alive()) return;
    fuel.textContent = `${response.impulse_nms.toFixed(1)} N m s`;
    const rates = response.candidates.map((c) => c.final_rate_rad_s);
    finalRate.textContent = `${fmt(rates.reduce((a, b) => a + b, 0) / rates.length, 4)} rad/s`;
    sequencePlot(seqPlot, response);
    Plotly.newPlot(responsePlot, responseTraces(response), responseLayout("ω response to the classifier's sequence"), PLOT_CONFIG);
  } catch (exc) {
    fuel.textContent = exc.message;
  }
}

async function sweepsOf(card, classifier, context, sweepId) {
  const page = await api.jobs({ type: "sweep", scenario_id: classifier.scenario_id, limit: 200 });
  const sweeps = page.items.filter((j) => j.params.classifier_id === classifier.id);
  card.append(h("h2", {}, "Accuracy against noise"));
  if (!sweeps.length) {
    card.append(messageBox("notice", "No sweep of this classifier yet: run one to see its accuracy as noise grows."));
    return;
  }
  const chosen = sweeps.find((j) => j.id === sweepId) || sweeps.find((j) => j.status === "succeeded") || sweeps[0];
  const select = h(
    "select",
    { id: "sweep-select", "aria-label": "sweep" },
    sweeps.map((j) => h("option", { value: j.id, selected: j.id === chosen.id }, `${j.id.slice(0, 8)} · ${j.status} · ${when(j.created_at)}`)),
  );
  const holder = h("div");
  card.append(h("div", { class: "toolbar" }, h("label", { for: "sweep-select" }, "sweep"), select, link(`#/jobs/${chosen.id}`, "job page")), holder);
  const show = async (job) => {
    clear(holder);
    const panel = await sweepPanel(holder, job, classifier, context);
    if (!isTerminal(job.status)) {
      const timer = setInterval(async () => {
        if (!context.alive()) return clearInterval(timer);
        const fresh = await api.job(job.id).catch(() => null);
        if (!fresh) return;
        await panel.update(fresh);
        if (isTerminal(fresh.status)) clearInterval(timer);
      }, 2000);
    }
  };
  select.addEventListener("change", async () => show(await api.job(select.value)));
  await show(chosen);
}

// Accuracy vs each source of error's multiple with 95 % intervals, the other
// classifiers scored on the same series (the likelihood limit dashed, least squares
// dotted), the confusion matrix at a chosen point, and how often bodies off the
// candidates get "matches none". While the sweep runs, the main classifier's points come
// from the job's metrics; the finished result brings the rest.
const OTHER_STYLE = {
  likelihood: { dash: "dashdot", color: "#555", name: "likelihood trained at 1×" },
  "least-squares": { dash: "dot", color: "#8c564b", name: "least squares (physics)" },
};

function axisTitle(noise, result) {
  const { label, unit } = noiseInfo(noise);
  const level = result && result.levels ? result.levels[noise] : null;
  if (level === null || level === undefined) return `multiple of the 1× ${label}`;
  return `multiple of the 1× ${label} (${Number(level.toPrecision(2))} ${unit})`;
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
      traces.push({ x: limit.map((p) => p.multiple), y: limit.map((p) => p.accuracy), mode: "lines+markers", marker: { size: 5 }, name: "limit: likelihood fitted at each noise", line: { color: "#111", dash: "dash", width: 1.5 }, hovertemplate: "×%{x}: %{y:.3f}<extra>the limit</extra>" });
    }
    Object.entries(others).forEach(([label, points], i) => {
      const style = OTHER_STYLE[label] || { dash: "solid", color: COLORS[(i + 2) % COLORS.length], name: label };
      traces.push({ x: points.map((p) => p.multiple), y: points.map((p) => p.accuracy), mode: "lines+markers", marker: { size: 5 }, name: style.name, line: { color: style.color, dash: style.dash, width: 1.5 }, hovertemplate: "×%{x}: %{y:.3f}<extra>%{fullData.name}</extra>" });
    });
    if (chance !== null && x.length) {
      traces.push({ x: [Math.min(...x), Math.max(...x)], y: [chance, chance], mode: "lines", name: "chance", line: { color: "#9a9a9a", dash: "longdash", width: 1 }, hoverinfo: "skip" });
    }
    Plotly.react(
      plots[noise],
      traces,
      layout(axisTitle(noise, result), "accuracy (fraction of test series)", {
        title: { text: `Accuracy vs ${noiseInfo(noise).label}`, font: { size: 14 } },
        yaxis: { title: { text: "accuracy (fraction of test series)" }, range: [0, 1.03] },
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
        { class: "muted" },
        `${result.n_test_per_candidate} test series per candidate and point, seed ${result.seed}. Beside ${mainName}, on the same series: ${otherNames.join(", ") || "no other classifier"}${result.limit && result.limit.length ? `, and the limit (a likelihood classifier fitted on ${result.limit_realisations} realisations per candidate at each noise level)` : ""}.`,
      ),
    );
    for (const noise of noises) {
      const points = result.points.filter((p) => p.noise === noise);
      if (!points.length) continue;
      const others = Object.fromEntries(otherNames.map((label) => [label, result.others[label].filter((p) => p.noise === noise)]));
      const limit = (result.limit || []).filter((p) => p.noise === noise);
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
      h("h3", {}, "Confusion matrix at a noise level"),
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
    h("h3", {}, "Bodies off the candidates: is the answer \"matches none\"?"),
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
    text: points.map((p) => `nearest: ${p.predicted.map((c, k) => (c ? `${names[k]} ${c}` : "")).filter((t) => t).join(", ")}`),
    hovertemplate: "%{x}: matches none %{y:.2f}<br>%{text}<extra></extra>",
  });
  Plotly.newPlot(
    plot,
    [trace(scaled, 1, COLORS[4], "scaled body"), trace(between, 2, COLORS[5], "in-between body")],
    {
      ...layout("", ""),
      height: 380,
      xaxis: { title: { text: `scale of ${names[inertia.base]}'s inertia (×)` }, domain: [0, 0.46], anchor: "y" },
      yaxis: { title: { text: "fraction flagged \"matches none\"" }, range: [0, 1.05], anchor: "x" },
      xaxis2: { title: { text: "position between the closest two candidates" }, domain: [0.54, 1], anchor: "y2" },
      yaxis2: { range: [0, 1.05], anchor: "x2" },
    },
    PLOT_CONFIG,
  );
}
