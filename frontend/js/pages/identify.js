// Identify: paste or upload telemetry, pick a classifier, and see the verdict, the
// distance to every candidate, and the telemetry over the matched candidate's response.

import { api } from "../api.js";
import { downloads } from "../components/downloads.js";
import { BAND, COLORS, PLOT_CONFIG, layout, plotDiv, responseLayout, title, withAlpha } from "../components/plots.js";
import { clear, fmt, h, jsonBlob, link, messageBox, sequenceText, showFieldErrors } from "../ui.js";

const EXAMPLE = "time_s,wx_rad_s,wy_rad_s,wz_rad_s\n0.05,0.0001,0.0009,-0.0004\n0.10,0.0012,0.0031,0.0015\n...";

// For drawing only: the service parses the same text authoritatively.
export function parseTelemetry(text) {
  const trimmed = text.trim();
  if (trimmed.startsWith("{")) {
    const data = JSON.parse(trimmed);
    return { time: data.time_s, omega: data.omega_rad_s };
  }
  const time = [];
  const omega = [];
  for (const line of trimmed.split(/\r?\n/)) {
    const cells = line.split(",").map((c) => Number(c.trim()));
    if (cells.length !== 4 || cells.some((v) => !Number.isFinite(v))) continue;
    time.push(cells[0]);
    omega.push(cells.slice(1));
  }
  return { time, omega };
}

export async function render(root, context) {
  const page = await api.classifiers();
  root.append(h("h1", {}, "Identify telemetry"));
  if (!page.items.length) {
    root.append(messageBox("notice", "No classifier yet: train one on the Jobs page first."));
    return;
  }
  const select = h(
    "select",
    { id: "identify-classifier" },
    page.items.map((c) =>
      h("option", { value: c.id, selected: c.id === context.query.classifier }, `${c.job_name || c.id.slice(0, 8)} · ${c.kind} ${c.metric} · F1 ${c.f1.toFixed(3)} · ${sequenceText(c.sequence)}`),
    ),
  );
  const text = h("textarea", { id: "telemetry-text", rows: 8, placeholder: `CSV (time_s, wx_rad_s, wy_rad_s, wz_rad_s) or JSON {"time_s": [...], "omega_rad_s": [[...], ...]}\n${EXAMPLE}` });
  const file = h("input", { type: "file", id: "telemetry-file", accept: ".csv,.json,text/csv,application/json" });
  file.addEventListener("change", async () => {
    if (file.files.length) text.value = await file.files[0].text();
  });
  const general = h("div", { id: "identify-errors" });
  const submit = h("button", { type: "submit", id: "identify-submit" }, "Identify");
  const result = h("div", { id: "identify-result" });
  const form = h(
    "form",
    {
      id: "identify-form",
      onsubmit: async (event) => {
        event.preventDefault();
        clear(result);
        clear(general);
        const content = text.value;
        if (!content.trim()) {
          general.append(messageBox("error", "paste telemetry or choose a file first"));
          return;
        }
        const name = content.trim().startsWith("{") ? "telemetry.json" : "telemetry.csv";
        submit.disabled = true;
        try {
          const file = new File([content], name, { type: "text/plain" });
          const verdict = await api.identify(select.value, file);
          const classifier = page.items.find((c) => c.id === select.value);
          await showVerdict(result, verdict, classifier, content, context, file);
        } catch (exc) {
          showFieldErrors(exc, { file: text, classifier_id: select }, general);
        } finally {
          submit.disabled = false;
        }
      },
    },
    h(
      "div",
      { class: "stack" },
      h("label", { for: "identify-classifier" }, "classifier"),
      select,
      h("label", { for: "telemetry-file" }, "upload a file"),
      h("div", {}, file, h("span", { class: "hint" }, " .csv or .json; time in s from the sequence start, ω in rad/s")),
      h("label", { for: "telemetry-text", class: "full" }, "or paste telemetry"),
      h("div", { class: "full" }, text),
    ),
    general,
    h("div", { class: "toolbar" }, submit),
  );
  root.append(h("div", { class: "card" }, form), result);
}

async function showVerdict(holder, verdict, classifier, content, context, file) {
  const names = Object.keys(verdict.distances);
  const box = verdict.matches_none
    ? h(
        "div",
        { class: "verdict none", id: "verdict", role: "status" },
        "Matches none of the candidates",
      )
    : h("div", { class: "verdict match", id: "verdict", role: "status" }, `Candidate: ${verdict.candidate}`);
  const distancePlot = plotDiv("distance-plot", "short");
  const overlayPlot = plotDiv("overlay-plot");
  holder.append(
    h(
      "div",
      { class: "card" },
      box,
      verdict.verdict !== verdict.candidate ? h("p", {}, verdict.verdict) : null,
      downloads("identify-downloads", [
        { label: "verdict (JSON)", filename: `identify-${verdict.classifier_id.slice(0, 8)}.json`, make: async () => jsonBlob(verdict) },
        { label: "verdict (CSV)", filename: `identify-${verdict.classifier_id.slice(0, 8)}.csv`, make: () => api.identify(verdict.classifier_id, file, "csv") },
      ]),
      h(
        "dl",
        { class: "kv" },
        h("dt", {}, "margin to the runner-up"),
        h("dd", {}, `${fmt(verdict.margin)} (relative ${fmt(verdict.relative_margin)})`),
        h("dt", {}, "inertia of the nearest candidate (kg m²)"),
        h("dd", { class: "mono" }, verdict.inertia_kg_m2 ? verdict.inertia_kg_m2.map((r) => `[${r.map((v) => fmt(v, 4)).join(", ")}]`).join(" ") : "–"),
        h("dt", {}, "classifier"),
        h("dd", {}, link(`#/classifiers/${verdict.classifier_id}`, verdict.classifier_id)),
        h("dt", {}, "least-squares estimate from this telemetry (kg m²)"),
        h(
          "dd",
          { id: "ls-estimate" },
          verdict.estimated_inertia_kg_m2
            ? [
                h("span", { class: "mono" }, verdict.estimated_inertia_kg_m2.map((r) => `[${r.map((v) => v.toFixed(2)).join(", ")}]`).join(" ")),
                h("br"),
                `principal moments ${verdict.estimated_principal_moments_kg_m2.map((v) => v.toFixed(2)).join(", ")}; condition number ${fmt(verdict.estimate_condition_number, 3)}`,
                verdict.poorly_excited.length
                  ? h("div", { class: "field-error" }, `the sequence hardly excites ${verdict.poorly_excited.join(", ")}: those components are unreliable`)
                  : null,
              ]
            : "–",
        ),
      ),
    ),
    h("div", { class: "grid2" }, h("div", { class: "card" }, h("h2", {}, "Distance to each candidate"), distancePlot), h("div", { class: "card" }, h("h2", {}, `Telemetry over ${verdict.candidate}'s response`), overlayPlot)),
  );
  const values = names.map((n) => verdict.distances[n]);
  Plotly.newPlot(
    distancePlot,
    [
      {
        type: "bar",
        x: names,
        y: values,
        marker: { color: names.map((n) => (n === verdict.candidate ? (verdict.matches_none ? "#b3261e" : "#1e7b34") : "#8da9c4")) },
        hovertemplate: "%{x}: %{y:.4g}<extra></extra>",
        name: "distance",
      },
      ...(verdict.threshold !== null
        ? [{ x: names, y: names.map(() => verdict.threshold), mode: "lines", line: { color: "#b3261e", dash: "dash" }, name: `"matches none"<br>threshold` }]
        : []),
    ],
    layout("candidate", "distance (training-RMS units)", {
      height: 420,
      title: title(`${classifier ? classifier.metric : ""} distance to each candidate's centroid`, 13),
      showlegend: verdict.threshold !== null,
    }),
    PLOT_CONFIG,
  );

  if (!classifier) return;
  const response = await api.response(classifier.scenario_id, classifier.sequence, { n_realisations: 20 });
  if (!context.alive()) return;
  const k = response.candidates.findIndex((c) => c.name === verdict.candidate);
  const candidate = response.candidates[k];
  const telemetry = parseTelemetry(content);
  const color = COLORS[k % COLORS.length];
  const traces = [];
  ["x", "y", "z"].forEach((axis, a) => {
    const yaxis = a === 0 ? "y" : `y${a + 1}`;
    traces.push(
      { x: response.time_s, y: candidate.low_rad_s.map((r) => r[a]), yaxis, mode: "lines", line: { width: 0 }, showlegend: false, hoverinfo: "skip" },
      { x: response.time_s, y: candidate.high_rad_s.map((r) => r[a]), yaxis, mode: "lines", line: { width: 0 }, fill: "tonexty", fillcolor: withAlpha(color, 0.2), showlegend: false, hoverinfo: "skip" },
      { x: response.time_s, y: candidate.mean_rad_s.map((r) => r[a]), yaxis, mode: "lines", line: { color, width: 2 }, name: "mean response", showlegend: a === 0 },
      { x: telemetry.time, y: telemetry.omega.map((r) => r[a]), yaxis, mode: "markers", marker: { color: "#222", size: 4 }, name: "telemetry", showlegend: a === 0 },
    );
  });
  Plotly.newPlot(overlayPlot, traces, responseLayout(`telemetry (dots) over ${candidate.name}'s mean and ${BAND.label} band`), PLOT_CONFIG);
}
