// Several searches' learning curves on the same axes: pick jobs, see their reward and
// best-F1 curves overlaid (running ones keep gaining points).

import { MetricFollower, api } from "../api.js";
import { isTerminal } from "../vocabulary.js";
import { COLORS, PLOT_CONFIG, h, layout, link, messageBox, plotDiv, statusBadge, when } from "../ui.js";

function label(job) {
  return `${job.id.slice(0, 8)} · ${job.params.method} · L=${job.params.sequence_length} · seed ${job.seed}`;
}

export async function render(root, context) {
  const chosen = new Set((context.query.jobs || "").split(",").filter((v) => v));
  const page = await api.jobs({ type: "search", limit: 200 });
  root.append(h("h1", {}, "Compare searches"));
  if (!page.items.length) {
    root.append(messageBox("notice", "No search jobs yet: submit one on the Jobs page."));
    return;
  }
  const picker = h("tbody", { id: "compare-picker" });
  for (const job of page.items) {
    picker.append(
      h(
        "tr",
        {},
        h("td", {}, h("input", { type: "checkbox", id: `pick-${job.id}`, checked: chosen.has(job.id), onchange: (e) => { if (e.target.checked) chosen.add(job.id); else chosen.delete(job.id); location.hash = `#/compare?jobs=${[...chosen].join(",")}`; } })),
        h("td", {}, h("label", { for: `pick-${job.id}` }, label(job))),
        h("td", {}, statusBadge(job.status)),
        h("td", {}, job.result ? `best F1 ${job.result.best.f1.toFixed(3)}` : "–"),
        h("td", {}, when(job.created_at)),
        h("td", {}, link(`#/jobs/${job.id}`, "job page")),
      ),
    );
  }
  const reward = plotDiv("compare-reward");
  const f1 = plotDiv("compare-f1");
  root.append(
    h("div", { class: "card" }, h("h2", {}, "Learning curves"), chosen.size ? null : messageBox("notice", "Tick searches below to overlay their curves."), h("div", { class: "grid2" }, reward, f1)),
    h("div", { class: "card" }, h("h2", {}, "Search jobs"), h("table", {}, h("thead", {}, h("tr", {}, ["", "search", "status", "result", "created", ""].map((n) => h("th", {}, n)))), picker)),
  );
  const jobs = page.items.filter((j) => chosen.has(j.id));
  const traces = () =>
    jobs.map((job, i) => ({ x: [], y: [], mode: "lines+markers", name: label(job), line: { color: COLORS[i % COLORS.length] } }));
  Plotly.newPlot(reward, traces(), layout("environment steps", "mean episode reward", { title: { text: "Mean episode reward", font: { size: 14 } } }), PLOT_CONFIG);
  Plotly.newPlot(f1, traces(), layout("environment steps", "best clustering F1 so far", { title: { text: "Best F1", font: { size: 14 } }, yaxis: { title: { text: "best clustering F1 so far" }, range: [0, 1.05] } }), PLOT_CONFIG);
  const followers = jobs.map((job) => new MetricFollower(job.id));
  const poll = async () => {
    const batches = await Promise.all(followers.map((f) => f.poll()));
    if (!context.alive()) return;
    for (const [plot, key] of [[reward, "mean_episode_reward"], [f1, "best_f1"]]) {
      const indices = [];
      const xs = [];
      const ys = [];
      batches.forEach((fresh, i) => {
        if (fresh[key]) {
          indices.push(i);
          xs.push(fresh[key].steps);
          ys.push(fresh[key].values);
        }
      });
      if (indices.length) Plotly.extendTraces(plot, { x: xs, y: ys }, indices);
    }
  };
  await poll();
  if (jobs.some((j) => !isTerminal(j.status))) context.every(3000, poll);
}
