// Identify: paste or upload telemetry (with the sequence start when its clock is not from
// the start), pick a classifier and the confidence naming one takes, and see the verdict
// coloured by its status (green only when identified), the posterior of every candidate
// and of "none of these", the estimate when it is valid, the posterior over time, and
// the telemetry over the most probable candidate's response.

import { api } from "../api.js";
import { downloads } from "../components/downloads.js";
import { withoutKey } from "../components/keyed.js";
import { BAND, COLORS, PLOT_CONFIG, keepTwins, layout, plotDiv, plotText, responseLayout, responseTwins, title, twinTraces, withAlpha } from "../components/plots.js";
import { kindInfo } from "../vocabulary.js";
import { clear, clearFieldErrors, decimalsFor, h, jsonBlob, link, measured, messageBox, plain, probability, put, quantity, sequenceText, showFieldErrors, warningsBox } from "../ui.js";

const DEFAULT_CONFIDENCE = 0.99;

// The estimate's standard errors are per parameter; the tensor entry each belongs to.
const TENSOR_NAMES = [
  ["Ixx", "Ixy", "Ixz"],
  ["Ixy", "Iyy", "Iyz"],
  ["Ixz", "Iyz", "Izz"],
];

// Each at least 3:1 on the plots' white, WCAG 2.x's contrast for graphics (the amber,
// #c98a00 before, was 2.95:1; #b97f00 is the same hue at 3.44:1): tests/test_dashboard_contrast.py.
const STATUS_COLOR = { identified: "#1e7b34", ambiguous: "#b97f00", "matches-none": "#b3261e", "not-this-sequence": "#b3261e" };

// A verdict (or online result) whose classifier cannot test for a body off the candidates
// (off_candidates_note, no factor): its name is the posterior's alone, so a pass no
// candidate gives (thrusters off their stated torque) is named as confidently. Green
// means a name that passed that test too: such a name is drawn amber, not green.
export function untested(result) {
  return Boolean(result.off_candidates_note) && typeof result.off_candidates_log_bayes !== "number";
}

// The colour of the verdict's candidate: its status's, amber for an untested name.
function candidateColor(verdict) {
  return verdict.status === "identified" && untested(verdict) ? STATUS_COLOR.ambiguous : STATUS_COLOR[verdict.status];
}

const EXAMPLE = "time_s,wx_rad_s,wy_rad_s,wz_rad_s\n0.05,0.0001,0.0009,-0.0004\n0.10,0.0012,0.0031,0.0015\n...";

// A file that begins with gzip's two magic bytes (RFC 1952) is gzip, whatever its name, as
// the service reads an upload.
async function isGzip(file) {
  const head = new Uint8Array(await file.slice(0, 2).arrayBuffer());
  return head.length === 2 && head[0] === 0x1f && head[1] === 0x8b;
}

// The most a gzip file may hold for the page to show it: a bomb (a megabyte of gzip that
// holds gigabytes) stops here instead of filling the tab's memory. The service holds the
// upload to its own limit (INERTIA_ID_MAX_BODY_BYTES, 5 MB by default).
const PAGE_GUNZIP_LIMIT = 64 * 1024 * 1024;

// The text a gzip file holds, decompressed as a stream and stopped past the page's limit.
async function gunzipText(file) {
  const reader = file.stream().pipeThrough(new DecompressionStream("gzip")).getReader();
  const chunks = [];
  let size = 0;
  try {
    for (;;) {
      const { done, value } = await reader.read();
      if (done) break;
      size += value.length;
      if (size > PAGE_GUNZIP_LIMIT) {
        reader.cancel().catch(() => {});
        throw new Error(`${file.name} holds more than ${PAGE_GUNZIP_LIMIT} bytes once decompressed: more than this page reads`);
      }
      chunks.push(value);
    }
  } catch (exc) {
    if (size > PAGE_GUNZIP_LIMIT) throw exc;
    throw new Error(`${file.name} is not a valid gzip file: ${exc.message}`);
  }
  return new Blob(chunks).text();
}

// A stamp in seconds: a number, or an ISO-8601 UTC time (to the millisecond: for drawing).
function stampSeconds(value) {
  if (typeof value === "number") return value;
  const text = String(value ?? "").trim();
  const number = Number(text);
  if (text !== "" && Number.isFinite(number)) return number;
  const ms = Date.parse(text);
  return Number.isFinite(ms) ? ms / 1000 : NaN;
}

// For drawing only: the service parses the same text authoritatively. Times come back
// from the sequence start: `sequenceStart` (seconds in the stamps' clock or ISO-8601
// UTC), else the JSON's own sequence_start, else the stamps are taken as from the start.
export function parseTelemetry(text, sequenceStart = "") {
  const trimmed = text.trim();
  let time = [];
  let omega = [];
  let start = sequenceStart;
  if (trimmed.startsWith("{")) {
    const data = JSON.parse(trimmed);
    time = (data.time_s ?? data.time_utc ?? []).map(stampSeconds);
    // omega_deg_s states deg/s as a CSV header's wx_deg_s does: drawn in rad/s.
    omega = data.omega_rad_s ?? (data.omega_deg_s ?? []).map((row) => row.map((v) => v / DEG));
    if (start === "" || start === null || start === undefined) start = data.sequence_start;
  } else {
    for (const line of trimmed.split(/\r?\n/)) {
      const cells = line.split(",").map((c) => c.trim());
      const stamp = stampSeconds(cells[0]);
      const rates = cells.slice(1).map(Number);
      if (cells.length !== 4 || !Number.isFinite(stamp) || rates.some((v) => !Number.isFinite(v))) continue;
      time.push(stamp);
      omega.push(rates);
    }
  }
  const offset = start === "" || start === null || start === undefined ? 0 : stampSeconds(start);
  if (Number.isFinite(offset) && offset !== 0) time = time.map((t) => t - offset);
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
  const text = h("textarea", { id: "telemetry-text", rows: 8, placeholder: `CSV (time_s or time_utc, wx_rad_s, wy_rad_s, wz_rad_s) or JSON {"time_s": [...], "omega_rad_s": [[...], ...]}\n${EXAMPLE}` });
  const file = h("input", { type: "file", id: "telemetry-file", accept: ".csv,.json,.gz,text/csv,application/json,application/gzip" });
  // A gzip file chosen and the text it holds: sent as chosen (compressed) while the text
  // is not edited.
  let gzipped = null;
  // A file's text lands only if it is still the file chosen last and nothing was typed in
  // the box since it was chosen: a large (gzip) file read slowly landed over the file
  // chosen after it, or over what was typed meanwhile.
  let chosenCount = 0;
  let typed = false;
  text.addEventListener("input", () => {
    typed = true;
  });
  file.addEventListener("change", async () => {
    const mine = ++chosenCount;
    typed = false;
    gzipped = null;
    clear(general);
    if (!file.files.length) return;
    const chosen = file.files[0];
    const current = () => mine === chosenCount && !typed && context.alive();
    try {
      if (await isGzip(chosen)) {
        const unpacked = await gunzipText(chosen);
        if (!current()) return;
        text.value = unpacked;
        gzipped = { file: chosen, text: text.value };
      } else {
        const read = await chosen.text();
        if (!current()) return;
        text.value = read;
      }
    } catch (exc) {
      if (!current()) return;
      text.value = "";
      general.append(messageBox("error", exc.message));
    }
  });
  const start = h("input", { type: "text", id: "identify-sequence-start", size: 34, placeholder: "e.g. 810000000.0 or 2025-03-01T12:00:00Z", value: context.query.sequence_start || "" });
  const averaged = h("input", { type: "checkbox", id: "identify-averaged", checked: context.query.averaged === "true" });
  const startWithin = h("input", { type: "number", id: "identify-start-within", min: "0", max: "100", step: "any", placeholder: "e.g. 0.5", value: context.query.estimate_start_within_s || "" });
  const confidence = h("input", { type: "number", id: "identify-confidence", min: "0", max: "1", step: "any", value: context.query.confidence || String(DEFAULT_CONFIDENCE) });
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
        // The last refusal's messages beside the fields go too: they stayed, in red, under
        // the verdict of the corrected telemetry.
        clearFieldErrors(form, general);
        if (withoutKey(general, "Identifying telemetry")) return;
        const content = text.value;
        if (!content.trim()) {
          general.append(messageBox("error", "paste telemetry or choose a file first"));
          return;
        }
        const name = content.trim().startsWith("{") ? "telemetry.json" : "telemetry.csv";
        const options = { sequenceStart: start.value.trim(), startWithin: startWithin.value.trim(), confidence: confidence.value.trim(), averaged: averaged.checked };
        submit.disabled = true;
        // The classifier sent, not the one the menu names when the verdict comes: chosen
        // meanwhile, another one's metric titled the verdict and its response (of other
        // candidates, on another scenario) was drawn under the telemetry, or failed to be.
        const classifier = page.items.find((c) => c.id === select.value);
        try {
          const upload = gzipped && gzipped.text === content ? gzipped.file : new File([content], name, { type: "text/plain" });
          const verdict = await api.identify(classifier.id, upload, "json", options);
          await showVerdict(result, verdict, classifier, { content, context, file: upload, options });
        } catch (exc) {
          showFieldErrors(exc, { file: text, classifier_id: select, sequence_start: start, estimate_start_within_s: startWithin, confidence, averaged }, general);
        } finally {
          submit.disabled = false;
          // Disabled while it ran, the button lost the focus to <body>: give it back.
          if (document.activeElement === document.body && context.alive()) submit.focus();
        }
      },
    },
    h(
      "div",
      { class: "stack" },
      h("label", { for: "identify-classifier" }, "classifier"),
      select,
      h("label", { for: "telemetry-file" }, "upload a file"),
      h("div", {}, file, h("span", { class: "hint" }, " .csv or .json, or either gzip-compressed (.csv.gz, .json.gz); time_s in seconds (any clock) or time_utc in ISO-8601 UTC, ω in rad/s")),
      h("label", { for: "identify-sequence-start" }, "sequence start"),
      h(
        "div",
        {},
        start,
        h("div", { class: "hint" }, "when the actuation sequence began, in the telemetry's clock: seconds (e.g. mission time 810000000.0) or ISO-8601 UTC (2025-03-01T12:00:00Z). Leave empty when time_s counts from the sequence start."),
      ),
      h("label", { for: "identify-start-within" }, "search the start within (s)"),
      h("div", {}, startWithin, h("div", { class: "hint" }, "optional: try the starts within this many seconds of the stated one and judge from the one whose series lies closest to a candidate; the verdict says the shift it used. Empty: the stated start (a matches-none verdict still says when a start within 0.5 s would match).")),
      h("label", { for: "identify-averaged" }, "averaging gyro"),
      h("div", {}, averaged, h("span", { class: "hint" }, " each rate is the mean over one sample period before its stamp (an integrating or delta-angle gyro): read half a period earlier")),
      h("label", { for: "identify-confidence" }, "confidence"),
      h("div", {}, confidence, h("div", { class: "hint" }, "the posterior the most probable candidate needs before it is named (0 to 1, exclusive); below it the verdict is ambiguous")),
      h("label", { for: "telemetry-text", class: "full" }, "or paste telemetry"),
      h("div", { class: "full" }, text),
    ),
    general,
    h("div", { class: "toolbar" }, submit),
  );
  root.append(h("div", { class: "card" }, form), result);
}

// The box's class and headline for each status: green only for "identified" by a
// classifier that tested for a body off the candidates; amber, saying so, for one that
// cannot (its name is the posterior's alone).
function verdictBox(verdict, ranked) {
  const [first, second] = ranked;
  const named = (entry) => `${entry[0]} (${probability(entry[1])})`;
  const candidate = `Candidate: ${verdict.candidate} (${probability(verdict.confidence)})`;
  const headline = {
    identified: untested(verdict)
      ? ["untested", `${candidate}, untested: this classifier cannot tell it from a body off the candidates (thrusters off their stated torque?)`]
      : ["match", candidate],
    // A candidate reached the confidence, but the telemetry fits another body near the
    // candidates better (thrusters off their stated torque, for one): not named.
    ambiguous: verdict.fits_off_candidates
      ? ["ambiguous", `Not identified: ${named(first)} fits best, but the telemetry fits another body better (thrusters off their stated torque?)`]
      : ["ambiguous", `Ambiguous: ${named(first)} or ${second ? named(second) : "none of these"}`],
    "matches-none": ["none", `Matches none of the candidates (none of these: ${probability(verdict.p_none)})`],
    "not-this-sequence": ["none", "Not a response to this sequence: check the start stated, and that the sequence fired"],
  }[verdict.status] || ["none", verdict.verdict];
  return h("div", { class: `verdict ${headline[0]}`, id: "verdict", role: "status", "data-status": verdict.status }, headline[1]);
}

// How much better another body near the candidates explains the telemetry than they do
// (the default kind's model of "none"): a candidate is named only below 0. A classifier
// without that model says it cannot test it (off_candidates_note): amber, since its name
// is the posterior's alone.
function offCandidates(verdict) {
  const factor = verdict.off_candidates_log_bayes;
  if (verdict.off_candidates_note && typeof factor !== "number") {
    return [h("dt", {}, "another body near the candidates"), h("dd", { id: "off-candidates", class: "caution" }, `not tested: ${verdict.off_candidates_note}`)];
  }
  if (typeof factor !== "number" || !Number.isFinite(factor)) return null;
  const reading = factor < 0 ? "below 0: no other body near the candidates fits better" : "not below 0: another body near the candidates fits better, so none is named";
  return [h("dt", {}, "another body near the candidates against them (log Bayes factor)"), h("dd", { id: "off-candidates" }, `${ratio(factor)} (${reading})`)];
}

// Where a candidate reached 1 - alpha but the data so far fit another body near the
// candidates better (the online result's fits_off_candidates): amber, saying whether that
// held the decision back or disowns one taken earlier. Null otherwise.
function offCandidatesOnline(online, decided, t, needed) {
  if (!online.fits_off_candidates) return null;
  const factor = `log Bayes factor ${ratio(online.current_off_candidates_log_bayes)}, not below 0`;
  const text = decided
    ? `but the data so far fit another body near the candidates better (${factor}): the decision on ${online.candidate} is disowned since (thrusters off their stated torque?)`
    : `not decided: a candidate reached ${needed} %${online.withheld_time_s === null ? "" : ` at ${t(online.withheld_time_s)} s`}, but the data so far fit another body near the candidates better (${factor}; thrusters off their stated torque?)`;
  return h("p", { class: "verdict ambiguous", id: "online-off-candidates", role: "status" }, text);
}

// What the sequence hardly excites, in words: "it cannot see it" for one entry, "them"
// for several (one read "it cannot see them").
export function notExcitedText(poorly) {
  return `this sequence hardly excites ${poorly.join(", ")}: it cannot see ${poorly.length === 1 ? "it" : "them"}`;
}

// The tensor with each entry's standard error, or why it is withheld and what this
// sequence cannot see.
function estimateOf(verdict) {
  const poorly = verdict.poorly_excited || [];
  const blind = poorly.length ? h("div", { class: "field-error", id: "ls-blind" }, notExcitedText(poorly)) : null;
  if (verdict.estimated_inertia_kg_m2) {
    const std = verdict.estimated_inertia_std_kg_m2 || {};
    const rows = verdict.estimated_inertia_kg_m2.map((row, i) =>
      h("tr", {}, row.map((v, j) => h("td", {}, measured(v, std[TENSOR_NAMES[i][j]])))),
    );
    return [
      h("table", { class: "tensor mono" }, h("tbody", {}, rows)),
      `principal moments ${verdict.estimated_principal_moments_kg_m2.map((v) => quantity(v, 4)).join(", ")}; condition number ${ratio(verdict.estimate_condition_number)}`,
      blind,
    ];
  }
  if (verdict.estimate_rejected) return [h("span", { id: "ls-rejected" }, `withheld: ${verdict.estimate_rejected}`), blind];
  return "–";
}

const DEG = 180 / Math.PI;

// The body's rate plus the gyro bias at the sequence start, measured by the samples before
// it (the classifier conditions on it), in rad/s and deg/s, the rad/s with its standard
// error and every digit that justifies.
function offsetOf(verdict) {
  if (!verdict.initial_offset_rad_s) return "– (the telemetry starts at the sequence start)";
  const std = verdict.initial_offset_std_rad_s || [];
  const axes = verdict.initial_offset_rad_s.map((v, i) => measured(v, std[i]));
  const deg = verdict.initial_offset_rad_s.map((v) => (v * DEG).toPrecision(3));
  return `[${axes.join(", ")}] rad/s = [${deg.join(", ")}] deg/s, from ${verdict.pre_start_samples} samples`;
}

// A dimensionless figure (a condition number, a distance in training-RMS units, a
// margin): three significant digits, no trailing zeros (fixed decimals wrote 12.500).
const ratio = (value) => (typeof value === "number" && Number.isFinite(value) ? plain(value, 3) : "–");

// The telemetry's sample period, s: the median spacing of its stamps (as the service
// takes it), to three significant digits (mission-time stamps near 1e9 s differ by a
// period give or take their rounding); null for fewer than two stamps.
function samplePeriod(time) {
  const steps = [];
  for (let i = 1; i < time.length; i += 1) if (time[i] > time[i - 1]) steps.push(time[i] - time[i - 1]);
  if (!steps.length) return null;
  steps.sort((a, b) => a - b);
  return Number(steps[Math.floor(steps.length / 2)].toPrecision(3));
}

// The decimals a time on this page carries: those that resolve one sample period of the
// telemetry (and of the posterior's grid, `periods` more), and never fewer than two (two
// alone wrote a 1 kHz gyro's dropout from 1.003 s as 1.00).
function timeDecimals(...periods) {
  return Math.max(2, ...periods.filter((p) => typeof p === "number" && p > 0).map((p) => decimalsFor(p, 1)));
}

// The start the verdict judged from, and the shift a start search moved it by: seconds
// to the telemetry's decimals, or as many as the stated start was typed with (an ISO
// start as the service wrote it).
function startUsed(verdict, decimals, stated) {
  const typed = /^[-+]?\d*\.(\d+)$/.exec(String(stated ?? "").trim());
  const start =
    typeof verdict.sequence_start === "number"
      ? verdict.sequence_start.toFixed(Math.max(decimals, typed ? typed[1].length : 0))
      : verdict.sequence_start ?? "the telemetry's zero";
  if (verdict.estimate_start_within_s === null || verdict.estimate_start_within_s === undefined) return `${start} (as stated)`;
  const shift = verdict.sequence_start_shift_s;
  // A start refined below the grid period (the likelihood kinds) is said to be.
  const refined = verdict.sequence_start_refined === true ? ", refined below the grid period" : "";
  const used = `${start} (shifted ${shift >= 0 ? "+" : ""}${shift.toFixed(decimals)} s by the search within ±${plain(verdict.estimate_start_within_s, 6)} s${refined})`;
  // A kind that compares whole series keeps its grid's start, unrefined: said in amber.
  if (!verdict.sequence_start_note) return used;
  return [used, h("div", { class: "caution", id: "start-unrefined" }, verdict.sequence_start_note)];
}

// The dropouts the verdict judged across (on the samples present), the part of the
// sequence's grid times outside them and the part with a real sample; null when none.
function gapsOf(verdict, decimals) {
  const gaps = verdict.telemetry_gaps || [];
  if (!gaps.length) return null;
  const s = (v) => v.toFixed(decimals);
  const spans = gaps.map((g) => `${s(g.length_s)} s (${s(g.from_s)}–${s(g.to_s)} s)`).join(", ");
  const covered = `${plain(100 * verdict.sequence_covered_fraction, 3)} % of the sequence covered`;
  // The grid times with a real sample within half a grid period (older answers lack it).
  const measured = verdict.sequence_measured_fraction;
  return typeof measured === "number"
    ? `${spans}; ${covered}, ${plain(100 * measured, 3)} % sampled`
    : `${spans}; ${covered}`;
}

async function showVerdict(holder, verdict, classifier, { content, context, file, options }) {
  const telemetry = parseTelemetry(content, options.sequenceStart);
  const period = samplePeriod(telemetry.time);
  const decimals = timeDecimals(period);
  const names = Object.keys(verdict.distances);
  const ranked = Object.entries(verdict.posterior || {}).sort((a, b) => b[1] - a[1]);
  const met = verdict.confidence >= verdict.required_confidence;
  const posteriorPlot = plotDiv("posterior-plot", "short");
  const distancePlot = plotDiv("distance-plot", "short");
  const overlayPlot = plotDiv("overlay-plot");
  // The response's warnings (a classifier's sequence whose rates stay far below the gyro
  // noise: its verdict reads noise), said under the verdict as the classifier page says
  // them above the classifier; filled once the response the overlay draws has come.
  const responseWarnings = h("div", { id: "identify-response-warnings-holder" });
  const onlineHolder = h("div", { id: "online-holder" });
  const posteriorRows = [...ranked, ["none of these", verdict.p_none]].map(([name, p]) =>
    h(
      "tr",
      { class: name === verdict.candidate && verdict.status === "identified" ? "top" : null, "data-hypothesis": name },
      h("td", {}, name),
      h("td", { class: "num posterior" }, probability(p)),
      h("td", { class: "num" }, name in verdict.distances ? ratio(verdict.distances[name]) : "–"),
    ),
  );
  holder.append(
    h(
      "div",
      { class: "card" },
      verdictBox(verdict, ranked),
      responseWarnings,
      h(
        "p",
        { class: "verdict-confidence", id: "verdict-confidence" },
        `confidence ${probability(verdict.confidence)} ${met ? "≥" : "<"} required ${plain(100 * verdict.required_confidence, 8)} %`,
      ),
      verdict.verdict !== verdict.candidate ? h("p", { id: "verdict-text" }, verdict.verdict) : null,
      downloads("identify-downloads", [
        { label: "verdict (JSON)", filename: `identify-${verdict.classifier_id.slice(0, 8)}.json`, make: async () => jsonBlob(verdict) },
        { label: "verdict (CSV)", filename: `identify-${verdict.classifier_id.slice(0, 8)}.csv`, make: () => api.identify(verdict.classifier_id, file, "csv", options) },
      ]),
      h(
        "dl",
        { class: "kv" },
        h("dt", {}, "margin to the runner-up"),
        h("dd", { id: "verdict-margin" }, `${ratio(verdict.margin)} (relative ${ratio(verdict.relative_margin)})`),
        offCandidates(verdict),
        h("dt", {}, `inertia of ${verdict.status === "identified" ? "the candidate" : "the most probable candidate"} (kg m²)`),
        h("dd", { class: "mono", id: "candidate-inertia" }, verdict.inertia_kg_m2 ? verdict.inertia_kg_m2.map((r) => `[${r.map((v) => quantity(v, 4)).join(", ")}]`).join(" ") : "–"),
        h("dt", {}, "classifier"),
        h("dd", {}, link(`#/classifiers/${verdict.classifier_id}`, verdict.classifier_id)),
        h("dt", {}, "least-squares estimate from this telemetry (kg m², ± standard error)"),
        h("dd", { id: "ls-estimate" }, estimateOf(verdict)),
        h("dt", {}, "sequence start used"),
        h("dd", { id: "start-used" }, startUsed(verdict, decimals, options.sequenceStart)),
        gapsOf(verdict, decimals) ? [h("dt", {}, "dropouts judged across (s from the start used)"), h("dd", { id: "telemetry-gaps" }, gapsOf(verdict, decimals))] : null,
        h("dt", {}, "rate + gyro bias at the start, from the telemetry before it"),
        h("dd", { id: "initial-offset", class: "mono" }, offsetOf(verdict)),
      ),
    ),
    h(
      "div",
      { class: "grid2" },
      h(
        "div",
        { class: "card" },
        h("h2", {}, "Posterior of each candidate"),
        posteriorPlot,
        h("table", { class: "posterior-table", id: "posterior-table" }, h("thead", {}, h("tr", {}, h("th", { scope: "col" }, "hypothesis"), h("th", { scope: "col", class: "num" }, "posterior"), h("th", { scope: "col", class: "num" }, "distance"))), h("tbody", {}, posteriorRows)),
      ),
      h("div", { class: "card" }, h("h2", {}, "Distance to each candidate"), distancePlot),
    ),
    h("div", { class: "grid2" }, h("div", { class: "card" }, h("h2", {}, "Posterior over time"), onlineHolder), h("div", { class: "card" }, h("h2", {}, `Telemetry over ${verdict.candidate}'s response`), overlayPlot)),
  );
  drawPosterior(posteriorPlot, verdict, ranked);
  const values = names.map((n) => verdict.distances[n]);
  const none = verdict.status === "matches-none" || verdict.status === "not-this-sequence";
  Plotly.newPlot(
    distancePlot,
    [
      {
        type: "bar",
        x: names.map(plotText),
        y: values,
        marker: { color: names.map((n) => (n === verdict.candidate ? candidateColor(verdict) || (none ? "#b3261e" : "#1e7b34") : "#8da9c4")) },
        hovertemplate: "%{x}: %{y:.4g}<extra></extra>",
        name: "distance",
      },
      ...(verdict.threshold !== null
        ? [{ x: names.map(plotText), y: names.map(() => verdict.threshold), mode: "lines", line: { color: "#b3261e", dash: "dash" }, name: `"matches none"<br>threshold` }]
        : []),
    ],
    layout("candidate", "distance (training-RMS units)", {
      height: 420,
      title: title(`${classifier ? classifier.metric : ""} distance to each candidate's centroid`, 13),
      showlegend: verdict.threshold !== null,
    }),
    PLOT_CONFIG,
  );

  const info = classifier ? kindInfo(classifier.kind) : null;
  if (info && !info.online) {
    onlineHolder.append(h("p", { class: "note", id: "online-note" }, `No posterior over time for the ${info.label} kind: only the likelihood kinds have one (their Gaussian's leading block).`));
  } else {
    await showOnline(onlineHolder, verdict, file, options, context, period);
  }
  if (!classifier || !context.alive()) return;
  const response = await api.response(classifier.scenario_id, classifier.sequence, { n_realisations: 20 });
  if (!context.alive()) return;
  put(responseWarnings, warningsBox(response.warnings, "identify-response-warnings"));
  const k = response.candidates.findIndex((c) => c.name === verdict.candidate);
  const candidate = response.candidates[k];
  const color = COLORS[k % COLORS.length];
  // The response starts at rest; the telemetry carries the rate + gyro bias measured
  // before the start, which the verdict accounted for: the band is shifted by it.
  const offset = verdict.initial_offset_rad_s || [0, 0, 0];
  const shifted = offset.some((v) => v !== 0);
  const traces = [];
  ["x", "y", "z"].forEach((axis, a) => {
    const yaxis = a === 0 ? "y" : `y${a + 1}`;
    const plus = (rows) => rows.map((r) => r[a] + offset[a]);
    traces.push(
      { x: response.time_s, y: plus(candidate.low_rad_s), yaxis, mode: "lines", line: { width: 0 }, showlegend: false, hoverinfo: "skip" },
      { x: response.time_s, y: plus(candidate.high_rad_s), yaxis, mode: "lines", line: { width: 0 }, fill: "tonexty", fillcolor: withAlpha(color, 0.2), showlegend: false, hoverinfo: "skip" },
      { x: response.time_s, y: plus(candidate.mean_rad_s), yaxis, mode: "lines", line: { color, width: 2 }, name: "mean response", showlegend: a === 0 },
      { x: telemetry.time, y: telemetry.omega.map((r) => r[a]), yaxis, mode: "markers", marker: { color: "#222", size: 4 }, name: "telemetry", showlegend: a === 0 },
    );
  });
  overlayPlot.dataset.offset = JSON.stringify(offset);
  const overlayTitle = `telemetry (dots) over ${plotText(candidate.name)}'s mean and ${BAND.label} band${shifted ? ", shifted by the rate + bias measured before the start" : ""}`;
  await Plotly.newPlot(overlayPlot, [...traces, ...twinTraces(responseTwins())], responseLayout(overlayTitle), PLOT_CONFIG);
  keepTwins(overlayPlot, responseTwins());
}

// A bar per hypothesis, its percentage on it, the required confidence as a dashed line.
function drawPosterior(element, verdict, ranked) {
  const names = Object.keys(verdict.posterior || {});
  const y = [...names.map((n) => verdict.posterior[n]), verdict.p_none];
  const top = ranked.length ? ranked[0][0] : null;
  const none = verdict.status === "matches-none" || verdict.status === "not-this-sequence";
  const colors = [...names.map((n) => (n === top && !none ? candidateColor(verdict) : "#8da9c4")), none ? STATUS_COLOR[verdict.status] : "#9aa5b1"];
  const x = [...names.map(plotText), "none of these"];
  Plotly.newPlot(
    element,
    [
      {
        type: "bar",
        x,
        y,
        text: y.map(probability),
        textposition: "auto",
        marker: { color: colors },
        hovertemplate: "%{x}: %{text}<extra></extra>",
        name: "posterior",
      },
    ],
    layout("hypothesis", "posterior", {
      height: 380,
      showlegend: false,
      yaxis: { title: { text: "posterior" }, range: [0, 1.05], tickformat: ".0%" },
      title: title(`posterior; naming one requires ${plain(100 * verdict.required_confidence, 8)} %`, 13),
      shapes: [{ type: "line", xref: "paper", x0: 0, x1: 1, y0: verdict.required_confidence, y1: verdict.required_confidence, line: { color: "#5f6b7a", dash: "dash", width: 1 } }],
    }),
    PLOT_CONFIG,
  );
}

// The posterior after every covered sample (likelihood kinds), the decision marked; a
// kind without a Gaussian model gets the service's message instead.
async function showOnline(holder, verdict, file, options, context, period) {
  let online;
  try {
    online = await api.identifyPartial(verdict.classifier_id, file, options);
  } catch (exc) {
    if (!context.alive()) return;
    holder.append(h("p", { class: "note", id: "online-note" }, exc.status === 422 ? `No posterior over time for this classifier: ${exc.message}` : exc.message));
    return;
  }
  if (!context.alive()) return;
  const plot = plotDiv("online-plot");
  const decided = online.decided && online.decision_time_s !== null;
  // The posterior's times lie on the classifier's grid: to a period of it and of the telemetry.
  const decimals = timeDecimals(period, samplePeriod(online.time_s));
  const t = (v) => v.toFixed(decimals);
  const needed = plain(100 * (1 - online.alpha), 8);
  // The verdict's off-candidates rule, prefix by prefix: the factor at the decision.
  const atDecision = online.decision_off_candidates_log_bayes;
  const factorThen = typeof atDecision === "number" && Number.isFinite(atDecision) ? `; another body near the candidates: log Bayes factor ${ratio(atDecision)}, below 0` : "";
  // A decision the data since disown (fits_off_candidates): its summary is amber like the
  // box below it and the plot's line, not the grey of a plain note.
  const disowned = decided && online.fits_off_candidates;
  // A classifier that cannot test for other bodies says so (its decision is the
  // posterior's alone), in amber; a decision it took is amber too (summary, line and
  // title), not the grey summary and green line of a decision that passed the test.
  const unconfirmed = decided && untested(online);
  const untestedNote = online.off_candidates_note ? h("p", { class: "note caution", id: "online-off-candidates-untested" }, `not tested: ${online.off_candidates_note}`) : null;
  holder.append(
    h(
      "p",
      { class: disowned || unconfirmed ? "note disowned" : "note", id: "online-summary" },
      decided
        ? `decided on ${online.candidate} at ${t(online.decision_time_s)} s (posterior ≥ ${needed} %${factorThen}${unconfirmed ? "; untested for a body off the candidates" : ""})`
        : `not decided within ${t(online.covers_s)} s of the ${t(online.sequence_s)} s sequence (posterior ≥ ${needed} % needed)`,
    ),
    ...[offCandidatesOnline(online, decided, t, needed), untestedNote].filter(Boolean),
    plot,
  );
  const names = Object.keys(online.posterior);
  const traces = names.map((name, k) => ({
    x: online.time_s,
    y: online.posterior[name],
    mode: "lines",
    line: { color: COLORS[k % COLORS.length], width: 2 },
    name: plotText(name),
    hovertemplate: `${plotText(name)}, t = %{x:.${decimals}f} s: %{y:.2%}<extra></extra>`,
  }));
  traces.push({ x: online.time_s, y: online.p_none, mode: "lines", line: { color: "#5f6b7a", width: 2, dash: "dash" }, name: "none of these", hovertemplate: `none of these, t = %{x:.${decimals}f} s: %{y:.2%}<extra></extra>` });
  const shapes = [{ type: "line", xref: "paper", x0: 0, x1: 1, y0: 1 - online.alpha, y1: 1 - online.alpha, line: { color: "#9aa5b1", dash: "dot", width: 1 } }];
  // A decision the data since disown, or one a classifier took that cannot test for a
  // body off the candidates, is drawn amber, not green, and the title says so: the plot
  // alone read as a confirmed identification.
  if (decided) shapes.push({ type: "line", yref: "paper", x0: online.decision_time_s, x1: online.decision_time_s, y0: 0, y1: 1, line: { color: disowned || unconfirmed ? STATUS_COLOR.ambiguous : STATUS_COLOR.identified, dash: "dash", width: 2 } });
  const caveat = disowned ? ", disowned since: the data so far fit another body better" : unconfirmed ? ", untested for a body off the candidates" : "";
  Plotly.newPlot(
    plot,
    traces,
    layout("time from sequence start (s)", "posterior", {
      height: 560,
      yaxis: { title: { text: "posterior" }, range: [0, 1.05], tickformat: ".0%" },
      title: title(decided ? `decided at ${t(online.decision_time_s)} s (dashed line)${caveat}` : "not decided yet", 13),
      shapes,
    }),
    PLOT_CONFIG,
  );
}
