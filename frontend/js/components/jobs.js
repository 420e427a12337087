// What every page showing jobs shares: a job's title, its timing (queue time beside run
// time), its headline figures as table columns (from GET /vocabulary job_summaries), a
// cancel button that asks first, the name-and-tags editor, and the notice for an
// identical resubmission with its rerun button.

import { api } from "../api.js";
import { isTerminal, vocabulary } from "../vocabulary.js";
import { clear, fmt, h, link, messageBox, quantity, rateDeg, rateRad, seconds, tagChips } from "../ui.js";
import { confirmAction } from "./dialog.js";
import { withoutKey } from "./keyed.js";

// Where the jobs page keeps the body of a submission an identical job answered, for the
// rerun button on that job's page.
export const REUSED_KEY = "inertia-id-reused-submission";

// "PPO on paper" or "search 1a2b3c4d".
// What stopped a job short of its own end (GET /vocabulary stopped_reasons), said beside
// its status in the lists: a search or sweep that its limit stopped succeeds with what it
// had, and read "succeeded" alone.
export const STOPPED_LABELS = { time_limit: "time limit" };

export function stoppedNote(job) {
  if (!job.stopped) return null;
  return h("span", { class: "hint stopped-note", title: "its time limit stopped it" }, ` stopped: ${STOPPED_LABELS[job.stopped] || job.stopped}`);
}

export function jobTitle(job) {
  return job.name || `${job.type} ${job.id.slice(0, 8)}`;
}

// What a search scored: NSGA-II a predicted accuracy, never a clustering F1 (the job
// list's line and the compare page's legend had said "F1" of it).
export function searchScore(job) {
  const p = job.params || {};
  return p.method === "nsga2" ? "predicted accuracy" : p.objective === "separability" ? "separability" : "F1";
}

// What distinguishes a job of its type at a glance: method and score, kind, classifier.
export function jobDetail(job) {
  const p = job.params || {};
  if (job.type === "search") return `${p.method}, ${searchScore(job)}, L=${p.sequence_length}, seed ${job.seed}`;
  if (job.type === "train") return `${p.kind || ""}${p.metric ? ` ${p.metric}` : ""}, seed ${job.seed}`;
  if (job.type === "sweep") return `${(p.noises || []).join(", ")}, ×${(p.multiples || []).join(", ")}, seed ${job.seed}`;
  return "";
}

// The run's name (a link), its id, tags, and the detail line.
export function jobCell(job) {
  return h(
    "div",
    { class: "job-cell" },
    link(`#/jobs/${job.id}`, jobTitle(job), { title: job.id, class: "job-link" }),
    job.name ? h("code", { class: "muted" }, ` ${job.id.slice(0, 8)}`) : null,
    " ",
    tagChips(job.tags),
    h("div", { class: "hint" }, jobDetail(job)),
  );
}

export function timingCell(job) {
  return h(
    "span",
    { class: "timing", title: "time queued before its run started · time its run took" },
    h("span", { class: "queue-time" }, `queued ${seconds(job.queue_time_s)}`),
    h("br"),
    h("span", { class: "run-time" }, job.run_time_s === null || job.run_time_s === undefined ? "not started" : `ran ${seconds(job.run_time_s)}`),
  );
}

export function summaryColumns(type) {
  return vocabulary().job_summaries[type] || [];
}

// A column per headline figure of `type`, sortable on the server.
export function summaryTableColumns(type) {
  return summaryColumns(type).map((c) => ({
    key: c.key,
    label: c.label,
    unit: c.unit,
    sort: c.key,
    num: true,
    cell: (job) => summaryValue(job, c),
  }));
}

export function summaryValue(job, column) {
  const value = job.summary ? job.summary[column.key] : null;
  if (value === null || value === undefined || !Number.isFinite(value)) return "–";
  if (column.digits === 0) return fmt(value);
  // A physical figure (a rate, an impulse, a time) to three significant digits, as the
  // job's own page writes it (its `digits` decimals wrote 0.45 N m s as 0.5 and a rate
  // of 1.06e-3 rad/s as 0.0011); a fraction (F1, accuracy) with its decimals.
  if (column.unit) {
    // A flight team reads rates in deg/s: a rad/s figure carries its deg/s beside it (a
    // rate no gyro reads, the dust of cancelling thrusters, written 0).
    return column.unit === "rad/s" ? `${rateRad(value)} (${rateDeg((value * 180) / Math.PI)} deg/s)` : quantity(value);
  }
  const abs = Math.abs(value);
  return abs !== 0 && abs < 10 ** -column.digits ? value.toExponential(2) : value.toFixed(column.digits);
}

// The first two figures with their labels, for lists mixing job types.
export function headline(job) {
  if (!job.summary) return h("span", { class: "muted" }, "–");
  return summaryColumns(job.type)
    .slice(0, 2)
    .map((c) => h("div", { class: "headline" }, h("span", { class: "hint" }, `${c.label} `), summaryValue(job, c)));
}

// Cancel, after asking; `notice` gets the service's refusal, `after` runs once it is done.
export function cancelButton(job, notice, after = () => {}, { id = null, text = "cancel" } = {}) {
  if (isTerminal(job.status)) return null;
  return h(
    "button",
    {
      type: "button",
      class: "danger",
      id,
      "data-cancel": job.id,
      disabled: job.cancel_requested,
      onclick: async () => {
        // Without the key the service refuses it: say so before asking anything.
        if (withoutKey(notice, "Cancelling a job")) return;
        const ok = await confirmAction({
          title: `Cancel ${jobTitle(job)}?`,
          text: job.status === "running" ? "The worker stops it at its next check; what it measured so far is kept." : "It is taken off the queue and never runs.",
          confirm: "Cancel job",
          keep: "Keep it running",
        });
        if (!ok) return;
        try {
          await api.cancelJob(job.id);
        } catch (exc) {
          clear(notice);
          notice.append(messageBox("error", exc.message));
        }
        after();
      },
    },
    job.cancel_requested ? "cancel requested" : text,
  );
}

// Name and tags of a job, editable in place (PATCH /jobs/{id}); `onSaved(job)`.
export function labelEditor(job, onSaved) {
  const name = h("input", { id: "job-name", value: job.name || "", size: 40, placeholder: "a name for this run" });
  const tags = h("input", { id: "job-tags", value: (job.tags || []).join(", "), size: 30, placeholder: "tags, comma separated" });
  const state = h("span", { class: "muted", id: "labels-state" });
  const errors = h("div");
  const form = h(
    "form",
    {
      class: "toolbar labels",
      id: "labels-form",
      onsubmit: async (event) => {
        event.preventDefault();
        clear(errors);
        state.textContent = "";
        if (withoutKey(errors, "Saving labels")) return;
        try {
          const saved = await api.updateJob(job.id, { name: name.value.trim() || null, tags: parseTags(tags.value) });
          state.textContent = "saved";
          onSaved(saved);
        } catch (exc) {
          errors.append(messageBox("error", exc.message));
        }
      },
    },
    h("label", { for: "job-name" }, "name"),
    name,
    h("label", { for: "job-tags" }, "tags"),
    tags,
    h("button", { type: "submit", class: "secondary", id: "save-labels" }, "Save labels"),
    state,
  );
  return h("div", {}, form, errors);
}

export function parseTags(text) {
  return String(text)
    .split(",")
    .map((t) => t.trim())
    .filter((t) => t);
}

// Submits a job and opens its page. A job an identical submission handed back opens
// with the notice that offers to run it again: the body is kept for that rerun.
export async function submitAndOpen(body) {
  const job = await api.submitJob(body);
  if (job.reused) {
    sessionStorage.setItem(REUSED_KEY, JSON.stringify({ id: job.id, body }));
    location.hash = `#/jobs/${job.id}?reused=1`;
  } else {
    location.hash = `#/jobs/${job.id}`;
  }
  return job;
}

// Shown on the page of a job an identical submission handed back: say so, and offer to
// run it again anyway. The rerun names the job it replaces (`rerun_of`): sent again (a
// second tab, a retry) once its job is made, it is handed that job, not another run.
export function reusedNotice(body, job) {
  const holder = h("div", { id: "reused-notice" });
  const rerun = h(
    "button",
    {
      type: "button",
      id: "rerun-job",
      onclick: async () => {
        rerun.disabled = true;
        try {
          const fresh = await api.submitJob({ ...body, rerun: true, rerun_of: job.id });
          location.hash = `#/jobs/${fresh.id}`;
        } catch (exc) {
          holder.append(messageBox("error", exc.message));
          rerun.disabled = false;
        }
      },
    },
    "Run it again",
  );
  const created = `created ${new Date(job.created_at).toISOString().replace("T", " ").slice(0, 19)} UTC`;
  // A job not yet finished has no result to reuse: the submission was handed the run
  // under way (the service starts no second copy of it), and "Run it again" would.
  const unfinished = job.status === "queued" || job.status === "running";
  if (unfinished) rerun.textContent = "Start a second run anyway";
  // The submission's labels are not put on a job that stands (it may be someone else's):
  // said, where it carried ones the job lacks (they were dropped without a word).
  const name = body.name && body.name !== job.name ? body.name : null;
  const tags = (body.tags || []).filter((tag) => !(job.tags || []).includes(tag));
  const dropped = [name ? `name “${name}”` : null, tags.length ? `tag${tags.length === 1 ? "" : "s"} ${tags.join(", ")}` : null].filter(Boolean);
  // One label "was" not applied, several "were" (it said "name “A again” were").
  const one = (name ? 1 : 0) + tags.length === 1;
  const labels = dropped.length
    ? h("span", { id: "reused-labels" }, `This submission's ${dropped.join(" and ")} ${one ? "was" : "were"} not applied to it: set ${one ? "it" : "them"} under “name and tags” below. `)
    : null;
  holder.append(
    messageBox("notice", [
      unfinished
        ? `Handed the identical job ${job.id.slice(0, 8)}, still ${job.status} (${created}): it has the same scenario, parameters and seed, so no second copy was started; its result will answer this submission. `
        : `Reused an earlier result: job ${job.id.slice(0, 8)} has the same scenario, parameters and seed (${job.status}, ${created}), so it was not run again. `,
      ...(labels ? [labels] : []),
      rerun,
    ]),
  );
  return holder;
}
