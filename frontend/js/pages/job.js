// One job: its status header, and what its type shows — a search's learning curves
// (fetched incrementally while it runs), best sequence and responses; a training's
// classifier; a sweep's accuracy against noise.

import { MetricFollower, api } from "../api.js";
import {
  PLOT_CONFIG,
  clear,
  duration,
  fmt,
  h,
  layout,
  link,
  messageBox,
  plotDiv,
  progressBar,
  put,
  responseLayout,
  responseTraces,
  score,
  sequencePlot,
  sequenceText,
  statusBadge,
  table,
  when,
} from "../ui.js";
import { renderClassifier, sweepPanel } from "./classifiers.js";
import { isTerminal } from "../vocabulary.js";
import { cancelJob } from "./jobs.js";

const POLL_MS = 2000;

function drawHeader(header, job, scenarioName) {
  clear(header);
  const notice = h("div");
  const cancel = isTerminal(job.status)
    ? null
    : h(
        "button",
        { type: "button", class: "danger", id: "cancel-job", disabled: job.cancel_requested, onclick: () => cancelJob(job, notice) },
        job.cancel_requested ? "cancel requested" : "Cancel job",
      );
  put(
    header,
    h("div", { class: "toolbar" }, statusBadge(job.status), progressBar(job.progress, job.status), h("span", { id: "job-duration" }, duration(job.started_at, job.finished_at)), cancel),
    notice,
    job.error ? messageBox("error", job.error) : null,
    h(
      "dl",
      { class: "kv" },
      h("dt", {}, "job"),
      h("dd", {}, h("code", {}, job.id)),
      h("dt", {}, "scenario"),
      h("dd", {}, link(`#/scenarios/${job.scenario_id}`, scenarioName || job.scenario_id)),
      h("dt", {}, "seed"),
      h("dd", {}, job.seed),
      h("dt", {}, "created / started / finished"),
      h("dd", {}, `${when(job.created_at)} / ${when(job.started_at)} / ${when(job.finished_at)}`),
      h("dt", {}, "worker, attempts"),
      h("dd", {}, `${job.worker || "–"}, ${job.attempts}`),
    ),
    h("details", {}, h("summary", {}, "parameters"), h("pre", { class: "mono" }, JSON.stringify(job.params, null, 2))),
  );
}

export async function render(root, context) {
  const [id] = context.params;
  let job = await api.job(id);
  const scenario = await api.scenario(job.scenario_id).catch(() => null);
  const header = h("div", { class: "card", id: "job-header" });
  const body = h("div", { id: "job-body" });
  root.append(h("h1", {}, `${job.type[0].toUpperCase()}${job.type.slice(1)} job `, h("code", {}, job.id.slice(0, 8))), header, body);
  drawHeader(header, job, scenario && scenario.name);
  const views = { search: searchView, train: trainView, sweep: sweepView };
  const view = await views[job.type](body, job, context);
  let done = isTerminal(job.status);
  const tick = async () => {
    if (done) {
      // Keep the duration honest while nothing else changes.
      return;
    }
    job = await api.job(id);
    if (!context.alive()) return;
    drawHeader(header, job, scenario && scenario.name);
    await view.update(job);
    done = isTerminal(job.status);
  };
  context.every(POLL_MS, tick);
}

// Search: reward and F1 curves that gain points as PPO writes them, then the result.
async function searchView(body, job, context) {
  const rewardPlot = plotDiv("reward-plot");
  const f1Plot = plotDiv("f1-plot");
  const pointCount = h("span", { id: "curve-points", class: "muted" }, "0 points");
  const resultHolder = h("div", { id: "search-result" });
  body.append(
    h(
      "div",
      { class: "card" },
      h("div", { class: "toolbar" }, h("h2", { style: "margin: 0" }, "Learning curve"), pointCount, link(`#/compare?jobs=${job.id}`, "compare with other searches")),
      h("div", { class: "grid2" }, rewardPlot, f1Plot),
    ),
    resultHolder,
  );
  Plotly.newPlot(
    rewardPlot,
    [{ x: [], y: [], mode: "lines+markers", name: "mean episode reward", line: { color: "#1f77b4" } }],
    layout("environment steps", "mean episode reward", { title: { text: "Reward per episode: −1 + 3·F1 per step, −|ω| (rad/s) at the last", font: { size: 13 } }, showlegend: false }),
    PLOT_CONFIG,
  );
  // A separability search scores sequences by the separability bound, not by F1.
  const what = job.params.objective === "separability" ? "separability score" : "clustering F1";
  Plotly.newPlot(
    f1Plot,
    [
      { x: [], y: [], mode: "lines+markers", name: `best ${what} so far`, line: { color: "#2ca02c" } },
      { x: [], y: [], mode: "lines+markers", name: `mean ${what} of the episodes since the last point`, line: { color: "#ff7f0e", dash: "dot" } },
    ],
    layout("environment steps", what, { title: { text: what, font: { size: 14 } }, yaxis: { title: { text: what }, range: [0, 1.05] } }),
    PLOT_CONFIG,
  );
  const follower = new MetricFollower(job.id);
  let points = 0;
  let resultShown = false;
  const update = async (current) => {
    const fresh = await follower.poll();
    if (!context.alive()) return;
    const extend = (plot, keys) => {
      const indices = [];
      const xs = [];
      const ys = [];
      keys.forEach((key, i) => {
        if (fresh[key]) {
          indices.push(i);
          xs.push(fresh[key].steps);
          ys.push(fresh[key].values);
        }
      });
      if (indices.length) Plotly.extendTraces(plot, { x: xs, y: ys }, indices);
    };
    extend(rewardPlot, ["mean_episode_reward"]);
    extend(f1Plot, ["best_f1", "mean_f1"]);
    if (fresh.mean_episode_reward) points += fresh.mean_episode_reward.steps.length;
    pointCount.textContent = `${points} point${points === 1 ? "" : "s"}${isTerminal(current.status) ? "" : " · updating live"}`;
    pointCount.dataset.points = String(points);
    if (!resultShown && isTerminal(current.status) && current.result) {
      resultShown = true;
      await searchResult(resultHolder, current, context);
    }
  };
  await update(job);
  return { update };
}

async function searchResult(holder, job, context) {
  const result = job.result;
  const best = result.best;
  const freshF1 = result.fresh.f1;
  const mean = freshF1.reduce((a, b) => a + b, 0) / Math.max(1, freshF1.length);
  const seqPlot = plotDiv("sequence-plot", "short");
  const responsePlot = plotDiv("response-plot");
  const trainHref = `#/jobs?type=train&scenario=${job.scenario_id}&sequence=${encodeURIComponent(sequenceText(best.sequence))}`;
  holder.append(
    h(
      "div",
      { class: "card" },
      h("h2", {}, "Best sequence"),
      h(
        "dl",
        { class: "kv", id: "best-summary" },
        h("dt", {}, "sequence (level indices)"),
        h("dd", { class: "mono", id: "best-sequence" }, sequenceText(best.sequence)),
        h("dt", {}, job.params.objective === "separability" ? "separability score on the search's draw" : "F1 on the search's noise draw"),
        h("dd", {}, score(best.f1)),
        h("dt", {}, `clustering F1 on ${freshF1.length} fresh draws`),
        h("dd", {}, `${score(mean)} mean (min ${score(Math.min(...freshF1))})`),
        h("dt", {}, "final rate"),
        h("dd", {}, `${fmt(best.final_rate_rad_s, 4)} rad/s`),
        h("dt", {}, "fuel (commanded impulse)"),
        h("dd", {}, `${best.fuel_nms.toFixed(1)} N m s`),
        h("dt", {}, "environment steps, episodes"),
        h("dd", {}, `${fmt(result.timesteps)}, ${fmt(result.episodes)}`),
        h("dt", {}, "wall time, stopped by"),
        h("dd", {}, `${fmt(result.wall_time_s, 3)} s, ${result.stopped}`),
      ),
      baselineTable(result, best, freshF1),
      h("div", { class: "toolbar" }, link(trainHref, "Train a classifier on this sequence", { class: "button", id: "train-best" })),
      h("h3", {}, "Thruster duty over time"),
      seqPlot,
      h("h3", {}, "Each candidate's response (mean and 10–90 % band over 20 noisy realisations)"),
      responsePlot,
    ),
  );
  try {
    const response = await api.response(job.scenario_id, best.sequence, { n_realisations: 20, seed: job.seed });
    if (!context.alive()) return;
    sequencePlot(seqPlot, response);
    Plotly.newPlot(responsePlot, responseTraces(response), responseLayout("ω response to the best sequence"), PLOT_CONFIG);
  } catch (exc) {
    responsePlot.replaceWith(messageBox("error", exc.message));
  }
}

// The best sequence beside the hand-designed baselines, on the same fresh draws.
function baselineTable(result, best, freshF1) {
  if (!result.baselines) return null;
  const mean = (values) => values.reduce((a, b) => a + b, 0) / Math.max(1, values.length);
  const rows = [["found by the search", freshF1, result.fresh.final_rate_rad_s, best.fuel_nms, best.sequence]];
  for (const [name, base] of Object.entries(result.baselines)) {
    // A baseline the sequence length or the thrusters do not allow says why instead.
    if (base.unavailable) continue;
    rows.push([name, base.fresh_f1, base.fresh_final_rate_rad_s, base.fuel_nms, base.sequence]);
  }
  return h(
    "div",
    {},
    h("h3", {}, `Against the hand-designed baselines, on the same ${freshF1.length} fresh draws`),
    table(
      ["sequence", "F1 mean", "F1 min", "final rate (rad/s)", "fuel (N m s)", "levels"],
      rows.map(([name, f1, rate, fuel, levels]) => [name, score(mean(f1)), score(Math.min(...f1)), fmt(mean(rate), 3), fuel.toFixed(1), h("span", { class: "mono" }, sequenceText(levels))]),
      { id: "baseline-table" },
    ),
  );
}

async function trainView(body, job, context) {
  const holder = h("div", { id: "train-result" });
  body.append(holder);
  let shown = false;
  const update = async (current) => {
    if (shown) return;
    if (current.status === "succeeded" && current.result) {
      shown = true;
      clear(holder);
      const classifier = await api.classifier(current.result.classifier_id);
      if (context.alive()) await renderClassifier(holder, classifier, context);
    } else if (!isTerminal(current.status)) {
      clear(holder);
      holder.append(messageBox("notice", "Training: the classifier appears here when the job finishes."));
    } else {
      shown = true;
    }
  };
  await update(job);
  return { update };
}

async function sweepView(body, job, context) {
  const holder = h("div", { id: "sweep-holder" });
  const classifierId = job.params.classifier_id;
  body.append(h("p", {}, "Classifier: ", link(`#/classifiers/${classifierId}`, classifierId)), holder);
  const classifier = await api.classifier(classifierId).catch(() => null);
  const panel = await sweepPanel(holder, job, classifier, context);
  return { update: (current) => panel.update(current) };
}
