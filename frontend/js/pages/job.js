// One job: its header (status, name and tags, timing, downloads, cancel), and what its
// type shows: a search's learning curves (fetched incrementally while it runs), best
// sequence and responses; a training's classifier; a sweep's accuracy against noise.

import { MetricFollower, api } from "../api.js";
import { downloads, jobDownloads } from "../components/downloads.js";
import { REUSED_KEY, cancelButton, labelEditor, reusedNotice, timingCell } from "../components/jobs.js";
import { redrawWhenRekeyed, whenKeyed } from "../components/keyed.js";
import { BAND, BestSoFar, DEG_PER_RAD, PLOT_CONFIG, extendWith, fitFlatSeries, keepTwins, layout, plotDiv, polishMarks, polishStart, responseView, sequencePlot, splitInfeasible, title, twinAxes, twinTraces } from "../components/plots.js";
import { isTerminal } from "../vocabulary.js";
import { clear, fmt, h, link, messageBox, patch, plain, progressBar, put, quantity, rateDeg, rateRad, score, sequenceText, statusBadge, table, tagChips, utcText, warningsBox, whenText } from "../ui.js";
import { renderClassifier } from "../views/classifier.js";
import { frontPanel } from "../views/front.js";
import { sweepPanel } from "../views/sweep.js";

const POLL_MS = 2000;
const RAD_TO_DEG = 180 / Math.PI;

// One part of the job's header, a place in `parent`: `show(node)` writes `node` there only
// where it differs from what the part shows (ui.js patch); `show(node, key)`, for a part
// with listeners, puts `node` in whole when `key` (what they read of the job) changed, and
// else keeps the one shown with its listeners. A null node shows nothing.
function part(parent) {
  let shown = parent.appendChild(document.createComment(""));
  let shownKey;
  return (node, key) => {
    const wanted = node ?? document.createComment("");
    if (key === undefined) {
      shown = patch(shown, wanted);
    } else if (key !== shownKey) {
      shown.replaceWith(wanted);
      shown = wanted;
      shownKey = key;
    }
  };
}

// The header of a job: `draw(job)` at every poll. A running job's header was cleared and
// drawn again every 2 s: text the user had selected in it (a job id to copy) was lost, the
// focus left the cancel button and the header flickered. Each part is compared with what
// it shows now, and only what changed is written (the time ran, the progress).
// `notice`: what the cancel button says (a refusal, the key it needs), kept across draws.
// The parts the user opened ("parameters", "name and tags") stay open.
function jobHeader(header, scenarioName, onLabels, notice) {
  const toolbar = h("div", { class: "toolbar" });
  const [status, progress, duration, tags, cancel] = [0, 1, 2, 3, 4].map(() => part(toolbar));
  header.append(toolbar, notice);
  const [error, facts, labels, parameters, results] = [0, 1, 2, 3, 4].map(() => part(header));
  const open = (id) => Boolean(header.querySelector(`details[open]#${id}`));
  return (job) => {
    status(statusBadge(job.status));
    progress(progressBar(job.progress, job.status));
    duration(h("span", { id: "job-duration" }, timingCell(job)));
    // Contents: each tag stays an item of the toolbar, as drawn loose before.
    tags(h("span", { style: "display: contents" }, tagChips(job.tags)));
    // Its click asks "Cancel <name>?", worded by the status; disabled once asked.
    const cancelKey = JSON.stringify([job.id, job.status, job.name, job.cancel_requested]);
    cancel(cancelButton(job, notice, () => {}, { id: "cancel-job", text: "Cancel job" }), cancelKey);
    error(job.error ? messageBox("error", job.error) : null);
    facts(
      h(
        "dl",
        { class: "kv" },
        h("dt", {}, "job"),
        h("dd", {}, h("code", {}, job.id)),
        h("dt", {}, "scenario"),
        h("dd", {}, link(`#/scenarios/${job.scenario_id}`, scenarioName || job.scenario_id)),
        h("dt", {}, "seed"),
        h("dd", { id: "job-seed" }, job.seed),
        h("dt", {}, "created"),
        h("dd", {}, whenText(job.created_at)),
        h("dt", {}, "started"),
        h("dd", {}, whenText(job.started_at)),
        h("dt", {}, "finished"),
        h("dd", {}, whenText(job.finished_at)),
        h("dt", {}, "worker, runs"),
        h("dd", { id: "job-runs" }, `${job.worker || "–"}, ${runsText(job)}`),
        h("dt", {}, "time limit"),
        h("dd", { id: "job-time-limit" }, timeLimitText(job)),
        ...lostRuns(job.attempt_history || []),
      ),
    );
    // The editor's inputs start from the name and tags, and its save reads the job's id.
    // Open, it is left alone while the user types (a poll with other labels would put it
    // in anew); the rest of the header goes on being drawn.
    if (!open("job-labels")) {
      labels(
        h("details", { id: "job-labels" }, h("summary", {}, "name and tags"), labelEditor(job, onLabels)),
        JSON.stringify([job.id, job.name, job.tags]),
      );
    }
    parameters(h("details", { id: "job-parameters", open: open("job-parameters") }, h("summary", {}, "parameters"), h("pre", { class: "mono" }, JSON.stringify(job.params, null, 2))));
    results(job.result ? downloads("job-downloads", jobDownloads(job), { label: "Download the result" }) : null);
  };
}

// "600 s (asked); stopped on it" or "the service's ceiling": the job's `stopped` says its
// limit stopped it (a search or sweep past it succeeds with what it had, a training fails
// naming it), read as a field, not matched in the error's words.
function timeLimitText(job) {
  const asked = job.params ? job.params.time_limit_s : null;
  const limit = typeof asked === "number" ? `${plain(asked)} s (asked)` : "the service's ceiling";
  return job.stopped === "time_limit" ? `${limit}; stopped on it` : limit;
}

// "3 runs: 2 handed back, 1 counted": a hand-back (a worker told to stop) costs no
// attempt, so the bare attempts count (3) read like failed tries.
function runsText(job) {
  const runs = `${job.attempts} run${job.attempts === 1 ? "" : "s"}`;
  if (!job.handbacks) return runs;
  const counted = job.counted_attempts ?? job.attempts - job.handbacks;
  return `${runs}: ${job.handbacks} handed back, ${counted} counted`;
}

// The runs taken from the job (a worker killed, a heartbeat missed, a worker told to
// stop): a later run's claim overwrote their start and worker above.
// "attempt 1 lost at … UTC: heartbeat missed; re-queued", its worker and times beneath,
// the reason in words as the line's title.
function lostRuns(history) {
  if (!history.length) return [];
  const line = (run) =>
    h(
      "div",
      { class: "lost-run", title: run.reason },
      `attempt ${run.attempt} ${run.outcome} at ${utcText(run.ended_at)}: ${run.cause}; ${run.then}`,
      h("div", { class: "hint" }, `worker ${run.worker || "unknown"}, started ${utcText(run.started_at)}, last heartbeat ${utcText(run.last_heartbeat_at)}`),
    );
  return [h("dt", {}, "interrupted runs"), h("dd", { id: "job-attempt-history" }, history.map(line))];
}

function reused(job, context) {
  if (!context.query.reused) return null;
  let saved = null;
  try {
    saved = JSON.parse(sessionStorage.getItem(REUSED_KEY) || "null");
  } catch {
    saved = null;
  }
  const body = saved && saved.id === job.id ? saved.body : { type: job.type, scenario_id: job.scenario_id, seed: job.seed, params: job.params };
  return reusedNotice(body, job);
}

export async function render(root, context) {
  const [id] = context.params;
  let job = await api.job(id);
  const scenario = await api.scenario(job.scenario_id).catch(() => null);
  const header = h("div", { class: "card", id: "job-header" });
  const body = h("div", { id: "job-body" });
  const heading = h("h1", {}, `${job.type[0].toUpperCase()}${job.type.slice(1)} job `, h("code", {}, job.id.slice(0, 8)));
  const named = () => {
    heading.replaceChildren(`${job.name ? `${job.name} · ` : ""}${job.type[0].toUpperCase()}${job.type.slice(1)} job `, h("code", {}, job.id.slice(0, 8)));
  };
  // Labels saved while a poll was answered outdate its answer: it held the old ones, and
  // drawn after the save it put them back in the header until the next poll.
  let saves = 0;
  const onLabels = (saved) => {
    saves += 1;
    job = saved;
    named();
    // Saved, the editor closes, and the polls draw the header again (an open one they leave).
    const editor = header.querySelector("#job-labels");
    if (editor) editor.open = false;
    redraw();
  };
  const drawHeader = jobHeader(header, scenario && scenario.name, onLabels, h("div", { id: "cancel-notice" }));
  const redraw = () => drawHeader(job);
  named();
  put(root, heading, reused(job, context), header, body);
  redraw();
  const views = { search: searchView, train: trainView, sweep: sweepView };
  const view = await views[job.type](body, job, context, scenario);
  let done = isTerminal(job.status);
  const tick = async () => {
    if (done) return;
    const before = saves;
    const fresh = await api.job(id);
    if (!context.alive() || saves !== before) return;
    job = fresh;
    done = isTerminal(job.status);
    // An open labels editor is left alone by the header itself: the status and run time
    // go on updating while the user types.
    redraw();
    await view.update(job);
  };
  context.every(POLL_MS, tick);
}

// Search: reward and F1 curves that gain points as PPO writes them, then the result.
// `scenario`: the search's (null when it could not be read), for its front's chart.
async function searchView(body, job, context, scenario) {
  const rewardPlot = plotDiv("reward-plot");
  const f1Plot = plotDiv("f1-plot");
  const pointCount = h("span", { id: "curve-points", class: "muted" }, "0 points");
  const separability = job.params.objective === "separability";
  // NSGA-II has no episode reward: its curve is the most accurate feasible sequence so
  // far (its predicted accuracy at the design noise, and its residual rate), and the
  // mean accuracy of each generation, then of each polish round's neighbours.
  const pareto = job.params.method === "nsga2";
  // The line holds the most accurate feasible sequence so far, and the most accurate of
  // all while none is feasible: a search that found none (it fails, "no sequence met the
  // constraints") drew "most accurate feasible so far" through sequences that break them.
  const noneFeasible = (current) => pareto && current.status === "failed" && /\bno sequence met the constraints\b/.test(current.error || "");
  const bestName = (current) => (!pareto ? "best so far" : noneFeasible(current) ? "most accurate so far (none feasible)" : "most accurate feasible so far");
  const rateTitle = (current) => title(noneFeasible(current) ? "Residual rate of the most accurate sequence so far (none feasible)" : "Residual rate of the most accurate feasible sequence so far", 13);
  const resultHolder = h("div", { id: "search-result" });
  // NSGA-II's curve runs through its generations, then its polish rounds: where the
  // one ends and the other begins, once the result says (and a line on both plots).
  const phases = h("p", { id: "curve-phases", class: "hint", hidden: true });
  // A constrained NSGA-II search stored before its curve held the best feasible so far:
  // what its line is instead (BestSoFar.predates).
  const predates = h("p", { id: "curve-predates", class: "hint", hidden: true });
  // A constrained search's best so far, while no sequence had met the constraints, is
  // the most accurate of all: those points are drawn apart (open markers), and said so.
  const constrained = Object.keys(job.params.constraints || {}).length > 0;
  const beforeFeasible = h("p", { id: "curve-infeasible", class: "hint", hidden: true });
  const infeasibleTrace = (name, color) => ({ x: [], y: [], mode: "lines+markers", name, line: { color, dash: "dash" }, marker: { symbol: "circle-open", size: 8 } });
  const infeasibleName = pareto ? "most accurate so far, none yet feasible" : "best so far, none yet feasible";
  body.append(
    h(
      "div",
      { class: "card" },
      h("div", { class: "toolbar" }, h("h2", { style: "margin: 0" }, "Learning curve"), pointCount, link(`#/compare?ids=${job.id}`, "compare with other searches")),
      h("div", { class: "grid2 curves" }, rewardPlot, f1Plot),
      phases,
      predates,
      beforeFeasible,
    ),
    resultHolder,
  );
  // The reward is built from what the search scored: the clustering F1 (the paper's
  // objective) or the separability score.
  const what = separability ? "separability score" : "clustering F1";
  const rewardText = separability ? "Reward per episode: −1 + 3·separability per step, −|ω| (rad/s) at the last" : "Reward per episode: −1 + 3·F1 per step, −|ω| (rad/s) at the last";
  const steps = pareto ? "sequences evaluated × steps" : "environment steps";
  // NSGA-II's residual rate in rad/s, and in deg/s on the right.
  const rateTwins = [{ of: "yaxis", twin: "yaxis2", factor: DEG_PER_RAD, title: "residual rate (deg/s)" }];
  await Plotly.newPlot(
    rewardPlot,
    pareto
      ? [{ x: [], y: [], mode: "lines+markers", name: "residual rate", line: { color: "#1f77b4" } }, ...twinTraces(rateTwins), ...(constrained ? [infeasibleTrace("residual rate, none yet feasible", "#1f77b4")] : [])]
      : [{ x: [], y: [], mode: "lines+markers", name: "mean episode reward", line: { color: "#1f77b4" } }],
    pareto
      ? layout(steps, "residual rate (rad/s)", { title: rateTitle(job), showlegend: false, ...twinAxes(rateTwins) })
      : layout(steps, "mean episode reward", { title: title(rewardText, 13), showlegend: false }),
    PLOT_CONFIG,
  );
  if (pareto) keepTwins(rewardPlot, rateTwins);
  const accuracyText = "predicted accuracy at the design noise";
  Plotly.newPlot(
    f1Plot,
    [
      { x: [], y: [], mode: "lines+markers", name: bestName(job), line: { color: "#2ca02c" } },
      { x: [], y: [], mode: "lines+markers", name: pareto ? "mean of the generation (polish round)" : "mean since last point", line: { color: "#ff7f0e", dash: "dot" } },
      ...(constrained ? [infeasibleTrace(noneFeasible(job) ? bestName(job) : infeasibleName, "#2ca02c")] : []),
    ],
    layout(steps, pareto ? accuracyText : what, {
      // NSGA-II's title short enough for half a 1024 px page: the longer one was cut at the
      // figure's edge up to 1440 px (the legend and the phases line name the polish rounds),
      // and this one at 14 px still by 15 px at 1024; at 13 px, as the residual rate's
      // title beside it, it fits (the two plots side by side only where each is 560 px wide:
      // .grid2.curves in style.css).
      title: pareto
        ? title("Predicted accuracy: best so far, and each generation's mean", 13)
        : title(`${separability ? "Separability score" : "Clustering F1"} of the episodes' sequences`),
      yaxis: { title: { text: pareto ? accuracyText : what }, range: [0, 1.05] },
    }),
    PLOT_CONFIG,
  );
  const follower = new MetricFollower(job.id);
  // NSGA-II's best line as the best so far, for searches stored before it was.
  const bestSoFar = new BestSoFar(job);
  let points = 0;
  let resultShown = false;
  let infeasibleShown = noneFeasible(job);
  const update = async (current) => {
    const fresh = bestSoFar.apply(await follower.poll());
    if (!context.alive()) return;
    if (!infeasibleShown && noneFeasible(current)) {
      // Failed while the page followed it: the line renamed for what it held.
      infeasibleShown = true;
      await Promise.all([Plotly.restyle(f1Plot, { name: bestName(current) }, constrained ? [0, 2] : [0]), Plotly.relayout(rewardPlot, { title: rateTitle(current) })]);
    }
    // Metrics stored before the rate was named for what it is were renamed by the
    // database migration 0005 (NSGA-II's to best_residual_rate_rad_s).
    const shown = splitInfeasible(fresh, ["best_f1", "best_residual_rate_rad_s"]);
    if (extendWith(rewardPlot, shown, pareto ? ["best_residual_rate_rad_s", null, constrained && "best_residual_rate_rad_s_infeasible"] : ["mean_episode_reward"])) fitFlatSeries(rewardPlot);
    extendWith(f1Plot, shown, ["best_f1", "mean_f1", constrained && "best_f1_infeasible"]);
    if (beforeFeasible.hidden && shown.best_f1_infeasible) {
      beforeFeasible.textContent =
        `Open markers, dashed: no sequence had met the constraints yet. Each such point is the most accurate sequence of all so far, which breaks them${pareto ? "; the residual rate beside it is that sequence's" : ""}. The solid line takes over once a sequence meets them.`;
      beforeFeasible.hidden = false;
      if (pareto && !noneFeasible(current)) await Plotly.relayout(rewardPlot, { title: title("Residual rate of the most accurate feasible sequence so far (open markers: before any was)", 13) });
    }
    if (bestSoFar.predates && predates.hidden) {
      // Its line named for what it holds, not "so far" (which cannot fall), and why.
      await Plotly.restyle(f1Plot, { name: "most accurate feasible of the generation (polish round)" }, [0]);
      predates.textContent =
        "This search was stored before its curve held the most accurate feasible sequence so far: each " +
        "point, on both plots, is the most accurate feasible sequence of its generation, then of its polish " +
        "round (of all where none was feasible), so the lines fall where one was less accurate than an " +
        "earlier one. They are drawn as stored: which earlier sequences were feasible was not stored, so the " +
        "best so far cannot be drawn from them.";
      predates.hidden = false;
    }
    if (fresh.best_f1) points += fresh.best_f1.steps.length;
    pointCount.textContent = `${points} point${points === 1 ? "" : "s"}${isTerminal(current.status) ? "" : " · updating live"}`;
    pointCount.dataset.points = String(points);
    if (!resultShown && isTerminal(current.status) && current.result) {
      resultShown = true;
      if (pareto) {
        const start = polishStart(current);
        curvePhases(phases, current, start);
        if (start && start.rounds) {
          const marks = polishMarks([{ x: start.timesteps, label: "polish starts" }]);
          await Promise.all([Plotly.relayout(rewardPlot, marks), Plotly.relayout(f1Plot, marks)]);
        }
      }
      await searchResult(resultHolder, current, context, scenario);
    }
  };
  await update(job);
  return { update };
}

// "736 environment steps on the curve: 192 in 3 generations, 544 in 34 polish rounds":
// the generations are the curve's first points (fewer when the search stopped in them).
function curvePhases(node, job, start) {
  const result = job.result;
  const curve = result.curve || [];
  if (!start) return;
  const { generations, rounds, timesteps: inGenerations } = start;
  const last = curve[curve.length - 1].timesteps;
  const plural = (n, word) => `${fmt(n)} ${word}${n === 1 ? "" : "s"}`;
  let text = `${fmt(last)} environment steps on the curve: ${fmt(inGenerations)} in ${plural(generations, "generation")}`;
  if (rounds) text += `, then ${fmt(last - inGenerations)} in ${plural(rounds, "polish round")} (the points after step ${fmt(inGenerations)}, at the dashed line: each a round's neighbours of the sequences climbed)`;
  if (last !== result.timesteps) text += `; ${fmt(result.timesteps - last)} more scored after the last point`;
  node.textContent = text + ".";
  node.hidden = false;
}

// A search other than NSGA-II keeps its best when nothing it tried met the constraints
// (the least violating): the card said nothing of it, while the front, judged on fresh
// draws, could call the same sequence within them.
function constraintsMet(result, best) {
  const constraints = (result.settings || {}).constraints || {};
  if (!Object.keys(constraints).length || typeof best.constraint_violation !== "number") return [];
  const met = best.constraint_violation <= 0;
  return [
    h("dt", {}, "constraints, on the search's draw"),
    h(
      "dd",
      { id: "best-constraints" },
      met ? "met" : `broken (summed relative violation ${quantity(best.constraint_violation)}): no sequence the search tried met them; this one breaks them least`,
    ),
  ];
}

// The best sequence as found, beside the one shown: the same torque at every step.
function firingsTakenOff(taken) {
  if (!taken) return [];
  const steps = taken.steps || [];
  return [
    h("dt", {}, "firings that cancelled, taken off"),
    h(
      "dd",
      { id: "best-firings-taken-off" },
      `step${steps.length === 1 ? "" : "s"} ${steps.join(", ")}: the same torque, ${quantity(taken.impulse_saved_nms)} N m s and ${quantity(taken.on_time_saved_s)} s of on-time less than the sequence found, `,
      h("span", { class: "mono" }, sequenceText(taken.sequence_found)),
      ` (${quantity(taken.impulse_found_nms)} N m s, score ${score(taken.score_found)} on the search's draw)`,
    ),
  ];
}

async function searchResult(holder, job, context, scenario) {
  const result = job.result;
  const best = result.best;
  const freshF1 = result.fresh.f1;
  const mean = meanOf(freshF1);
  // A re-score cut by the time limit's grace kept the draws it completed.
  const asked = result.fresh.draws_asked;
  const drawsText = typeof asked === "number" && asked > freshF1.length ? `${freshF1.length} of ${asked} fresh draws asked (the re-score stopped)` : `${freshF1.length} fresh draws`;
  const seqPlot = plotDiv("sequence-plot", "short");
  const responseHolder = h("div", { id: "response-holder" });
  // The response's warning (a sequence whose rates stay far below the gyro noise), as a
  // front member's plan and a training say it: above the charts drawn from it.
  const responseWarnings = h("div", { id: "best-response-warnings-holder" });
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
        // CEM, random, exhaustive and PPO sample each thruster apart: firings of the best
        // found whose torques cancelled were taken off after the search (the result says).
        ...firingsTakenOff(result.firings_taken_off),
        // NSGA-II ranks by the noise model's predicted accuracy, which no draw produced.
        h("dt", {}, job.params.method === "nsga2" ? "predicted accuracy at the design noise" : job.params.objective === "separability" ? "separability score on the search's draw" : "F1 on the search's noise draw"),
        h("dd", {}, score(best.f1)),
        h("dt", {}, `clustering F1 on ${drawsText}`),
        h("dd", { id: "best-fresh-f1" }, freshF1.length ? `${score(mean)} mean (min ${score(Math.min(...freshF1))})` : "–"),
        // On the search's own draw, as the score above: the front's table gives the rate
        // re-scored on fresh draws, a little off it (0.141 against 0.152 deg/s in a review).
        h("dt", {}, job.params.method === "nsga2" ? "residual rate on the search's draw (once the lag is empty)" : "rate at the last step's end, on the search's draw"),
        h("dd", { id: "best-final-rate" }, `${rateDeg(best.final_rate_rad_s * RAD_TO_DEG)} deg/s (${rateRad(best.final_rate_rad_s)} rad/s)`),
        h("dt", {}, "fuel (commanded impulse)"),
        h("dd", {}, `${quantity(best.fuel_nms)} N m s`),
        ...constraintsMet(result, best),
        h("dt", {}, "environment steps, episodes"),
        h("dd", {}, `${fmt(result.timesteps)}, ${fmt(result.episodes)}`),
        h("dt", {}, "wall time, stopped by"),
        h("dd", {}, `${quantity(result.wall_time_s)} s, ${result.stopped}`),
      ),
      bestVersusCurve(result, best),
      baselineTable(result, best, freshF1),
      h("div", { class: "toolbar" }, link(trainHref, "Train a classifier on this sequence", { class: "button", id: "train-best" })),
      responseWarnings,
      h("h3", {}, "Thruster duty over time"),
      h("p", { class: "hint" }, "Thrusters numbered from 1, as in the report."),
      seqPlot,
      h("h3", {}, `Each candidate's response (mean and ${BAND.label} band over 20 noisy realisations)`),
      responseHolder,
    ),
  );
  const front = frontPanel(job, context, scenario);
  if (front) {
    holder.append(front.node);
    await front.draw();
  }
  // Both drawn from the simulated response, which needs the key: hidden until it comes.
  seqPlot.hidden = true;
  const drawResponse = async () => {
    try {
      const response = await api.response(job.scenario_id, best.sequence, { n_realisations: 20, seed: job.seed });
      if (!context.alive()) return;
      clear(responseHolder);
      put(responseWarnings, warningsBox(response.warnings, "best-response-warnings"));
      seqPlot.hidden = false;
      sequencePlot(seqPlot, response);
      const view = responseView(response, { id: "response-plot", titleText: "ω response to the best sequence" });
      responseHolder.append(view.node);
      view.draw();
    } catch (exc) {
      if (!responseHolder.isConnected) return;
      // In the holder, not in its place: a saved key refused is drawn again once the
      // current one is saved, as a member's plan is (it stayed on the refusal until a reload).
      responseHolder.replaceChildren(messageBox("error", exc.message));
      redrawWhenRekeyed(responseHolder, exc, drawResponse);
    }
  };
  await whenKeyed(responseHolder, "The thruster duty and each candidate's simulated response", drawResponse);
}

// Why NSGA-II's best is not the curve's highest point (null where no front was built: a
// cancelled search's best is the curve's). The curve is the search's prediction on its own
// draw; the best is the front's member 0, the most accurate of the front when every member
// was measured on fresh test series (pareto.py build_front), so a sequence the search
// predicted higher can measure lower and sit behind it. Four decimals: a measurement on
// 2,000 series moves in steps of 0.0005, which three decimals can write alike.
function bestVersusCurve(result, best) {
  const front = result.front;
  if (result.method !== "nsga2" || !front || !(front.members || []).length) return null;
  const curve = (result.curve || []).map((p) => p.best_f1).filter((v) => typeof v === "number" && Number.isFinite(v));
  if (!curve.length) return null;
  const top = Math.max(...curve);
  const four = (v) => (typeof v === "number" && Number.isFinite(v) ? v.toFixed(4) : "–");
  const [first] = front.members;
  const measured = front.accuracy_source === "measured";
  const how = measured ? `measured on ${front.fresh_test_series} fresh test series per candidate at each condition` : "predicted again on a fresh draw";
  const confirmed = front.confirmation ? `; ${four(front.confirmation.accuracy)} on the confirmation's other series, the figure to quote` : "";
  let text;
  if (top === best.f1) {
    text = `The curve's highest point, ${four(top)}, is this sequence's accuracy as the search predicted it on its own draw (the figure above); ${how} it scored ${four(first.scores.accuracy)}${confirmed}.`;
  } else {
    const curveMember = front.members.find((m) => m.search_scores && m.search_scores.accuracy === top);
    const where = curveMember ? `front member ${curveMember.index}, ${four(curveMember.scores.accuracy)} there` : "not kept on the front once re-scored on fresh draws";
    text =
      `The curve's highest point, ${four(top)}, is the search's prediction, on its own draw, for the most accurate feasible sequence up to its last point. ` +
      `The best sequence is the front's member 0 instead: the most accurate when the front was ${how} (${four(first.scores.accuracy)}${confirmed}; the curve's sequence is ${where}), though the search predicted it ${four(best.f1)}.`;
  }
  return h("p", { class: "hint", id: "best-vs-curve", "data-curve": String(top), "data-best": String(best.f1), "data-member-0": String(first.scores.accuracy) }, text);
}

// NaN (shown "–") without values: a re-score the time limit's grace cut may hold none.
function meanOf(values) {
  return values.length ? values.reduce((a, b) => a + b, 0) / values.length : NaN;
}

// The best sequence beside the hand-designed baselines, on the same fresh draws.
function baselineTable(result, best, freshF1) {
  if (!result.baselines) return null;
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
      ["sequence", "F1 mean", "F1 min", "rate at the last step's end (deg/s)", "(rad/s)", "fuel (N m s)", "levels"],
      rows.map(([name, f1, rate, fuel, levels]) => [name, score(meanOf(f1)), score(Math.min(...f1)), rateDeg(meanOf(rate) * RAD_TO_DEG), rateRad(meanOf(rate)), quantity(fuel), h("span", { class: "mono" }, sequenceText(levels))]),
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
      // What the training found doubtful (a sequence whose responses are noise to the
      // gyro): said above the classifier it trained.
      const warned = warningsBox(current.result.warnings, "train-warnings");
      put(holder, warned);
      const classifier = await api.classifier(current.result.classifier_id);
      // The classifier's response says the same warning: once is enough (a training
      // stored before its result had warnings leaves it to the response).
      if (context.alive()) await renderClassifier(holder, classifier, context, null, { responseWarnings: !warned });
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
