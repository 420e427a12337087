// Compare runs: searches (fresh F1, residual rate, commanded impulse and time on one table, and
// their learning curves on the same axes), sweeps, or classifiers (through their latest
// finished sweep: accuracy curves of several on one plot). Restricted to one scenario,
// or grouped by scenario: runs of different scenarios never share a plot.
//
// Route: #/compare?type=search|sweep|classifier&ids=a,b&scenario=<id>

import { MetricFollower, api } from "../api.js";
import { jobCell, jobDetail, searchScore, stoppedNote, summaryColumns, summaryValue } from "../components/jobs.js";
import { BestSoFar, COLORS, PLOT_CONFIG, extendWith, layout, plotDiv, plotText, polishMarks, polishStart, tightRange, title } from "../components/plots.js";
import { dataTable } from "../components/table.js";
import { classifierName, isTerminal, noiseInfo } from "../vocabulary.js";
import { h, link, messageBox, quantity, rateDeg, rateRad, score, statusBadge, tagChips, when } from "../ui.js";

const TYPES = [
  ["search", "Searches"],
  ["sweep", "Sweeps"],
  ["classifier", "Classifiers"],
];

function hashFor(type, ids, scenario) {
  const query = new URLSearchParams({ type });
  if (ids.length) query.set("ids", ids.join(","));
  if (scenario) query.set("scenario", scenario);
  return `#/compare?${query.toString().replace(/%2C/g, ",")}`;
}

export async function render(root, context) {
  const ids = (context.query.ids || context.query.jobs || "").split(",").filter((v) => v);
  let type = context.query.type;
  if (!type && ids.length) {
    const first = await api.job(ids[0]).catch(() => null);
    type = first ? first.type : "search";
  }
  if (!TYPES.some(([t]) => t === type)) type = "search";
  const scenarioFilter = context.query.scenario || "";
  const scenarios = (await api.scenarios()).items;
  const scenarioName = Object.fromEntries(scenarios.map((s) => [s.id, s.name]));

  root.append(
    h("h1", {}, "Compare runs"),
    h(
      "div",
      { class: "tabs", role: "tablist" },
      TYPES.map(([t, label]) => h("a", { class: "button", role: "tab", id: `compare-tab-${t}`, "aria-selected": String(t === type), href: hashFor(t, [], scenarioFilter) }, label)),
    ),
  );
  const scenarioSelect = h(
    "select",
    { id: "compare-scenario", "aria-label": "scenario" },
    h("option", { value: "" }, "every scenario, grouped"),
    scenarios.map((s) => h("option", { value: s.id, selected: s.id === scenarioFilter }, `only ${s.name}`)),
  );
  scenarioSelect.addEventListener("change", () => {
    location.hash = hashFor(type, ids, scenarioSelect.value);
  });
  const results = h("div", { id: "compare-results" });
  const picker = pickerTable(type, ids, scenarioFilter, scenarios);
  root.append(
    h("div", { class: "card" }, h("div", { class: "toolbar" }, h("label", { for: "compare-scenario" }, "scenarios"), scenarioSelect, h("span", { class: "hint" }, "runs of different scenarios are never drawn on one plot")), results),
    h("div", { class: "card" }, h("h2", {}, `Pick ${TYPES.find(([t]) => t === type)[1].toLowerCase()} to compare`), picker.node),
  );
  await picker.refresh();

  const items = await load(type, ids);
  const shown = items.filter((item) => !scenarioFilter || item.scenario_id === scenarioFilter);
  if (!shown.length) {
    const why = !ids.length
      ? "Tick runs below to compare them."
      : items.length
        ? "None of the chosen runs belongs to this scenario."
        : `No ${type} run has the id${ids.length > 1 ? "s" : ""} ${ids.join(", ")} (unknown, deleted, or a run of another type).`;
    results.append(messageBox("notice", why));
    return;
  }
  const groups = new Map();
  for (const item of shown) {
    if (!groups.has(item.scenario_id)) groups.set(item.scenario_id, []);
    groups.get(item.scenario_id).push(item);
  }
  let index = 0;
  const pollers = [];
  for (const [scenarioId, members] of groups) {
    const section = h("section", { class: "compare-group", dataset: { scenario: scenarioId } }, h("h2", {}, "Scenario ", link(`#/scenarios/${scenarioId}`, scenarioName[scenarioId] || scenarioId.slice(0, 8))));
    results.append(section);
    const suffix = index++ === 0 ? "" : `-${index}`;
    if (type === "search") pollers.push(await searchGroup(section, members, suffix, context));
    else await sweepGroup(section, members, suffix, type);
  }
  const live = pollers.filter((p) => p);
  if (live.length) context.every(3000, () => Promise.all(live.map((poll) => poll())));
}

function pickerTable(type, ids, scenarioFilter, scenarios) {
  const names = Object.fromEntries(scenarios.map((s) => [s.id, s.name]));
  const select = {
    initial: ids,
    label: (row) => `compare ${row.id}`,
    onChange: (chosen) => {
      location.hash = hashFor(type, chosen, scenarioFilter);
    },
  };
  const filters = [{ name: "q", label: "search", type: "text", placeholder: "name, tag or id" }];
  if (type === "classifier") {
    return dataTable({
      id: "compare-picker",
      load: (q) => api.classifiers({ ...q, scenario_id: scenarioFilter || undefined }),
      filters,
      select,
      pageSize: 10,
      columns: [
        { key: "classifier", label: "classifier", sort: "name", cell: (c) => [link(`#/classifiers/${c.id}`, c.job_name || c.id.slice(0, 8)), " ", tagChips(c.tags)] },
        { key: "kind", label: "kind", sort: "kind", cell: (c) => classifierName(c) },
        { key: "scenario", label: "scenario", cell: (c) => names[c.scenario_id] || c.scenario_id.slice(0, 8) },
        { key: "f1", label: "training F1", sort: "f1", num: true, cell: (c) => score(c.f1) },
        { key: "created", label: "created", sort: "created", cell: (c) => when(c.created_at) },
      ],
    });
  }
  return dataTable({
    id: "compare-picker",
    load: (q) => api.jobs({ ...q, type, scenario_id: scenarioFilter || undefined }),
    filters,
    select,
    pageSize: 10,
    columns: [
      { key: "run", label: "run", sort: "name", cell: jobCell },
      { key: "status", label: "status", sort: "status", cell: (job) => [statusBadge(job.status), stoppedNote(job)] },
      { key: "scenario", label: "scenario", cell: (job) => names[job.scenario_id] || job.scenario_id.slice(0, 8) },
      ...summaryColumns(type)
        .slice(0, 3)
        .map((c) => ({ key: c.key, label: c.label, unit: c.unit, sort: c.key, num: true, cell: (job) => summaryValue(job, c) })),
      { key: "created", label: "created", sort: "created", cell: (job) => when(job.created_at) },
    ],
  });
}

// The chosen runs: jobs, or classifiers each with its latest finished sweep.
async function load(type, ids) {
  if (type === "classifier") {
    const classifiers = await Promise.all(ids.map((id) => api.classifier(id).catch(() => null)));
    return Promise.all(
      classifiers
        .filter((c) => c)
        .map(async (c) => {
          // Its points are drawn: the one sweep comes with its result.
          const page = await api.jobs({ type: "sweep", classifier_id: c.id, status: "succeeded", limit: 1, include: "result" });
          return { ...c, sweep: page.items[0] || null };
        }),
    );
  }
  const jobs = await Promise.all(ids.map((id) => api.job(id).catch(() => null)));
  return jobs.filter((job) => job && job.type === type);
}

// A search's name, method and score: NSGA-II's is a predicted accuracy (its legend said
// "F1", under a title that says predicted accuracy).
const searchLabel = (job) => `${plotText(job.name || job.id.slice(0, 8))} (${job.params.method}, ${searchScore(job)})`;

// Searches of one scenario: a table of their headline figures, and their curves.
async function searchGroup(section, jobs, suffix, context) {
  const columns = summaryColumns("search");
  section.append(
    h(
      "table",
      { class: "compare-table", id: `compare-table${suffix}` },
      h("thead", {}, h("tr", {}, h("th", {}, "search"), h("th", {}, "status"), columns.map((c) => h("th", { class: "num" }, c.label, c.unit ? ` (${c.unit})` : "")))),
      h(
        "tbody",
        {},
        jobs.map((job, i) =>
          h(
            "tr",
            { dataset: { id: job.id } },
            h("td", {}, h("span", { class: "swatch", style: `background: ${COLORS[i % COLORS.length]}` }), jobCell(job)),
            h("td", {}, statusBadge(job.status), stoppedNote(job)),
            columns.map((c) => h("td", { class: "num" }, summaryValue(job, c))),
          ),
        ),
      ),
    ),
    h("p", { class: "hint" }, "Fresh F1: the best sequence's clustering F1 on fresh noise draws, whatever the search scored. Score on the search's draw: its F1, or its separability score for a separability search. Residual rate: |ω| once the actuation lag has delivered its torque (ω(0) included), mean over the candidates on the fresh draws. Commanded impulse: every thruster's torque times its on-time, summed (N m s), a propellant proxy, not a mass: a scenario that states its thrust and specific impulse gives its propellant in kg on the search's page."),
  );
  const reward = plotDiv(`compare-reward${suffix}`);
  const best = plotDiv(`compare-best${suffix}`);
  const tradeoff = plotDiv(`compare-tradeoff${suffix}`, "short");
  section.append(h("div", { class: "grid2" }, reward, best), tradeoff);
  const traces = () => jobs.map((job, i) => ({ x: [], y: [], mode: "lines+markers", name: searchLabel(job), line: { color: COLORS[i % COLORS.length] } }));
  // Where each finished NSGA-II search's polish rounds begin on its curve: a dashed line
  // in its colour (its points before are its generations), on the score's plot (NSGA-II
  // has no episode reward).
  const marks = jobs.flatMap((job, i) => {
    const start = polishStart(job);
    return start && start.rounds ? [{ x: start.timesteps, label: `${job.name || job.id.slice(0, 8)}: polish starts`, color: COLORS[i % COLORS.length] }] : [];
  });
  const polish = polishMarks(marks);
  Plotly.newPlot(reward, traces(), layout("environment steps", "mean episode reward", { title: title("Mean episode reward (each search's own reward)"), showlegend: true }), PLOT_CONFIG);
  Plotly.newPlot(
    best,
    traces(),
    layout("environment steps", "best score so far", {
      title: title("Best score so far (F1, separability or NSGA-II's predicted accuracy)"),
      showlegend: true,
      yaxis: { title: { text: "best score so far" }, range: [0, 1.05] },
      ...polish,
    }),
    PLOT_CONFIG,
  );
  const done = jobs.filter((j) => j.summary && j.summary.fresh_f1 !== null && j.summary.fresh_f1 !== undefined);
  Plotly.newPlot(
    tradeoff,
    done.map((job) => ({
      x: [job.summary.fuel_nms],
      y: [job.summary.fresh_f1],
      mode: "markers+text",
      text: [plotText(job.name || job.id.slice(0, 8))],
      textposition: "top center",
      marker: { size: 12, color: COLORS[jobs.indexOf(job) % COLORS.length] },
      name: searchLabel(job),
      hovertemplate: `%{text}: fresh F1 %{y:.3f}, ${quantity(job.summary.fuel_nms)} N m s, residual ${rateRad(job.summary.residual_rate_rad_s)} rad/s (${rateDeg(Number.isFinite(job.summary.residual_rate_rad_s) ? (job.summary.residual_rate_rad_s * 180) / Math.PI : null)} deg/s)<extra></extra>`,
    })),
    layout("commanded impulse (N m s)", "fresh F1 (mean)", {
      title: title("Separation against commanded impulse"),
      height: 340,
      showlegend: false,
      xaxis: { title: { text: "commanded impulse (N m s)" }, range: tightRange(done.map((j) => j.summary.fuel_nms), 0.2) },
      yaxis: { title: { text: "fresh F1 (mean)" }, range: tightRange(done.map((j) => j.summary.fresh_f1), 0.35) },
    }),
    PLOT_CONFIG,
  );
  const followers = jobs.map((job) => new MetricFollower(job.id));
  // NSGA-II's best line as the best so far, for searches stored before it was.
  const bests = jobs.map((job) => new BestSoFar(job));
  const poll = async () => {
    const batches = await Promise.all(followers.map(async (f, i) => bests[i].apply(await f.poll())));
    if (!context.alive()) return;
    for (const [plot, key] of [
      [reward, "mean_episode_reward"],
      [best, "best_f1"],
    ]) {
      batches.forEach((fresh, i) => extendWith(plot, fresh, jobs.map((_, j) => (j === i ? key : null))));
    }
  };
  await poll();
  return jobs.some((j) => !isTerminal(j.status)) ? poll : null;
}

// Sweeps (or classifiers through their latest sweep) of one scenario: their accuracy
// against each source of error on one plot per source, with intervals; their figures in
// a table.
async function sweepGroup(section, members, suffix, type) {
  const entries = [];
  for (const member of members) {
    const job = type === "classifier" ? member.sweep : member;
    const classifier = type === "classifier" ? member : await api.classifier(member.params.classifier_id).catch(() => null);
    const label = type === "classifier" ? `${member.job_name || member.id.slice(0, 8)} (${classifierName(member)})` : `${member.name || member.id.slice(0, 8)}${classifier ? ` (${classifierName(classifier)})` : ""}`;
    entries.push({ member, job, classifier, label });
  }
  const columns = summaryColumns("sweep");
  section.append(
    h(
      "table",
      { class: "compare-table", id: `compare-table${suffix}` },
      h("thead", {}, h("tr", {}, h("th", {}, type === "classifier" ? "classifier" : "sweep"), h("th", {}, "training F1"), h("th", {}, "sweep"), columns.map((c) => h("th", { class: "num" }, c.label)))),
      h(
        "tbody",
        {},
        entries.map((e, i) =>
          h(
            "tr",
            { dataset: { id: e.member.id } },
            h("td", {}, h("span", { class: "swatch", style: `background: ${COLORS[i % COLORS.length]}` }), type === "classifier" ? link(`#/classifiers/${e.member.id}`, e.label) : jobCell(e.member)),
            h("td", { class: "num" }, e.classifier ? score(e.classifier.f1) : "–"),
            h("td", {}, e.job ? [link(`#/jobs/${e.job.id}`, e.job.name || e.job.id.slice(0, 8)), h("div", { class: "hint" }, jobDetail(e.job))] : h("span", { class: "muted" }, "no finished sweep yet")),
            columns.map((c) => h("td", { class: "num" }, e.job ? summaryValue(e.job, c) : "–")),
          ),
        ),
      ),
    ),
  );
  const noises = [...new Set(entries.flatMap((e) => (e.job && e.job.result ? e.job.result.points.map((p) => p.noise) : [])))];
  if (!noises.length) {
    section.append(messageBox("notice", "No finished sweep among these yet: accuracy curves appear once one has points."));
    return;
  }
  // Every plot's cell is in the grid before the first is drawn: Plotly takes its width
  // from the cell once, and the first plot, drawn alone in the grid, was drawn the whole
  // row wide (1,212 px in a 599 px cell), its highest multiples and its legend hidden
  // under the next plot.
  const plots = noises.map((noise) => plotDiv(`compare-accuracy-${noise}${suffix}`));
  section.append(h("div", { class: "grid2" }, plots));
  noises.forEach((noise, n) => {
    const plot = plots[n];
    const traces = [];
    entries.forEach((e, i) => {
      if (!e.job || !e.job.result) return;
      const points = e.job.result.points.filter((p) => p.noise === noise);
      if (!points.length) return;
      const color = COLORS[i % COLORS.length];
      traces.push({
        x: points.map((p) => p.multiple),
        y: points.map((p) => p.accuracy),
        mode: "lines+markers",
        name: plotText(e.label),
        line: { color, width: 2 },
        error_y: { type: "data", symmetric: false, array: points.map((p) => p.ci_high - p.accuracy), arrayminus: points.map((p) => p.accuracy - p.ci_low), color, thickness: 1 },
        hovertemplate: "×%{x}: %{y:.3f}<extra>%{fullData.name}</extra>",
      });
    });
    const { label } = noiseInfo(noise);
    Plotly.newPlot(
      plot,
      traces,
      layout("multiple of the 1× level", "accuracy", { title: title(`Accuracy vs ${label} (95 % intervals)`), yaxis: { title: { text: "accuracy" }, range: [0, 1.03] }, height: 400, showlegend: true }),
      PLOT_CONFIG,
    );
  });
}
