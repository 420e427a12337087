// Classifiers: a sorted, filtered, paged list with their training scores and the
// training run's name and tags; one classifier's page (views/classifier.js).

import { api } from "../api.js";
import { dataTable } from "../components/table.js";
import { vocabulary } from "../vocabulary.js";
import { h, link, score, sequenceText, tagChips, when } from "../ui.js";
import { renderClassifier } from "../views/classifier.js";

export async function renderList(root) {
  root.append(h("h1", {}, "Classifiers"));
  const scenarios = await api.scenarios();
  const names = Object.fromEntries(scenarios.items.map((s) => [s.id, s.name]));
  const compare = h("a", { class: "button secondary", id: "compare-classifiers", href: "#/compare?type=classifier" }, "Compare selected");
  const table = dataTable({
    id: "classifier-list",
    load: (query) => api.classifiers(query),
    initial: { sort: "created", order: "desc" },
    filters: [
      { name: "q", label: "search", type: "text", placeholder: "name, tag, kind, id" },
      { name: "kind", label: "kind", options: [["", "any"], ...vocabulary().classifier_kinds.map((k) => [k.kind, k.label])] },
      { name: "scenario_id", label: "scenario", options: [["", "any"], ...scenarios.items.map((s) => [s.id, s.name])] },
    ],
    select: {
      label: (c) => `select classifier ${c.id} to compare`,
      onChange: (ids) => compare.setAttribute("href", `#/compare?type=classifier&ids=${ids.join(",")}`),
    },
    empty: "No classifier yet: submit a train job on the Jobs page.",
    columns: [
      { key: "classifier", label: "classifier", sort: "name", cell: (c) => [link(`#/classifiers/${c.id}`, c.job_name || c.id.slice(0, 8), { title: c.id }), " ", tagChips(c.tags)] },
      { key: "kind", label: "kind", sort: "kind", cell: (c) => `${c.kind}${c.metric && c.metric !== c.kind ? ` · ${c.metric}` : ""}` },
      { key: "scenario", label: "scenario", cell: (c) => link(`#/scenarios/${c.scenario_id}`, names[c.scenario_id] || c.scenario_id.slice(0, 8)) },
      { key: "f1", label: "training F1", sort: "f1", num: true, cell: (c) => score(c.f1) },
      { key: "accuracy", label: "training accuracy", sort: "accuracy", num: true, cell: (c) => score(c.accuracy) },
      { key: "sequence", label: "sequence", cell: (c) => h("span", { class: "mono" }, sequenceText(c.sequence)) },
      { key: "created", label: "created", sort: "created", cell: (c) => when(c.created_at) },
      { key: "actions", label: "", cell: (c) => link(`#/identify?classifier=${c.id}`, "identify") },
    ],
  });
  root.append(h("div", { class: "card" }, h("div", { class: "toolbar" }, compare, h("span", { class: "hint" }, "tick classifiers to draw their sweeps' accuracy curves on one plot")), table.node));
  await table.refresh();
}

export async function renderOne(root, context) {
  const classifier = await api.classifier(context.params[0]);
  root.append(h("h1", {}, "Classifier ", classifier.job_name ? `${classifier.job_name} ` : "", h("code", {}, classifier.id.slice(0, 8))));
  await renderClassifier(root, classifier, context, context.query.sweep);
}
