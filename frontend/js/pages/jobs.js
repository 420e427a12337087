// Jobs: submit a search, a training or a sweep (with a name and tags), and the runs: a
// sorted, filtered, paged list with their headline figures, queue and run time, refreshed
// every two seconds without reloading the page.

import { api } from "../api.js";
import { STOPPED_LABELS, cancelButton, headline, jobCell, parseTags, stoppedNote, submitAndOpen, summaryTableColumns, timingCell } from "../components/jobs.js";
import { dataTable } from "../components/table.js";
import { otherSpecs, vocabulary } from "../vocabulary.js";
import { clear, h, link, messageBox, progressBar, showFieldErrors, statusBadge, when } from "../ui.js";

const POLL_MS = 2000;

// The value as the service should see it: an integer or number when it parses as one,
// else the text itself, so that the service's message quotes what was typed.
function intOrText(text) {
  const trimmed = String(text).trim();
  return /^[+-]?\d+$/.test(trimmed) ? Number(trimmed) : trimmed;
}

// A box of JSON refused before it is sent, next to the box (`loc` as the service's 422
// would give it): sent as typed, "{bad" came back "Input should be a valid dictionary,
// got '{bad'", and a design noise of "[[1, 1]" came back quoted as a string: neither
// said the JSON was broken.
class BoxError extends Error {
  constructor(loc, message) {
    super(message);
    this.errors = [{ loc, msg: message }];
  }
}

// Where in a parsed value a number past the largest a double holds sits ("population",
// "[0][0]"), or null: JSON.parse reads 1e400 as Infinity, which JSON.stringify sends as
// null, and the service answered "... got None", a value nobody typed.
function infiniteAt(value, path = "") {
  if (typeof value === "number") return Number.isFinite(value) ? null : path || "the value";
  if (value === null || typeof value !== "object") return null;
  for (const [key, item] of Object.entries(value)) {
    const found = infiniteAt(item, Array.isArray(value) ? `${path}[${key}]` : path ? `${path}.${key}` : key);
    if (found !== null) return found;
  }
  return null;
}

// The value typed in a box of JSON, or a BoxError naming the box and the parser's
// reason. An empty box is `empty` (undefined: sent as typed, for the service to name).
function jsonBox(input, label, loc, empty = undefined) {
  const text = String(input.value).trim();
  if (!text) return empty === undefined ? text : empty;
  let value;
  try {
    value = JSON.parse(text);
  } catch (exc) {
    throw new BoxError(loc, `${label}: not valid JSON: ${exc.message}`);
  }
  const infinite = infiniteAt(value);
  if (infinite !== null) throw new BoxError(loc, `${label}: ${infinite} is past the largest number (about 1.8e308)`);
  return value;
}

// "max_final_rate_deg_s=0.2, max_impulse_nms=20" as an object of numbers, or a JSON
// object (broken JSON named before it is sent). A part that is not name=number is
// refused next to the box, naming it: sent as typed, "max_final_rate_deg_s=abc" came back
// "Input should be a valid dictionary, got 'max_final_rate_deg_s=abc'".
function constraintsOrText(input) {
  const loc = ["body", "params", "constraints"];
  const trimmed = String(input.value).trim();
  if (!trimmed) return {};
  if (trimmed.startsWith("{")) return jsonBox(input, "constraints", loc);
  const out = {};
  for (const raw of trimmed.split(/[,;\n]+/)) {
    const part = raw.trim();
    if (!part) continue;
    // Names carry digits too (max_final_rate_p95_deg_s).
    const match = part.match(/^([A-Za-z_][A-Za-z0-9_]*)\s*(?:<=|>=|=|:)\s*(.*)$/);
    if (!match) throw new BoxError(loc, `constraints: “${part}” is not name=bound (such as max_final_rate_deg_s=0.2)`);
    const [, name, bound] = match;
    if (!bound) throw new BoxError(loc, `constraints: ${name} has no bound (such as ${name}=0.2)`);
    if (!DECIMAL.test(bound)) throw new BoxError(loc, `constraints: ${name}'s bound “${bound}” is not a number (its unit is in its name)`);
    if (!Number.isFinite(Number(bound))) throw new BoxError(loc, `constraints: ${name}'s bound ${bound} is past the largest number (about 1.8e308)`);
    out[name] = Number(bound);
  }
  return out;
}

// A number as the service should see it, else the text itself (quoted by its 422).
// Decimal notation only: Number() also reads "0x10" (16), "0b11" and "0o7", and a time
// limit or a multiple typed so was sent as another number than the one shown.
const DECIMAL = /^[+-]?(\d+\.?\d*|\.\d+)(e[+-]?\d+)?$/i;
function numberOrText(text) {
  const trimmed = String(text).trim();
  return DECIMAL.test(trimmed) && Number.isFinite(Number(trimmed)) ? Number(trimmed) : trimmed;
}

// The job's time limit box: left out when empty, so the service's ceiling holds.
const timeLimitBox = () => h("input", { value: "", size: 8, placeholder: "the ceiling" });
const timeLimit = (input) => (input.value.trim() ? { time_limit_s: numberOrText(input.value) } : {});
// The floor is the service's (inertia_id.deadline.TIME_LIMIT_MIN_S): less is refused
// with a 422, shown beside the box (most likely milliseconds typed as seconds).
const TIME_LIMIT_HINT = "wall-clock seconds, at least 1; empty: the service's ceiling (INERTIA_ID_JOB_TIME_LIMIT_S)";

function field(id, label, input, hint = "") {
  input.id = id;
  return [h("label", { for: id }, label), h("div", {}, input, hint ? h("span", { class: "hint" }, ` ${hint}`) : null)];
}

function submitForm(scenarios, classifiers, query) {
  const OTHERS = otherSpecs();
  const general = h("div");
  // A link naming a scenario or classifier the service no longer has (deleted in another
  // tab, a stale bookmark) selects nothing and says so: falling back to the first one in
  // the list sent the job against a scenario the user never chose.
  const unknownScenario = query.scenario && !scenarios.some((s) => s.id === query.scenario);
  const unknownClassifier = query.classifier && !classifiers.some((c) => c.id === query.classifier);
  const missing = [unknownScenario ? `scenario ${query.scenario}` : null, unknownClassifier ? `classifier ${query.classifier}` : null].filter((v) => v);
  const missingNote = missing.length
    ? messageBox("error", `The link names ${missing.join(" and ")}, which the service does not have (deleted, or a wrong link): choose below.`)
    : null;
  if (missingNote) missingNote.id = "job-form-missing";
  const choose = (what) => h("option", { value: "", selected: true, disabled: true }, `choose a ${what}`);
  const scenarioSelect = () => {
    const select = h(
      "select",
      { required: true },
      unknownScenario ? choose("scenario") : null,
      scenarios.map((s) => h("option", { value: s.id, selected: s.id === query.scenario }, `${s.name} (${s.id.slice(0, 8)})`)),
    );
    return select;
  };
  const byId = Object.fromEntries(scenarios.map((s) => [s.id, s]));

  // Search.
  const search = {
    scenario: scenarioSelect(),
    method: h("select", {}, vocabulary().search_methods.map((m) => h("option", { value: m.name, title: m.label }, m.name))),
    objective: h("select", {}, vocabulary().search_objectives.map((o) => h("option", { value: o.name }, o.label))),
    sequence_length: h("input", { value: 4, size: 6 }),
    timesteps: h("input", { value: 20480, size: 10 }),
    n_realisations: h("input", { value: 20, size: 6 }),
    metric: h("select", {}, ["dtw", "euclidean", "softdtw"].map((m) => h("option", { value: m }, m))),
    patience_episodes: h("input", { value: 500, size: 8 }),
    fuel_weight: h("input", { value: 0, size: 8 }),
    ppo: h("input", { value: "{}", size: 40 }),
    nsga2: h("input", { value: "{}", size: 40 }),
    objectives: h(
      "span",
      { class: "checks" },
      vocabulary().operator_objectives.map((o) =>
        h("label", { class: "check", title: o.label }, h("input", { type: "checkbox", value: o.name, id: `search-objective-${o.name}`, checked: vocabulary().default_operator_objectives.includes(o.name) }), ` ${o.name} `),
      ),
    ),
    design_noise: h("input", { value: JSON.stringify(vocabulary().default_design_noise), size: 24 }),
    constraints: h("input", { value: "", size: 48, placeholder: "max_final_rate_deg_s=0.2, max_impulse_nms=20" }),
    seed: h("input", { value: 0, size: 8 }),
    time_limit_s: timeLimitBox(),
  };
  const chosenObjectives = () => [...search.objectives.querySelectorAll("input:checked")].map((i) => i.value);
  const searchBody = () => ({
    type: "search",
    scenario_id: search.scenario.value,
    seed: intOrText(search.seed.value),
    params: {
      method: search.method.value,
      sequence_length: intOrText(search.sequence_length.value),
      timesteps: intOrText(search.timesteps.value),
      n_realisations: intOrText(search.n_realisations.value),
      objective: search.objective.value,
      metric: search.metric.value,
      patience_episodes: intOrText(search.patience_episodes.value),
      // Empty is 0, as before.
      fuel_weight: search.fuel_weight.value.trim() ? numberOrText(search.fuel_weight.value) : 0,
      ...(search.method.value === "ppo" ? { ppo: jsonBox(search.ppo, "PPO overrides", ["body", "params", "ppo"], {}) } : {}),
      ...(search.method.value === "nsga2" ? { nsga2: jsonBox(search.nsga2, "NSGA-II settings", ["body", "params", "nsga2"], {}) } : {}),
      objectives: chosenObjectives(),
      // An emptied design-noise box is left out: the service's default. Sent as "", it
      // refused every search, CEM and PPO too ("Input should be a valid list, got ''").
      ...(search.design_noise.value.trim() ? { design_noise: jsonBox(search.design_noise, "design noise", ["body", "params", "design_noise"]) } : {}),
      constraints: constraintsOrText(search.constraints),
      ...timeLimit(search.time_limit_s),
    },
  });

  // Train.
  const train = {
    scenario: scenarioSelect(),
    sequence: h("input", { size: 60 }),
    kind: h(
      "select",
      {},
      [...vocabulary().classifier_kinds]
        .sort((a, b) => (b.kind === vocabulary().default_kind) - (a.kind === vocabulary().default_kind))
        .map((k) => h("option", { value: k.kind }, k.kind === vocabulary().default_kind ? `${k.label} (default)` : k.label)),
    ),
    metric: h("select", {}, [h("option", { value: "" }, "default (dtw where it applies)"), ...["dtw", "euclidean", "softdtw"].map((m) => h("option", { value: m }, m))]),
    n_realisations: h("input", { value: "", size: 6, placeholder: "default" }),
    seed: h("input", { value: 0, size: 8 }),
    time_limit_s: timeLimitBox(),
  };
  // The core's hand-designed baseline for the chosen scenario's thrusters (a baseline
  // the thrusters do not allow comes as {unavailable: why}: the field is left alone).
  // It lands only if the box is untouched since it was asked for, and only the latest
  // ask lands: a slow answer used to overwrite what the user had typed meanwhile, or
  // land in the middle of it (broken JSON, and the job was never sent).
  let asked = 0;
  let typed = false;
  train.sequence.addEventListener("input", () => {
    typed = true;
  });
  const defaultSequence = async () => {
    const scenario = byId[train.scenario.value];
    if (!scenario || query.sequence) return;
    const mine = ++asked;
    const baselines = await api.baselines(scenario.id, 4).catch(() => null);
    const hand = baselines && baselines["hand-designed"];
    if (Array.isArray(hand) && !query.sequence && !typed && mine === asked) train.sequence.value = JSON.stringify(hand);
  };
  train.sequence.value = query.sequence || "";
  // Another scenario is a new start: its default replaces the box, typed or not (the
  // thrusters, so the sequence's columns, may differ).
  train.scenario.addEventListener("change", () => {
    query.sequence = "";
    typed = false;
    defaultSequence();
  });
  defaultSequence();
  const trainBody = () => ({
    type: "train",
    scenario_id: train.scenario.value,
    seed: intOrText(train.seed.value),
    params: {
      sequence: jsonBox(train.sequence, "sequence", ["body", "params", "sequence"]),
      kind: train.kind.value,
      ...(train.metric.value ? { metric: train.metric.value } : {}),
      ...(train.n_realisations.value.trim() ? { n_realisations: intOrText(train.n_realisations.value) } : {}),
      ...timeLimit(train.time_limit_s),
    },
  });

  // Sweep.
  const sweep = {
    scenario: scenarioSelect(),
    classifier: h("select", {}),
    multiples: h("input", { value: vocabulary().default_multiples.join(", "), size: 30 }),
    noises: Object.fromEntries(vocabulary().noises.map(({ noise }) => [noise, h("input", { type: "checkbox", id: `sweep-noise-${noise}`, checked: vocabulary().default_noises.includes(noise) })])),
    others: Object.fromEntries(OTHERS.map(([spec]) => [spec, h("input", { type: "checkbox", id: `sweep-other-${spec.replace(":", "-")}`, checked: spec === "least-squares" })])),
    limit: h("input", { type: "checkbox", id: "sweep-limit", checked: true }),
    inertia: h("input", { type: "checkbox", id: "sweep-inertia", checked: true }),
    n_train: h("input", { value: 20, size: 6 }),
    n_test: h("input", { value: 200, size: 8 }),
    seed: h("input", { value: 0, size: 8 }),
    time_limit_s: timeLimitBox(),
  };
  const fillClassifiers = () => {
    clear(sweep.classifier);
    const mine = classifiers.filter((c) => c.scenario_id === sweep.scenario.value);
    if (unknownClassifier && mine.length) sweep.classifier.append(choose("classifier"));
    for (const c of mine) {
      sweep.classifier.append(h("option", { value: c.id, selected: c.id === query.classifier }, `${c.job_name ? `${c.job_name}: ` : ""}${c.kind} ${c.metric}, F1 ${c.f1.toFixed(3)} (${c.id.slice(0, 8)})`));
    }
    if (!mine.length) sweep.classifier.append(h("option", { value: "" }, "no classifier for this scenario: train one first"));
  };
  const preselected = classifiers.find((c) => c.id === query.classifier);
  if (preselected) sweep.scenario.value = preselected.scenario_id;
  sweep.scenario.addEventListener("change", fillClassifiers);
  fillClassifiers();
  const sweepBody = () => ({
    type: "sweep",
    scenario_id: sweep.scenario.value,
    seed: intOrText(sweep.seed.value),
    params: {
      classifier_id: sweep.classifier.value,
      multiples: sweep.multiples.value
        .split(/[,\s]+/)
        .filter((v) => v)
        .map(numberOrText),
      noises: vocabulary().noises.map(({ noise }) => noise).filter((n) => sweep.noises[n].checked),
      others: OTHERS.map(([spec]) => spec).filter((spec) => sweep.others[spec].checked),
      n_train: intOrText(sweep.n_train.value),
      inertia: sweep.inertia.checked,
      ...(sweep.limit.checked ? {} : { ceiling_realisations: 0 }),
      n_test: intOrText(sweep.n_test.value),
      ...timeLimit(sweep.time_limit_s),
    },
  });

  const panels = {
    search: [
      h(
        "div",
        { class: "stack" },
        field("search-scenario", "scenario", search.scenario),
        field("search-method", "method", search.method, "PPO learns (the paper's); CEM refines a distribution over levels; random is the baseline; exhaustive enumerates short sequences; nsga2 finds a Pareto front of the operator objectives"),
        field("search-objective", "objective", search.objective, "what scores a sequence"),
        field("search-sequence_length", "sequence length", search.sequence_length, "steps"),
        field("search-timesteps", "budget", search.timesteps, "environment steps (ppo, cem, random; nsga2's budget is its settings' population and generations, exhaustive scores every sequence: leave it at its default for them)"),
        field("search-n_realisations", "realisations", search.n_realisations, "per candidate"),
        field("search-metric", "clustering metric", search.metric),
        field("search-patience_episodes", "patience", search.patience_episodes, "episodes without improvement after F1 = 1 before stopping"),
        field("search-fuel_weight", "fuel weight", search.fuel_weight, "reward per N m s of impulse"),
        field("search-ppo", "PPO overrides", search.ppo, 'JSON, e.g. {"n_steps": 256, "batch_size": 64} (method ppo)'),
        field("search-nsga2", "NSGA-II settings", search.nsga2, `JSON overrides (method nsga2); defaults ${JSON.stringify(vocabulary().nsga2_defaults)}`),
        field("search-objectives", "operator objectives", search.objectives, "what the Pareto front trades off (nsga2), and what every best sequence is judged on"),
        field("search-design_noise", "design noise", search.design_noise, "[process multiple, gyro multiple] pairs at which accuracy is predicted (their mean)"),
        field("search-constraints", "constraints", search.constraints, `name=bound, comma-separated: ${vocabulary().constraints.map((c) => c.name).join(", ")}`),
        field("search-seed", "seed", search.seed),
        field("search-time_limit_s", "time limit (s)", search.time_limit_s, TIME_LIMIT_HINT),
      ),
      searchBody,
      { ...search, scenario_id: search.scenario },
    ],
    train: [
      h(
        "div",
        { class: "stack" },
        field("train-scenario", "scenario", train.scenario),
        field("train-sequence", "sequence", train.sequence, "JSON rows of level indices, one per step"),
        field("train-kind", "classifier", train.kind),
        field("train-metric", "metric", train.metric, `${vocabulary().classifier_kinds.filter((k) => k.metrics.length).map((k) => k.kind).join(", ")} only`),
        field("train-n_realisations", "realisations", train.n_realisations, `per candidate (default: ${vocabulary().classifier_kinds.map((k) => `${k.kind} ${k.default_realisations}`).join(", ")})`),
        field("train-seed", "seed", train.seed),
        field("train-time_limit_s", "time limit (s)", train.time_limit_s, TIME_LIMIT_HINT),
      ),
      trainBody,
      { ...train, scenario_id: train.scenario },
    ],
    sweep: [
      h(
        "div",
        { class: "stack" },
        field("sweep-scenario", "scenario", sweep.scenario),
        field("sweep-classifier", "classifier", sweep.classifier),
        field("sweep-multiples", "noise multiples", sweep.multiples, "× the scenario's 1× level"),
        [h("span", {}, "sources of error"), h("div", {}, vocabulary().noises.map(({ noise, label }) => h("label", { class: "check" }, sweep.noises[noise], ` ${label}`)))],
        [h("span", {}, "beside it"), h("div", {}, OTHERS.map(([spec, label]) => h("label", { class: "check" }, sweep.others[spec], ` ${label}`)))],
        field("sweep-n_train", "their training", sweep.n_train, "realisations per candidate"),
        [h("span", {}, "the ceiling"), h("label", { class: "check" }, sweep.limit, " draw the ceiling: per-candidate Gaussians fitted at each noise level (2,000 realisations per candidate; a few seconds a point)")],
        [h("span", {}, "off the candidates"), h("label", { class: "check" }, sweep.inertia, " also test scaled and in-between bodies: is the answer \"matches none\"?")],
        field("sweep-n_test", "test series", sweep.n_test, "per point, over all candidates"),
        field("sweep-seed", "seed", sweep.seed),
        field("sweep-time_limit_s", "time limit (s)", sweep.time_limit_s, TIME_LIMIT_HINT),
      ),
      sweepBody,
      { ...sweep, ...sweep.noises, ...sweep.others, classifier_id: sweep.classifier },
    ],
  };

  const labels = {
    name: h("input", { id: "job-name-new", size: 40, placeholder: "optional: a name for this run" }),
    tags: h("input", { id: "job-tags-new", size: 30, placeholder: "optional: tags, comma separated" }),
  };
  const labelFields = h("div", { class: "stack" }, field("job-name-new", "name", labels.name, "for you; not part of the job's identity"), field("job-tags-new", "tags", labels.tags, "to filter and compare runs"));
  const withLabels = (body) => {
    const name = labels.name.value.trim();
    const tags = parseTags(labels.tags.value);
    return { ...body, ...(name ? { name } : {}), ...(tags.length ? { tags } : {}) };
  };

  let current = ["search", "train", "sweep"].includes(query.type) ? query.type : "search";
  const holder = h("div", { role: "tabpanel", id: "job-form-panel" });
  const tabs = h("div", { class: "tabs", role: "tablist", "aria-label": "job type" });
  const submit = h("button", { type: "submit", id: "submit-job" }, "Submit");
  const names = Object.keys(panels);
  const pickTab = (name) => {
    current = name;
    show();
    tabs.querySelector(`#tab-${name}`).focus();
  };
  // The ARIA tabs pattern: one Tab stop for the list (the chosen tab), arrow keys, Home
  // and End move between tabs and choose them.
  const KEYS = { ArrowRight: 1, ArrowLeft: -1, Home: "first", End: "last" };
  tabs.addEventListener("keydown", (event) => {
    const move = KEYS[event.key];
    if (move === undefined) return;
    event.preventDefault();
    const at = names.indexOf(current);
    const to = move === "first" ? 0 : move === "last" ? names.length - 1 : (at + move + names.length) % names.length;
    pickTab(names[to]);
  });
  const show = () => {
    clear(tabs);
    for (const name of names) {
      const chosen = name === current;
      tabs.append(
        h(
          "button",
          { type: "button", role: "tab", id: `tab-${name}`, "aria-selected": String(chosen), "aria-controls": "job-form-panel", tabindex: chosen ? "0" : "-1", onclick: () => pickTab(name) },
          name,
        ),
      );
    }
    holder.setAttribute("aria-labelledby", `tab-${current}`);
    clear(holder);
    clear(general);
    holder.append(panels[current][0]);
    submit.textContent = `Submit ${current} job`;
  };
  show();
  const form = h(
    "form",
    {
      id: "job-form",
      onsubmit: async (event) => {
        event.preventDefault();
        const [, body, inputs] = panels[current];
        submit.disabled = true;
        try {
          await submitAndOpen(withLabels(body()));
        } catch (exc) {
          const fields = Object.fromEntries(Object.entries(inputs).filter(([, v]) => v instanceof Element));
          showFieldErrors(exc, { ...fields, name: labels.name, tags: labels.tags }, general, event.target);
        } finally {
          submit.disabled = false;
          // Disabled while it was sent, the button lost the focus to <body>.
          if (document.activeElement === document.body && submit.isConnected) submit.focus();
        }
      },
    },
    missingNote,
    tabs,
    holder,
    labelFields,
    general,
    h("div", { class: "toolbar" }, submit),
  );
  return form;
}

//: The job list's state by its name in the page's address.
const LIST_QUERY = { type: "list", q: "list_q", status: "list_status", stopped: "list_stopped", scenario_id: "list_scenario", tag: "list_tag", sort: "list_sort", order: "list_order", offset: "list_offset" };
const LIST_DEFAULTS = { sort: "created", order: "desc", offset: 0 };

export async function render(root, context) {
  const query = { ...context.query };
  const [scenarios, classifiers] = await Promise.all([api.scenarios(), api.classifiers()]);
  const names = Object.fromEntries(scenarios.items.map((s) => [s.id, s.name]));
  root.append(h("h1", {}, "Jobs"));
  if (!scenarios.items.length) {
    root.append(messageBox("notice", "No scenario yet: "), link("#/scenarios/new", "create one first"));
  } else {
    root.append(h("details", { class: "card", open: true, id: "submit-card" }, h("summary", {}, "Submit a job"), submitForm(scenarios.items, classifiers.items, query)));
  }

  const notice = h("div");
  const compareButton = h("a", { class: "button secondary", id: "compare-selected", href: "#/compare" }, "Compare selected");
  const typeFilter = ["search", "train", "sweep"].includes(query.list) ? query.list : "";
  // The list's filters, sort and page live in the address (list_status=failed, ...), so
  // a reload, Back from a job or a shared link shows the same list (they reset to page
  // 1, sorted by created, with no filter).
  const initial = { sort: "created", order: "desc", type: typeFilter };
  for (const [key, name] of Object.entries(LIST_QUERY)) {
    if (key !== "type" && query[name]) initial[key] = key === "offset" ? Math.max(0, Number.parseInt(query[name], 10) || 0) : query[name];
  }
  const keepInAddress = (state) => {
    const params = new URLSearchParams();
    for (const [name, value] of Object.entries(context.query)) if (!Object.values(LIST_QUERY).includes(name)) params.set(name, value);
    for (const [key, name] of Object.entries(LIST_QUERY)) {
      const value = state[key];
      if (value === "" || value === null || value === undefined || value === LIST_DEFAULTS[key]) continue;
      params.set(name, value);
    }
    const text = params.toString();
    history.replaceState(history.state, "", `#/jobs${text ? `?${text}` : ""}`);
  };
  const runs = dataTable({
    id: "jobs",
    load: (q) => api.jobs(q),
    initial,
    onState: keepInAddress,
    filters: [
      { name: "q", label: "search", type: "text", placeholder: "name, tag or id" },
      { name: "type", label: "type", options: [["", "all"], ...vocabulary().job_types.map((t) => [t, t])] },
      { name: "status", label: "status", options: [["", "any"], ...vocabulary().job_statuses.map((t) => [t, t])] },
      { name: "stopped", label: "stopped by", options: [["", "anything"], ...vocabulary().stopped_reasons.map((t) => [t, STOPPED_LABELS[t] || t])] },
      { name: "scenario_id", label: "scenario", options: [["", "any"], ...scenarios.items.map((s) => [s.id, s.name])] },
      { name: "tag", label: "tag", type: "text", size: 10 },
    ],
    select: {
      label: (job) => `select ${job.id} for comparison`,
      enabled: (job) => job.type !== "train",
      onChange: (ids) => compareButton.setAttribute("href", `#/compare?ids=${ids.join(",")}`),
    },
    empty: "no jobs match",
    rowAttrs: (job) => ({ dataset: { id: job.id, jobId: job.id, status: job.status } }),
    columns: (state) => [
      { key: "run", label: "run", sort: "name", cell: jobCell },
      { key: "type", label: "type", sort: "type", cell: (job) => job.type },
      { key: "status", label: "status", sort: "status", cell: (job) => [statusBadge(job.status), stoppedNote(job), progressBar(job.progress, job.status)] },
      { key: "scenario", label: "scenario", cell: (job) => link(`#/scenarios/${job.scenario_id}`, names[job.scenario_id] || job.scenario_id.slice(0, 8)) },
      ...(state.type ? summaryTableColumns(state.type) : [{ key: "headline", label: "result", cell: headline }]),
      { key: "created", label: "created", sort: "created", cell: (job) => when(job.created_at) },
      { key: "timing", label: "queue · run", cell: timingCell },
      { key: "actions", label: "", cell: (job) => cancelButton(job, notice, () => runs.refresh({ user: true })) },
    ],
  });
  root.append(
    h(
      "div",
      { class: "card" },
      h("div", { class: "toolbar" }, h("h2", { style: "margin: 0" }, "Runs"), compareButton, h("span", { class: "hint" }, "tick searches or sweeps to compare them; choose a type to see and sort by its figures")),
      notice,
      runs.node,
    ),
  );
  await runs.refresh();
  context.every(POLL_MS, runs.refresh);
}
