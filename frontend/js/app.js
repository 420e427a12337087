// The dashboard's shell: hash routes to pages, the API key box and the health badge.
//
// A page is `render(root, context)`; `context.alive()` turns false once the user has
// navigated away (pages stop polling then), `context.every(ms, fn)` polls while alive,
// and `context.params` holds the route's parameters and query.

import { api, getApiKey, setApiKey } from "./api.js";
import { fitChartsToWidth } from "./components/plots.js";
import { h, messageBox } from "./ui.js";
import { loadVocabulary } from "./vocabulary.js";
// Pages never import each other: what two pages share lives in components/ and views/.
import * as classifiers from "./pages/classifiers.js";
import * as compare from "./pages/compare.js";
import * as identify from "./pages/identify.js";
import * as jobPage from "./pages/job.js";
import * as jobs from "./pages/jobs.js";
import * as scenarios from "./pages/scenarios.js";

const ROUTES = [
  [/^\/scenarios\/new$/, scenarios.renderNew, "scenarios"],
  [/^\/scenarios\/([^/]+)$/, scenarios.renderOne, "scenarios"],
  [/^\/scenarios$/, scenarios.renderList, "scenarios"],
  [/^\/jobs\/([^/]+)$/, jobPage.render, "jobs"],
  [/^\/jobs$/, jobs.render, "jobs"],
  [/^\/classifiers\/([^/]+)$/, classifiers.renderOne, "classifiers"],
  [/^\/classifiers$/, classifiers.renderList, "classifiers"],
  [/^\/compare$/, compare.render, "compare"],
  [/^\/identify$/, identify.render, "identify"],
];

let generation = 0;
let vocabularyLoad = null;

// The vocabulary, read once; a failed read is tried again at the next navigation rather
// than leaving every link dead until a reload.
function ensureVocabulary() {
  if (!vocabularyLoad) {
    vocabularyLoad = loadVocabulary().catch((exc) => {
      vocabularyLoad = null;
      throw exc;
    });
  }
  return vocabularyLoad;
}

function parseHash() {
  const hash = location.hash.replace(/^#/, "") || "/jobs";
  const [path, queryText = ""] = hash.split("?");
  return { path, query: Object.fromEntries(new URLSearchParams(queryText)) };
}

async function route() {
  const mine = ++generation;
  const { path, query } = parseHash();
  // Each visit draws into a container of its own: a page still awaiting the API when the
  // user moves on appends to its own container, now detached, and never under the next
  // page (it used to, buttons and all, after a slow response).
  const root = document.createElement("div");
  document.getElementById("page").replaceChildren(root);
  const timers = [];
  // A page that follows a running job says so when the service stops answering, instead
  // of showing "running" and figures that are no longer followed.
  const pollState = h("div", { id: "poll-state", role: "status" });
  root.append(pollState);
  let answered = new Date();
  const context = {
    query,
    alive: () => mine === generation,
    every(ms, fn) {
      let running = false;
      const tick = async () => {
        if (!context.alive() || running) return;
        running = true;
        try {
          await fn();
          answered = new Date();
          pollState.replaceChildren();
        } catch (exc) {
          console.warn("poll failed:", exc.message || exc);
          const since = answered.toISOString().slice(11, 19);
          pollState.replaceChildren(messageBox("error", `Not updated since ${since} UTC: ${exc.message || exc}. The page tries again every ${Math.round(ms / 1000)} s.`));
        } finally {
          running = false;
        }
      };
      timers.push(setInterval(tick, ms));
      return tick;
    },
  };
  window.addEventListener(
    "hashchange",
    () => timers.forEach((t) => clearInterval(t)),
    { once: true },
  );
  try {
    await ensureVocabulary();
  } catch (exc) {
    if (context.alive()) root.append(messageBox("error", `the service's vocabulary could not be read: ${exc.message}. Follow a link or reload the page to try again.`));
    return;
  }
  if (!context.alive()) return;
  for (const [pattern, render, nav] of ROUTES) {
    const match = path.match(pattern);
    if (!match) continue;
    for (const a of document.querySelectorAll("nav a")) {
      a.classList.toggle("active", a.dataset.nav === nav);
    }
    try {
      // A malformed escape (#/jobs/%) is no page, not an uncaught URIError.
      context.params = match.slice(1).map(decodeURIComponent);
    } catch {
      break;
    }
    try {
      await render(root, context);
    } catch (exc) {
      if (context.alive()) root.append(messageBox("error", exc.message || String(exc)));
    }
    return;
  }
  root.append(messageBox("error", `no page at #${path}`));
}

// The key is checked against the service (GET /auth/check) when it is entered, and kept
// only if it is accepted: a wrong key is refused there and then, never "saved".
function keyBox() {
  const form = document.getElementById("api-key-form");
  const input = document.getElementById("api-key");
  const state = document.getElementById("api-key-state");
  const show = (text = null, bad = false) => {
    state.textContent = text ?? (getApiKey() ? "saved" : "not set");
    state.classList.toggle("bad", bad);
    // The box is emptied once a key is saved: its placeholder said "needed to submit"
    // beside "saved", as if there were none, and Check and save on the empty box forgets it.
    input.placeholder = getApiKey() ? "saved: type another to replace it" : "needed to submit";
  };
  // Only the key entered last is answered, and the box is emptied (or its text selected)
  // only while it still holds the key checked: a check answered after the next key was
  // entered said "wrong key" over the later one's "saved", or saved the older key, and
  // an answer that came while the user typed on emptied the box or selected the text
  // (the next keystroke replaced it).
  let checks = 0;
  form.addEventListener("submit", async (event) => {
    event.preventDefault();
    const mine = ++checks;
    const key = input.value.trim();
    if (!key) {
      setApiKey("");
      show();
      return;
    }
    show("checking…");
    const unchanged = () => input.value.trim() === key;
    try {
      await api.checkKey(key);
    } catch (exc) {
      if (mine !== checks) return;
      show(exc.status === 401 ? "wrong key: not saved" : `not checked: ${exc.message}`, true);
      if (unchanged()) input.select();
      return;
    }
    if (mine !== checks) return;
    setApiKey(key);
    if (unchanged()) input.value = "";
    show();
  });
  window.addEventListener("api-key-rejected", () => show("saved key refused: enter the current one", true));
  window.addEventListener("api-key-changed", () => show());
  show();
}

async function health() {
  const badge = document.getElementById("health");
  try {
    const data = await api.health();
    const workers = data.workers.count;
    // A worker whose task process is being replaced takes no job until it is warm: the
    // badge counts it, and says so, as /health lists it.
    const warming = new Map((data.workers.warming ?? []).map((w) => [w.name, w.warming_s]));
    // A worker without its incarnation lock takes no job until it holds it again.
    const lockless = new Map((data.workers.without_lock ?? []).map((w) => [w.name, w.without_lock_s]));
    const names = data.workers.names.map((name) => {
      if (lockless.has(name)) return `${name} (without its lock for ${Math.round(lockless.get(name))} s: takes no job)`;
      return warming.has(name) ? `${name} (warming up, ${Math.round(warming.get(name))} s)` : name;
    });
    // A worker whose process is gone (killed, its machine lost: its incarnation lock is
    // free) is neither counted nor named above; /health lists it apart until its row
    // leaves the window.
    const gone = (data.workers.gone ?? []).map((w) => `${w.name} (process gone, its lock free; last beat ${Math.round(w.silent_s)} s ago)`);
    // The database refuses writes, the workers' beats with them: none is seen, yet they
    // may beat on (and hold a finished run's result). Said "0 workers", "none seen".
    const unknown = data.workers.state_unknown_since != null;
    badge.textContent = unknown
      ? `${data.status} · workers unknown`
      : `${data.status} · ${workers} worker${workers === 1 ? "" : "s"}` +
        (warming.size ? ` (${warming.size} warming up)` : "");
    badge.className = `health ${data.status}`;
    const seen = unknown ? data.workers.detail : names.join(", ") || "none seen";
    badge.title = `database: ${data.database.detail}\nbroker: ${data.broker.detail}\nworkers: ${seen}` + (gone.length ? `\ngone: ${gone.join(", ")}` : "");
  } catch (exc) {
    badge.textContent = "unreachable";
    badge.className = "health degraded";
    badge.title = exc.message;
  }
}

// The skip link moves the focus past the header's eight stops to the page itself,
// leaving the route alone (its href names the element, as skip links do).
function skipLink() {
  document.getElementById("skip-link").addEventListener("click", (event) => {
    event.preventDefault();
    document.getElementById("page").focus();
  });
}

function start() {
  skipLink();
  keyBox();
  health();
  setInterval(health, 10000);
  window.addEventListener("hashchange", route);
  route();
}

fitChartsToWidth();
start();
