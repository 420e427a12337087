// One classifier: its summary, training confusion, its posterior's calibration (ECE and
// reliability diagram), downloads, its sweeps (accuracy
// against noise) and its sequence with every candidate's response. Used by the
// classifier page and by the job page of a training.

import { api, getApiKey } from "../api.js";
import { BAND, PLOT_CONFIG, confusionPlot, layout, plotDiv, responseView, sequencePlot, title } from "../components/plots.js";
import { downloads, jobDownloads } from "../components/downloads.js";
import { redrawWhenRekeyed, whenKeyed } from "../components/keyed.js";
import { isTerminal } from "../vocabulary.js";
import { clear, fmt, h, link, messageBox, put, quantity, rateDeg, rateRad, score, sequenceText, tagChips, utcText, warningsBox, when } from "../ui.js";
import { sweepPanel } from "./sweep.js";

const RAD_TO_DEG = 180 / Math.PI;

// `responseWarnings`: whether the sequence's response states its warnings (a sequence
// whose rates stay far below the gyro noise) above the classifier; the job page of a
// training that said them already passes false.
export async function renderClassifier(container, classifier, context, sweepId = null, { responseWarnings = true } = {}) {
  const scenario = await api.scenario(classifier.scenario_id).catch(() => null);
  const summary = h("dl", { class: "kv", id: "classifier-summary" });
  const confusion = plotDiv("training-confusion");
  const seqPlot = plotDiv("classifier-sequence", "short");
  const responseHolder = h("div", { id: "classifier-response-holder" });
  const sweepCard = h("div", { class: "card", id: "sweep-card" });
  const warningsHolder = h("div", { id: "classifier-response-warnings-holder" });
  const calibrationCard = h("div", { class: "card", id: "calibration-card" }, h("h2", {}, "Calibration of the posterior"));
  container.append(
    warningsHolder,
    h(
      "div",
      { class: "toolbar" },
      link(`#/jobs?type=sweep&classifier=${classifier.id}`, "Run a noise sweep", { class: "button", id: "run-sweep" }),
      link(`#/identify?classifier=${classifier.id}`, "Identify telemetry", { class: "button secondary" }),
    ),
    downloads("classifier-downloads", [
      { label: "classifier document (JSON)", href: `/classifiers/${classifier.id}/download` },
      ...(classifier.job_id ? jobDownloads({ id: classifier.job_id, type: "train" }) : []),
    ]),
    h("div", { class: "row" }, h("div", { class: "card grow" }, h("h2", {}, "Classifier"), summary), h("div", { class: "card grow" }, h("h2", {}, "Training confusion"), confusion)),
    calibrationCard,
    sweepCard,
    h("div", { class: "card" }, h("h2", {}, "The sequence"), h("p", { class: "hint" }, "Thrusters numbered from 1."), seqPlot, h("h3", {}, `Each candidate's response (mean and ${BAND.label} band over 20 realisations)`), responseHolder),
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
    ["training job's name, tags", [classifier.job_name || "–", " ", tagChips(classifier.tags)]],
    ["trained by job", classifier.job_id ? link(`#/jobs/${classifier.job_id}`, classifier.job_id.slice(0, 8)) : "–"],
  ];
  const fuel = h("span", { id: "classifier-fuel" }, "…");
  const finalRate = h("span", { id: "classifier-final-rate" }, "…");
  // The response's final_rate_rad_s: the true |ω| at the last sample, when the last
  // command ends, before the torque still in the actuation lag is delivered (the
  // simulation's final_rate_rad_s), not the residual once the lag is empty that a
  // front's "residual rate" gives; its mean over each candidate's 20 realisations, then
  // over the candidates. It read "mean final rate", which said neither.
  const rateNote = h("span", { class: "hint", id: "classifier-final-rate-note" }, " true rate, mean over the candidates' 20 realisations each, before the actuation lag empties (not the settled residual)");
  rows.push(["fuel (commanded impulse)", fuel], ["mean |ω| at the last command's end", [finalRate, rateNote]]);
  for (const [name, value] of rows) summary.append(h("dt", {}, name), h("dd", {}, value));
  confusionPlot(confusion, classifier.confusion, classifier.candidate_names, "training series");
  if (context.alive && !context.alive()) return;

  await calibrationOf(calibrationCard, classifier, context);
  await sweepsOf(sweepCard, classifier, context, sweepId);

  // The fuel, the rate at the last command's end and both plots come from the simulated response, which
  // needs the key: without one they wait for it.
  seqPlot.hidden = true;
  if (!getApiKey()) fuel.textContent = finalRate.textContent = "– (needs the API key: see below)";
  const drawResponse = async () => {
    try {
      const response = await api.response(classifier.scenario_id, classifier.sequence, { n_realisations: 20 });
      if (!context.alive()) return;
      // A classifier of a sequence whose responses are noise to the gyro reads noise:
      // said above it, as at its training.
      if (responseWarnings) put(warningsHolder, warningsBox(response.warnings, "classifier-response-warnings"));
      fuel.textContent = `${quantity(response.impulse_nms)} N m s`;
      const rates = response.candidates.map((c) => c.final_rate_rad_s);
      const mean = rates.reduce((a, b) => a + b, 0) / rates.length;
      // In deg/s with rad/s beside it, as every rate on the dashboard.
      finalRate.textContent = `${rateDeg(mean * RAD_TO_DEG)} deg/s (${rateRad(mean)} rad/s)`;
      seqPlot.hidden = false;
      sequencePlot(seqPlot, response);
      const view = responseView(response, { id: "classifier-response", titleText: "ω response to the classifier's sequence" });
      responseHolder.append(view.node);
      view.draw();
    } catch (exc) {
      fuel.textContent = exc.message;
      finalRate.textContent = "–";
      // A saved key refused: drawn once the current one is saved at the top right (it
      // stayed on the refusal until a reload).
      redrawWhenRekeyed(responseHolder, exc, drawResponse);
    }
  };
  await whenKeyed(responseHolder, "The sequence's simulated response (its fuel, rate at the last command's end and plots)", drawResponse);
}

// The calibration report measured on fresh draws at training: the ECE and a reliability
// diagram (mean confidence against accuracy per bin; on the diagonal it is calibrated).
async function calibrationOf(card, classifier, context) {
  let report;
  try {
    report = await api.calibration(classifier.id);
  } catch (exc) {
    card.append(h("p", { class: "note", id: "calibration-note" }, exc.status === 404 ? "This classifier stores no calibration report (trained before calibration existed)." : exc.message));
    return;
  }
  if (context.alive && !context.alive()) return;
  const summary = h(
    "dl",
    { class: "kv", id: "calibration-summary" },
    h("dt", {}, "expected calibration error (ECE)"),
    h("dd", { id: "calibration-ece" }, report.ece.toFixed(4)),
    h("dt", {}, "held-out accuracy"),
    h("dd", {}, `${score(report.accuracy)} on ${report.n_held_out} fresh series`),
    h("dt", {}, "softmax temperature"),
    h("dd", {}, fmt(report.temperature)),
    h("dt", {}, "mean P(none of these) on genuine series"),
    h("dd", {}, fmt(report.mean_p_none)),
  );
  const plot = plotDiv("reliability-plot");
  card.append(h("div", { class: "grid2" }, h("div", {}, summary, h("p", { class: "hint" }, "Bins of the top posterior over fresh draws: a calibrated posterior's accuracy equals its confidence (the diagonal).")), plot));
  const bins = (report.bins || []).filter((b) => b.count > 0);
  Plotly.newPlot(
    plot,
    [
      { x: [0, 1], y: [0, 1], mode: "lines", line: { color: "#9aa5b1", dash: "dash", width: 1 }, name: "calibrated", hoverinfo: "skip" },
      {
        x: bins.map((b) => b.mean_confidence),
        y: bins.map((b) => b.accuracy),
        customdata: bins.map((b) => [b.count, b.low, b.high]),
        mode: "lines+markers",
        marker: { size: bins.map((b) => 6 + 10 * Math.sqrt(b.count / Math.max(...bins.map((c) => c.count)))), color: "#1f5fae" },
        line: { color: "#1f5fae" },
        name: "classifier",
        hovertemplate: "confidence %{customdata[1]:.2f}–%{customdata[2]:.2f}: mean %{x:.3f}, accuracy %{y:.3f}, %{customdata[0]} series<extra></extra>",
      },
    ],
    layout("mean confidence (top posterior)", "accuracy", {
      height: 360,
      title: title(`reliability diagram, ECE ${report.ece.toFixed(4)}`, 13),
      xaxis: { title: { text: "mean confidence (top posterior)" }, range: [0, 1.05] },
      yaxis: { title: { text: "accuracy" }, range: [0, 1.05] },
    }),
    PLOT_CONFIG,
  );
}

// A failed read (the list, the chosen sweep, a poll of a running one) is said in the card,
// as the calibration's is; it rejected before, unhandled where the menu's change called it,
// and the card stayed as it was.
async function sweepsOf(card, classifier, context, sweepId) {
  card.append(h("h2", {}, "Accuracy against noise"));
  let page;
  try {
    page = await api.jobs({ type: "sweep", classifier_id: classifier.id, limit: 200 });
  } catch (exc) {
    if (context.alive()) card.append(messageBox("error", `This classifier's sweeps could not be read: ${exc.message}. Reload the page to try again.`));
    return;
  }
  const sweeps = page.items;
  if (!sweeps.length) {
    card.append(messageBox("notice", "No sweep of this classifier yet: run one to see its accuracy as noise grows."));
    return;
  }
  const chosen = sweeps.find((j) => j.id === sweepId) || sweeps.find((j) => j.status === "succeeded") || sweeps[0];
  const select = h(
    "select",
    { id: "sweep-select", "aria-label": "sweep" },
    sweeps.map((j) => h("option", { value: j.id, selected: j.id === chosen.id }, `${j.name || j.id.slice(0, 8)} · ${j.status} · ${utcText(j.created_at)}`)),
  );
  // A running sweep's failed poll, until one is answered again.
  const pollNote = h("div", { id: "sweep-poll-state", role: "status" });
  const holder = h("div");
  const compareLink = link(`#/compare?type=classifier&ids=${classifier.id}`, "compare with other classifiers");
  const jobLink = link(`#/jobs/${chosen.id}`, "job page", { id: "sweep-job-link" });
  card.append(h("div", { class: "toolbar" }, h("label", { for: "sweep-select" }, "sweep"), select, jobLink, compareLink), pollNote, holder);
  // Only the sweep chosen last is drawn, and only its poll runs: a slow answer for one
  // chosen before it was drawn over it (the menu named one sweep, the panel showed
  // another), and the poll of every sweep once shown went on.
  let asked = 0;
  let timer = null;
  // Its own button tries again: choosing the sweep the menu shows already fires no
  // change (the message said "choose it again", which did nothing, and a classifier with
  // one sweep had only a reload of the page left).
  const failed = (id, exc) => {
    clear(holder);
    const retry = h("button", { type: "button", class: "secondary small", id: "sweep-retry", onclick: () => show(id) }, "Try again");
    holder.append(h("div", { class: "message error", role: "alert" }, `Sweep ${id.slice(0, 8)} could not be read: ${exc.message}. `, retry));
  };
  const show = async (id) => {
    const mine = ++asked;
    clearInterval(timer);
    pollNote.replaceChildren();
    // The list sends no results: the chosen sweep's comes with the job itself.
    let job;
    let panel;
    try {
      job = await api.job(id);
      if (mine !== asked || !context.alive()) return;
      clear(holder);
      jobLink.setAttribute("href", `#/jobs/${job.id}`);
      panel = await sweepPanel(holder, job, classifier, context);
    } catch (exc) {
      if (mine !== asked || !context.alive()) return;
      jobLink.setAttribute("href", `#/jobs/${id}`);
      failed(id, exc);
      return;
    }
    if (mine !== asked || isTerminal(job.status)) return;
    let answered = new Date();
    const polling = setInterval(async () => {
      if (!context.alive() || mine !== asked) return clearInterval(polling);
      try {
        const fresh = await api.job(job.id);
        if (mine !== asked || !context.alive()) return;
        await panel.update(fresh);
        answered = new Date();
        if (mine === asked) pollNote.replaceChildren();
        if (isTerminal(fresh.status)) clearInterval(polling);
      } catch (exc) {
        if (mine !== asked || !context.alive()) return;
        const since = answered.toISOString().slice(11, 19);
        pollNote.replaceChildren(messageBox("error", `Sweep not updated since ${since} UTC: ${exc.message}. The page tries again every 2 s.`));
      }
    }, 2000);
    timer = polling;
  };
  select.addEventListener("change", () => show(select.value));
  await show(chosen.id);
}
