// The domain's words as the service defines them (GET /vocabulary): classifier kinds and
// the metrics each takes, sources of error with labels and units, search methods and
// objectives, job statuses. Loaded once before the first page renders; pages ask here
// instead of keeping their own lists.

import { api } from "./api.js";

let words = null;

export async function loadVocabulary() {
  words = await api.vocabulary();
  return words;
}

export function vocabulary() {
  if (!words) throw new Error("the vocabulary is not loaded yet");
  return words;
}

export function isTerminal(status) {
  return vocabulary().terminal_statuses.includes(status);
}

export function kindInfo(kind) {
  return vocabulary().classifier_kinds.find((k) => k.kind === kind) || null;
}

// "1nn euclidean", "marginal-likelihood": a kind with its metric where it takes one.
export function classifierName(classifier) {
  const info = kindInfo(classifier.kind);
  return info && info.metrics.length ? `${classifier.kind} ${classifier.metric}` : classifier.kind;
}

export function noiseInfo(noise) {
  return vocabulary().noises.find((n) => n.noise === noise) || { noise, label: noise, unit: "", reference_level: null };
}

// Every classifier a sweep can draw beside the main one, as specs the service takes
// ("1nn:euclidean", "likelihood"), with labels.
export function otherSpecs() {
  const specs = [];
  for (const k of vocabulary().classifier_kinds) {
    if (k.metrics.length) k.metrics.forEach((m) => specs.push([`${k.kind}:${m}`, `${k.label}, ${m}`]));
    else specs.push([k.kind, k.label]);
  }
  return specs;
}
