// Jobs: submit a search, a training or a sweep, and a live list (status, progress,
// duration) refreshed every two seconds without reloading the page.

import { api } from "../api.js";
import { isTerminal, otherSpecs, vocabulary } from "../vocabulary.js";
import {
  clear,
  duration,
  h,
  link,
  messageBox,
  progressBar,
  showFieldErrors,
  statusBadge,
  when,
} from "../ui.js";

const POLL_MS = 2000;

// The value as the service should see it: an integer or number when it parses as one,
// else the text itself, so that the service's message quotes what was typed.
function intOrText(text) {
  const trimmed = String(text).trim();
  return /^[+-]?\d+$/.test(trimmed) ? Number(trimmed) : trimmed;
}

function jsonOrText(text) {
  try {
    return JSON.parse(text);
  } catch {
    return text;
  }
}

export async function cancelJob(job, notice) {
  try {
    await api.cancelJob(job.id);
  } catch (exc) {
    clear(notice);
    notice.append(messageBox("error", exc.message));
  }
}

function field(id, label, input, hint = "") {
  input.id = id;
  return [h("label", { for: id }, label), h("div", {}, input, hint ? h("span", { class: "hint" }, ` ${hint}`) : null)];
}

function submitForm(scenarios, classifiers, query) {
  const OTHERS = otherSpecs();
  const general = h("div");
  const scenarioSelect = () => {
    const select = h(
      "select",
      {},
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
    seed: h("input", { value: 0, size: 8 }),
  };
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
      fuel_weight: Number.isFinite(Number(search.fuel_weight.value)) ? Number(search.fuel_weight.value) : search.fuel_weight.value,
      ...(search.method.value === "ppo" ? { ppo: jsonOrText(search.ppo.value) } : {}),
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
  };
  // The core's hand-designed baseline for the chosen scenario's thrusters.
  const defaultSequence = async () => {
    const scenario = byId[train.scenario.value];
    if (!scenario || query.sequence) return;
    const baselines = await api.baselines(scenario.id, 4).catch(() => null);
    if (baselines && !query.sequence) train.sequence.value = JSON.stringify(baselines["hand-designed"]);
  };
  train.sequence.value = query.sequence || "";
  train.scenario.addEventListener("change", () => {
    query.sequence = "";
    defaultSequence();
  });
  defaultSequence();
  const trainBody = () => ({
    type: "train",
    scenario_id: train.scenario.value,
    seed: intOrText(train.seed.value),
    params: {
      sequence: jsonOrText(train.sequence.value),
      kind: train.kind.value,
      ...(train.metric.value ? { metric: train.metric.value } : {}),
      ...(train.n_realisations.value.trim() ? { n_realisations: intOrText(train.n_realisations.value) } : {}),
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
  };
  const fillClassifiers = () => {
    clear(sweep.classifier);
    const mine = classifiers.filter((c) => c.scenario_id === sweep.scenario.value);
    for (const c of mine) {
      sweep.classifier.append(h("option", { value: c.id, selected: c.id === query.classifier }, `${c.metric}, F1 ${c.f1.toFixed(3)} (${c.id.slice(0, 8)})`));
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
        .map((v) => (Number.isFinite(Number(v)) ? Number(v) : v)),
      noises: vocabulary().noises.map(({ noise }) => noise).filter((n) => sweep.noises[n].checked),
      others: OTHERS.map(([spec]) => spec).filter((spec) => sweep.others[spec].checked),
      n_train: intOrText(sweep.n_train.value),
      inertia: sweep.inertia.checked,
      limit_realisations: sweep.limit.checked ? 200 : 0,
      n_test: intOrText(sweep.n_test.value),
    },
  });

  const panels = {
    search: [
      h(
        "div",
        { class: "stack" },
        field("search-scenario", "scenario", search.scenario),
        field("search-method", "method", search.method, "PPO learns (the paper's); CEM refines a distribution over levels; random is the baseline; exhaustive enumerates short sequences"),
        field("search-objective", "objective", search.objective, "what scores a sequence"),
        field("search-sequence_length", "sequence length", search.sequence_length, "steps"),
        field("search-timesteps", "budget", search.timesteps, "environment steps (ppo, random)"),
        field("search-n_realisations", "realisations", search.n_realisations, "per candidate"),
        field("search-metric", "clustering metric", search.metric),
        field("search-patience_episodes", "patience", search.patience_episodes, "episodes without improvement after F1 = 1 before stopping"),
        field("search-fuel_weight", "fuel weight", search.fuel_weight, "reward per N m s of impulse"),
        field("search-ppo", "PPO overrides", search.ppo, 'JSON, e.g. {"n_steps": 256, "batch_size": 64} (method ppo)'),
        field("search-seed", "seed", search.seed),
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
        [h("span", {}, "the limit"), h("label", { class: "check" }, sweep.limit, " draw the limit: a likelihood classifier fitted at each noise level (200 realisations per candidate)")],
        [h("span", {}, "off the candidates"), h("label", { class: "check" }, sweep.inertia, " also test scaled and in-between bodies: is the answer \"matches none\"?")],
        field("sweep-n_test", "test series", sweep.n_test, "per point, over all candidates"),
        field("sweep-seed", "seed", sweep.seed),
      ),
      sweepBody,
      { ...sweep, ...sweep.noises, ...sweep.others, classifier_id: sweep.classifier },
    ],
  };

  let current = ["search", "train", "sweep"].includes(query.type) ? query.type : "search";
  const holder = h("div");
  const tabs = h("div", { class: "tabs", role: "tablist" });
  const submit = h("button", { type: "submit", id: "submit-job" }, "Submit");
  const show = () => {
    clear(tabs);
    for (const name of Object.keys(panels)) {
      tabs.append(
        h(
          "button",
          { type: "button", role: "tab", id: `tab-${name}`, "aria-selected": String(name === current), onclick: () => { current = name; show(); } },
          name,
        ),
      );
    }
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
          const job = await api.submitJob(body());
          location.hash = `#/jobs/${job.id}`;
        } catch (exc) {
          const fields = Object.fromEntries(Object.entries(inputs).filter(([, v]) => v instanceof Element));
          showFieldErrors(exc, fields, general);
        } finally {
          submit.disabled = false;
        }
      },
    },
    tabs,
    holder,
    general,
    h("div", { class: "toolbar" }, submit),
  );
  return form;
}

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

  const selected = new Set();
  const compareButton = h("button", { type: "button", class: "secondary", id: "compare-selected", disabled: true, onclick: () => { location.hash = `#/compare?jobs=${[...selected].join(",")}`; } }, "Compare selected searches");
  const filter = h("select", { id: "job-filter", "aria-label": "show jobs of type" }, ["all", "search", "train", "sweep"].map((t) => h("option", { value: t }, t)));
  const notice = h("div");
  const body = h("tbody", { id: "job-rows" });
  const count = h("span", { class: "muted", id: "job-count" });
  root.append(
    h(
      "div",
      { class: "card" },
      h("div", { class: "toolbar" }, h("h2", { style: "margin: 0" }, "All jobs"), h("label", { for: "job-filter" }, "type"), filter, compareButton, count),
      notice,
      h(
        "table",
        { id: "job-table" },
        h("thead", {}, h("tr", {}, ["", "job", "type", "status", "progress", "scenario", "created", "duration", ""].map((n) => h("th", {}, n)))),
        body,
      ),
    ),
  );

  const refresh = async () => {
    const page = await api.jobs(filter.value === "all" ? {} : { type: filter.value });
    if (!context.alive()) return;
    clear(body);
    count.textContent = `${page.items.length} of ${page.total}`;
    for (const job of page.items) {
      const check =
        job.type === "search"
          ? h("input", {
              type: "checkbox",
              "aria-label": `select ${job.id} for comparison`,
              checked: selected.has(job.id),
              onchange: (event) => {
                if (event.target.checked) selected.add(job.id);
                else selected.delete(job.id);
                compareButton.disabled = selected.size < 1;
              },
            })
          : "";
      const cancel = isTerminal(job.status)
        ? ""
        : h("button", { type: "button", class: "danger", disabled: job.cancel_requested, onclick: () => cancelJob(job, notice).then(refresh) }, job.cancel_requested ? "cancelling" : "cancel");
      body.append(
        h(
          "tr",
          { dataset: { jobId: job.id, status: job.status } },
          h("td", {}, check),
          h("td", {}, link(`#/jobs/${job.id}`, job.id.slice(0, 8), { title: job.id })),
          h("td", {}, job.type, h("span", { class: "hint" }, ` ${job.type === "search" ? job.params.method : job.type === "train" ? job.params.kind || "" : ""}`)),
          h("td", {}, statusBadge(job.status)),
          h("td", {}, progressBar(job.progress, job.status)),
          h("td", {}, link(`#/scenarios/${job.scenario_id}`, names[job.scenario_id] || job.scenario_id.slice(0, 8))),
          h("td", {}, when(job.created_at)),
          h("td", {}, duration(job.started_at, job.finished_at)),
          h("td", {}, cancel),
        ),
      );
    }
    if (!page.items.length) body.append(h("tr", {}, h("td", { colspan: 9, class: "muted" }, "no jobs yet")));
  };
  filter.addEventListener("change", refresh);
  await refresh();
  context.every(POLL_MS, refresh);
}
