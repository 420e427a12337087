// The service's HTTP API, as the dashboard uses it. Every call goes through `request`,
// which adds the API key (kept in the browser's localStorage) and turns an error answer
// into an ApiError carrying the server's messages, so pages can show them next to fields.

const KEY_STORAGE = "inertia-id-api-key";

export function getApiKey() {
  return localStorage.getItem(KEY_STORAGE) || "";
}

// Where a browser user finds the key, for every message that asks for it.
export const KEY_HINT = 'enter the API key (printed by "inertia-id serve" on its first run) at the top right';

export function setApiKey(key) {
  if (key) localStorage.setItem(KEY_STORAGE, key.trim());
  else localStorage.removeItem(KEY_STORAGE);
  window.dispatchEvent(new CustomEvent("api-key-changed"));
}

// A key saved or removed in another tab of the dashboard: this tab's key box and the
// sections waiting for a key follow it. The browser fires "storage" only in the other
// documents of the origin (a null key: the storage was cleared).
window.addEventListener("storage", (event) => {
  if (event.key === KEY_STORAGE || event.key === null) {
    window.dispatchEvent(new CustomEvent("api-key-changed"));
  }
});

export class ApiError extends Error {
  // status: the HTTP status (0 when the server could not be reached);
  // errors: [{loc: [...], msg}] as the service's 422 answers carry them.
  constructor(status, message, errors = []) {
    super(message);
    this.name = "ApiError";
    this.status = status;
    this.errors = errors;
  }
}

function errorFrom(status, body) {
  const detail = body && body.detail;
  if (Array.isArray(detail)) {
    const errors = detail.map((e) => ({ loc: e.loc || [], msg: String(e.msg || "") }));
    return new ApiError(status, errors.map((e) => e.msg).join("; "), errors);
  }
  if (typeof detail === "string") return new ApiError(status, detail, [{ loc: [], msg: detail }]);
  return new ApiError(status, `the service answered ${status}`);
}

// A POST that stores a row (a job, a scenario) carries an Idempotency-Key made for it.
// When its answer is lost (the connection dropped, so the page cannot tell whether the
// service stored it) it is sent again with the same key, and the service answers what
// it did the first time instead of storing a second; a 409 with Retry-After (the first
// is still being answered) is asked again after that wait (at most 10 s, and up to a
// quarter more). A 502, 503 or 504 (a proxy that lost the service, or the service's own
// "try again") is sent again too, the key making it safe: after 0.5, 1 and 2 s, each
// wait drawn between half and all of that so that pages refused together do not come
// back together, or after the answer's Retry-After as a 409's (up to a quarter more);
// one asking more than 10 s is shown at once.
// Tries of a request whose answer was lost, and of one answered 409 (each its own count).
const IDEMPOTENT_TRIES = 3;
// The longest Retry-After the page waits, a 409's or a 503's. The service asks a 409 for
// 1 s while the request holding the key is young, then a fifth of its age, at most 10 s
// (RETRY_AFTER_MAX in app/api/idempotency.py); a 503 for 1 or 2 s past its capacity, 5 s
// while the database cannot be reached or the service stops, the compute queue's wait
// (INERTIA_ID_COMPUTE_WAIT_S, 10 s by default) when no thread came free in it. Capped at
// 5 s before, a 409 asking 10 s was sent again after 5, and a 503 asking 10 s (the queue
// still full) after 5 to 7.5 s, to be refused again while its tries ran out. A 409 asking
// more (never the service's) is still asked again after 10 s.
const RETRY_AFTER_MAX_S = 10;
// Tries of one answered 502, 503 or 504 (a count of its own).
const GATEWAY_TRIES = 4;
const RETRIED_STATUSES = new Set([502, 503, 504]);

function newIdempotencyKey() {
  // crypto.randomUUID exists in secure contexts only (https, localhost); a dashboard
  // served over plain http on another host has getRandomValues still.
  if (crypto.randomUUID) return crypto.randomUUID();
  return Array.from(crypto.getRandomValues(new Uint8Array(16)), (b) => b.toString(16).padStart(2, "0")).join("");
}

const pause = (ms) => new Promise((resolve) => setTimeout(resolve, ms));

export async function request(method, path, { json, form, query, key = null, raw = false, idempotent = false } = {}) {
  const headers = { Accept: raw ? "*/*" : "application/json" };
  if (idempotent) headers["Idempotency-Key"] = newIdempotencyKey();
  const sent = key ?? getApiKey();
  if (sent) headers["X-API-Key"] = sent;
  else if (method !== "GET") {
    // Every write needs the key (the service always has one: generated on its first
    // run, or INERTIA_ID_API_KEY): without one the request would be a 401, which the
    // browser logs as a console error. Refused here, nothing sent, with the same words
    // and hint as the service's 401 would carry, wherever the page shows the error.
    const message = `missing API key (nothing was sent): ${KEY_HINT}`;
    throw new ApiError(401, message, [{ loc: [], msg: message }]);
  }
  let body;
  if (json !== undefined) {
    headers["Content-Type"] = "application/json";
    body = JSON.stringify(json);
  } else if (form !== undefined) {
    body = form;
  }
  let url = path;
  if (query) {
    const params = new URLSearchParams();
    for (const [name, value] of Object.entries(query)) {
      if (value !== undefined && value !== null && value !== "") params.set(name, value);
    }
    const text = params.toString();
    if (text) url += `?${text}`;
  }
  let response;
  // Each kind of failure has its own budget: a 504 does not spend a 409's tries (after a
  // 504 and a 409, a third answer 409 was shown as "still in progress" though a 409 had
  // been retried once), and all of them together stay bounded.
  const tries = { lost: 0, gateway: 0, conflict: 0 };
  for (;;) {
    try {
      response = await fetch(url, { method, headers, body });
    } catch (exc) {
      tries.lost += 1;
      if (idempotent && tries.lost < IDEMPOTENT_TRIES) {
        await pause(500 * tries.lost);
        continue;
      }
      throw new ApiError(0, `the service at ${location.origin} could not be reached (${exc.message})`);
    }
    const retryAfter = Number(response.headers.get("Retry-After"));
    if (idempotent && RETRIED_STATUSES.has(response.status)) {
      tries.gateway += 1;
      // A 503 asking more than the page waits is one an operator must end (30 s: the
      // database's disk is full, or it takes no writes): its message is shown at once,
      // where sending it again at 10 s had the page spin 30 to 37 s to show the same.
      if (tries.gateway >= GATEWAY_TRIES || retryAfter > RETRY_AFTER_MAX_S) break;
      // A Retry-After is a floor (the service asked for that wait): the jitter goes above
      // it, never below (drawn between half and all, a "Retry-After: 2" was retried in 1 s),
      // and is a quarter as a 409's.
      const wait =
        retryAfter > 0
          ? 1000 * retryAfter * (1 + Math.random() / 4)
          : 500 * 2 ** (tries.gateway - 1) * (0.5 + Math.random() / 2);
      await pause(wait);
      continue;
    }
    if (!(idempotent && response.status === 409 && retryAfter > 0)) break;
    tries.conflict += 1;
    if (tries.conflict >= IDEMPOTENT_TRIES) break;
    // The Retry-After in full (a floor, as a 503's), and a jitter of up to a quarter more
    // above it: the requests a held lock (SQLite's write lock) kept waiting are answered
    // 409 together, with the same Retry-After, and without it they would all come back in
    // the same instant and meet the lock together again. A quarter, so that the 10 s
    // bound's wait stays near the 10 s the service means.
    await pause(1000 * Math.min(retryAfter, RETRY_AFTER_MAX_S) * (1 + Math.random() / 4));
  }
  if (response.status === 204) return null;
  let data = null;
  const type = response.headers.get("content-type") || "";
  if (raw && response.ok) return response.blob();
  if (type.includes("json")) data = await response.json();
  if (!response.ok) {
    const error = errorFrom(response.status, data);
    if (response.status === 401 && key === null) {
      // A browser user cannot "send a header": every place that shows the error (a
      // form's field messages too) says what to do, and a saved key the service refuses
      // is marked in the key box instead of still reading "saved".
      const hint = sent
        ? "the saved API key was refused (a new key?): enter the current one at the top right"
        : KEY_HINT;
      error.message = `${error.message}: ${hint}`;
      error.errors = error.errors.length ? error.errors.map((e) => ({ ...e, msg: `${e.msg}: ${hint}` })) : [{ loc: [], msg: error.message }];
      if (sent) window.dispatchEvent(new CustomEvent("api-key-rejected"));
    }
    throw error;
  }
  return data;
}

function identifyForm(classifierId, file, { confidence, averaged } = {}) {
  const form = new FormData();
  form.set("classifier_id", classifierId);
  if (confidence !== undefined && confidence !== null && confidence !== "") form.set("confidence", String(confidence));
  // An integrating (delta-angle) gyro: each rate the mean over the interval before its stamp.
  if (averaged) form.set("averaged", "true");
  form.set("file", file);
  return form;
}

// The start search: /identify only (/identify/partial refuses it).
function withStartSearch(form, { startWithin } = {}) {
  if (startWithin !== undefined && startWithin !== null && startWithin !== "") form.set("estimate_start_within_s", String(startWithin));
  return form;
}

export const api = {
  health: () => request("GET", "/health"),
  // 204 (null) when the service accepts `key`; an ApiError 401 when it does not.
  checkKey: (key) => request("GET", "/auth/check", { key }),
  vocabulary: () => request("GET", "/vocabulary"),
  presets: () => request("GET", "/scenarios/presets"),
  baselines: (id, length) =>
    request("GET", `/scenarios/${encodeURIComponent(id)}/baselines`, { query: { length } }),
  scenarios: (query) => request("GET", "/scenarios", { query: { limit: 200, ...query } }),
  scenario: (id) => request("GET", `/scenarios/${encodeURIComponent(id)}`),
  createScenario: (body) => request("POST", "/scenarios", { json: body, idempotent: true }),
  deleteScenario: (id) => request("DELETE", `/scenarios/${encodeURIComponent(id)}`),
  response: (id, sequence, query = {}) =>
    request("GET", `/scenarios/${encodeURIComponent(id)}/response`, {
      query: { sequence: JSON.stringify(sequence), ...query },
    }),
  // Listed jobs carry their summary, not their result (`include: "result"` asks for it).
  jobs: (query) => request("GET", "/jobs", { query: { limit: 100, ...query } }),
  job: (id) => request("GET", `/jobs/${encodeURIComponent(id)}`),
  submitJob: (body) => request("POST", "/jobs", { json: body, idempotent: true }),
  updateJob: (id, labels) => request("PATCH", `/jobs/${encodeURIComponent(id)}`, { json: labels }),
  cancelJob: (id) => request("POST", `/jobs/${encodeURIComponent(id)}/cancel`),
  metrics: (id, query) => request("GET", `/jobs/${encodeURIComponent(id)}/metrics`, { query }),
  classifiers: (query) => request("GET", "/classifiers", { query: { limit: 200, ...query } }),
  classifier: (id) => request("GET", `/classifiers/${encodeURIComponent(id)}`),
  calibration: (id) => request("GET", `/classifiers/${encodeURIComponent(id)}/calibration`),
  // `options`: confidence (what naming a candidate takes, default the service's 0.99) and
  // sequenceStart (seconds in the telemetry's clock or ISO-8601 UTC), both optional.
  identify: (classifierId, file, format = "json", options = {}) =>
    request("POST", "/identify", {
      form: withStartSearch(identifyForm(classifierId, file, options), options),
      query: { format: format === "json" ? undefined : format, sequence_start: options.sequenceStart },
      raw: format !== "json",
    }),
  // The posterior over time from the same body; 422 for a kind without a Gaussian model.
  identifyPartial: (classifierId, file, options = {}) =>
    request("POST", "/identify/partial", { form: identifyForm(classifierId, file, options), query: { sequence_start: options.sequenceStart } }),
};

// Follows a job's metric series incrementally: each poll asks only for points after the
// last step it holds (`?after=`), so a long PPO curve is never fetched twice.
export class MetricFollower {
  constructor(jobId) {
    this.jobId = jobId;
    this.after = {};
  }

  // Returns {key: {steps, values}} holding only the new points since the last call.
  async poll() {
    const out = {};
    const keys = Object.keys(this.after);
    if (keys.length === 0) {
      const data = await api.metrics(this.jobId);
      for (const series of data.series) this.take(out, series);
      return out;
    }
    const data = await api.metrics(this.jobId, { after: Math.min(...Object.values(this.after)) });
    for (const series of data.series) this.take(out, series);
    return out;
  }

  take(out, series) {
    const after = this.after[series.key];
    const steps = [];
    const values = [];
    series.steps.forEach((step, i) => {
      if (after === undefined || step > after) {
        steps.push(step);
        values.push(series.values[i]);
      }
    });
    if (series.last_step !== null && series.last_step !== undefined) {
      this.after[series.key] = Math.max(after ?? -Infinity, series.last_step);
    }
    if (steps.length) out[series.key] = { steps, values };
  }
}
