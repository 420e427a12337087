// A search's front on the operator's objectives (result.front): every member re-scored
// on fresh draws (the rates, and the accuracy measured on fresh test series), the
// hand-designed baselines scored on the same draws beside it. A chart of the accuracy at
// the design noise against the residual rate (deg/s) or the commanded residual (the part
// the sequence leaves, from rest: what separates the members where an initial-rate spread
// dominates the total), coloured by impulse (or propellant), the baselines each with its
// own symbol, a baseline that dominates a member flagged, a member or baseline that
// breaks a constraint drawn open; a table of the members (rates, peak rates included, in deg/s
// and rad/s, attitude change); a chosen member's command plan (per candidate: residual rate and attitude
// change, from GET /jobs/{id}/plan?member=) as CSV or JSON, and a button that trains a
// classifier on it (POST /jobs with search_job_id and front_member).
//
// A Pareto search (nsga2) holds many members; the other methods hold their best sequence
// alone, so the page compares it with the baselines in the same terms.

import { request } from "../api.js";
import { downloads } from "../components/downloads.js";
import { submitAndOpen } from "../components/jobs.js";
import { redrawWhenRekeyed, whenKeyed, withoutKey } from "../components/keyed.js";
import { DEG_PER_RAD, PLOT_CONFIG, keepTwins, layout, plotDiv, twinAxes, twinTraces } from "../components/plots.js";
import { clear, h, messageBox, plain, put, quantity, rateDeg, rateRad, score, sequenceText, warningsBox } from "../ui.js";

const RAD_TO_DEG = 180 / Math.PI;
// What the chart's x axis plots: the residual rate the front is judged on (the scenario's
// initial rate |ω(0)| included), or the commanded residual, from rest. Each title says
// exactly which, mean over candidates, deg/s below and rad/s on the top axis (ω(0) named
// where the scenario's flights start spinning: elsewhere it is 0).
const X_AXES = {
  total: {
    key: "final_rate_deg_s",
    button: "residual rate, ω(0) included",
    // Shorter where ω(0) is named: four lines of title at 375 px left the plot no height
    // once its legend went under it (Plotly: "Something went wrong with axis scaling").
    title: (spinning) => (spinning ? "residual rate, ω(0) included (deg/s, mean over candidates)" : "residual rate once the lag is empty (deg/s, mean over candidates)"),
    twin: () => "residual rate (rad/s)",
  },
  commanded: {
    key: "commanded_residual_rate_deg_s",
    button: "commanded residual, from rest",
    title: () => "commanded residual, from rest (deg/s, mean over candidates)",
    twin: () => "commanded residual (rad/s)",
  },
};
const SYMBOLS = ["diamond", "square", "triangle-up", "cross", "star", "hexagon", "pentagon", "triangle-down"];
const DOMINATES = "#d62728";

// A number cell: the value as `format` writes it (quantity: three significant digits),
// and exactly as stored (data-value) for tests and for copying.
function num(key, value, format = quantity) {
  const shown = value === null || value === undefined ? "–" : typeof value === "number" ? format(value) : String(value);
  return h("td", { class: "num", "data-key": key, "data-value": value === null || value === undefined ? "" : String(value) }, shown);
}

// How a figure keyed `key` is written: a rate (…_deg_s, …_rad_s) 0 below the resolution
// a gyro reads, anything else as a quantity.
function rateFormat(key) {
  return key.endsWith("_deg_s") ? rateDeg : key.endsWith("_rad_s") ? rateRad : quantity;
}

// The figures every row shows, in order: [key in scores, header, how it is written]:
// the accuracy with three decimals, every physical figure as a quantity (three
// significant digits: fixed decimals wrote a residual of 0.0004 deg/s as 0.000, and the
// impulse differently from the best sequence's card). Rates in deg/s and rad/s alike.
function figures(hasPropellant) {
  return [
    ["accuracy", "accuracy", score],
    ["final_rate_deg_s", "residual rate (deg/s)", rateDeg],
    ["final_rate_rad_s", "residual rate (rad/s)", rateRad],
    // The part of it the sequence itself leaves (the plan's prediction from rest, mean
    // over candidates): beside an initial-rate spread the residual carries |ω(0)|, which
    // no sequence removes, and would hide whether a sequence brakes.
    ["commanded_residual_rate_deg_s", "commanded residual, from rest (deg/s)", rateDeg],
    ["commanded_residual_rate_rad_s", "commanded residual, from rest (rad/s)", rateRad],
    // What a residual-rate bound acts on: the candidate that ends fastest.
    ["final_rate_max_deg_s", "worst candidate's residual (deg/s)", rateDeg],
    ["final_rate_max_rad_s", "worst candidate's residual (rad/s)", rateRad],
    // What a per-flight bound acts on: a rate at least 95 % of that candidate's flights
    // stay under, with 95 % confidence (a tolerance bound from the realisations).
    ["final_rate_p95_deg_s", "residual, ≥ 95 % of flights under, 95 % conf. (deg/s)", rateDeg],
    ["final_rate_p95_rad_s", "residual, ≥ 95 % of flights under, 95 % conf. (rad/s)", rateRad],
    ["peak_rate_deg_s", "peak rate (deg/s)", rateDeg],
    ["peak_rate_rad_s", "peak rate (rad/s)", rateRad],
    // The same for each flight's own peak rate (what a per-flight peak bound acts on).
    ["peak_rate_p95_deg_s", "peak, ≥ 95 % of flights under, 95 % conf. (deg/s)", rateDeg],
    ["peak_rate_p95_rad_s", "peak, ≥ 95 % of flights under, 95 % conf. (rad/s)", rateRad],
    ["impulse_nms", "impulse (N m s)", quantity],
    ["on_time_s", "on-time (s)", quantity],
    ...(hasPropellant ? [["propellant_kg", "propellant (kg)", quantity]] : []),
    ["duration_s", "duration (s)", quantity],
    ["attitude_change_deg", "attitude change (deg)", quantity],
  ];
}

const OBJECTIVE_WORDS = { final_rate: "residual rate", peak_rate: "peak rate", on_time: "on-time" };

function available(front) {
  return Object.entries(front.baselines || {}).filter(([, base]) => !base.unavailable);
}

function designNoiseText(front) {
  return (front.design_noise || []).map(([p, q]) => `${p}× process, ${q}× gyro noise`).join("; ");
}

// What colours the markers: propellant when every member states it, else impulse.
function colourBy(front) {
  const members = front.members || [];
  const propellant = members.length > 0 && members.every((m) => typeof m.scores.propellant_kg === "number");
  return propellant ? ["propellant_kg", "propellant (kg)"] : ["impulse_nms", "impulse (N m s)"];
}

// "measured" or "predicted": where a front's accuracy comes from (older results: predicted).
function accuracyWord(front) {
  return front.accuracy_source === "measured" ? "measured" : "predicted";
}

// Member 0 measured again on series that did not rank it first (a front from before the
// confirmation, or of one member, has none).
function confirmationNote(front) {
  const c = front.confirmation;
  if (!c) return null;
  const conditions = (front.design_noise || []).map(([p, q]) => `${p}× process, ${q}× gyro`);
  const figures = c.accuracy_by_noise.map((a, i) => {
    const [low, high] = c.interval_by_noise[i] || [null, null];
    const where = conditions[i] ? ` at ${conditions[i]}` : "";
    return `${a.toFixed(3)} [${low === null ? "–" : low.toFixed(3)}, ${high === null ? "–" : high.toFixed(3)}]${where}`;
  });
  // The baselines that could dominate member 0, on the same series (older results: none).
  const rivals = Object.entries(c.baselines || {}).map(
    ([name, b]) =>
      `${name} ${b.accuracy_by_noise.map((a) => a.toFixed(3)).join(" / ")}${b.dominates_member_0 ? " (dominates member 0)" : ""}`,
  );
  let beside = " The baselines were not measured again.";
  if (c.baselines && !(front.objectives || []).includes("accuracy")) {
    beside = " Accuracy is not one of the front's objectives, so no baseline's flag depends on it and none was measured beside it.";
  } else if (c.baselines && rivals.length) {
    beside = ` Beside it on the same series, the baselines no costlier on the other objectives: ${rivals.join("; ")}; member 0's flags are judged there.`;
  } else if (c.baselines) {
    beside = " No baseline is as cheap on every other objective, so none was measured beside it.";
  }
  return h(
    "p",
    { class: "hint", id: "front-confirmation" },
    `Member 0 is the most accurate of the ${front.candidates_rescored || (front.members || []).length} sequences measured on the front's series, so its figure there is biased up on average. On ${c.test_series} other series per candidate at each condition it measured ${figures.join("; ")} (95 % Wilson intervals): the figure to quote.${beside}`,
  );
}

// What a time limit's grace (or a cancel) left out of the re-score on fresh draws: the
// front's candidates not re-scored (front.not_rescored: judged without them, their scores
// on the search's draw listed) and the best's fresh draws when fewer than asked; null
// when none.
function rescoreCut(job, front) {
  const left = front.not_rescored || [];
  const fresh = job.result.fresh || {};
  const done = (fresh.f1 || []).length;
  const fewer = typeof fresh.draws_asked === "number" && fresh.draws_asked > done;
  if (!left.length && !fewer) return null;
  const settings = job.result.settings || {};
  const limit = settings.time_limit_s;
  const grace = settings.time_limit_grace_s;
  // A search cancelled while its front was measured stopped on the cancel, not on its
  // time limit (the result's `stopped` says which): it had said "the time limit's grace
  // was spent" of a job that never reached its limit.
  const cancelled = job.result.stopped === "cancelled" || (job.status === "cancelled" && job.result.stopped !== "time_limit");
  // A grace of 0 is the job's own choice (stop at the limit), not a grace running out.
  const why = cancelled
    ? "the search was cancelled"
    : typeof limit === "number" && grace === 0
      ? `the time limit (${plain(limit)} s) was reached and no grace was asked for`
      : typeof limit === "number" && typeof grace === "number"
        ? `the time limit's grace was spent (the ${plain(limit)} s limit and its ${plain(grace)} s grace)`
        : "the time limit's grace was spent";
  const sentences = [];
  if (left.length) {
    sentences.push(
      `+ ${left.length} candidate${left.length === 1 ? "" : "s"} not re-scored: ${why}. The front is judged on the ${front.candidates_rescored} re-scored without ${left.length === 1 ? "it" : "them"}; ${left.length === 1 ? "its" : "their"} scores on the search's draw are below.`,
    );
  }
  if (fewer) sentences.push(`The best sequence's clustering F1 was measured on ${done} of the ${fresh.draws_asked} fresh draws asked${left.length ? "" : `: ${why}`}.`);
  const hasPropellant = left.some((c) => c.search_scores && typeof c.search_scores.propellant_kg === "number");
  const columns = figures(hasPropellant).filter(([key]) => !key.includes("p95") && !key.startsWith("final_rate_max"));
  return [
    h("p", { class: "message notice", id: "front-not-rescored", role: "status" }, sentences.join(" ")),
    left.length
      ? h(
          "details",
          { id: "front-not-rescored-list" },
          h("summary", {}, `The ${left.length} not re-scored: their scores on the search's draw`),
          h(
            "div",
            { class: "table-scroll", tabindex: "0", role: "region", "aria-label": "candidates not re-scored" },
            h(
              "table",
              { id: "front-not-rescored-table" },
              h("thead", {}, h("tr", {}, columns.map(([, label]) => h("th", { class: "num" }, label)), h("th", {}, "levels"))),
              h(
                "tbody",
                {},
                left.map((c) => h("tr", {}, columns.map(([key, , format]) => num(key, (c.search_scores || {})[key], format)), h("td", { class: "mono" }, sequenceText(c.sequence)))),
              ),
            ),
          ),
        )
      : null,
  ];
}

// A point's hover: each figure written as the tables write it (the attitude change had
// two significant digits where the table gives three).
function hover(label, scores, sequence) {
  const written = Object.fromEntries(figures(true).map(([key, , format]) => [key, format]));
  const figure = (key) => written[key](scores[key]);
  const predicted = scores.predicted_accuracy_by_noise;
  const mean = predicted ? predicted.reduce((a, b) => a + b, 0) / predicted.length : null;
  const commanded = typeof scores.commanded_residual_rate_deg_s === "number";
  return (
    `${label}<br>accuracy ${figure("accuracy")}` +
    (mean === null ? "" : ` (predicted ${score(mean)})`) +
    `<br>residual rate ${figure("final_rate_deg_s")} deg/s (${figure("final_rate_rad_s")} rad/s)` +
    (commanded ? `<br>commanded residual, from rest ${figure("commanded_residual_rate_deg_s")} deg/s (${figure("commanded_residual_rate_rad_s")} rad/s)` : "") +
    `<br>impulse ${figure("impulse_nms")} N m s` +
    (typeof scores.propellant_kg === "number" ? `<br>propellant ${figure("propellant_kg")} kg` : "") +
    `<br>attitude change ${figure("attitude_change_deg")} deg` +
    `<br>${sequenceText(sequence)}`
  );
}

// Whether the commanded residual can be plotted: every member and baseline states it
// (results stored before it do not).
function hasCommanded(front) {
  return [...front.members, ...available(front).map(([, base]) => base)].every((item) => typeof item.scores.commanded_residual_rate_deg_s === "number");
}

// The rad/s twin of the x axis `which` plots.
function rateTwins(which, spinning) {
  return [{ of: "xaxis", twin: "xaxis2", factor: 1 / DEG_PER_RAD, title: X_AXES[which].twin(spinning) }];
}

// The front's chart with `which` (a key of X_AXES) on its x axis; `spinning`: whether the
// scenario's flights start with an initial rate.
async function drawPlot(node, front, selected, which, spinning) {
  const members = front.members;
  const xKey = X_AXES[which].key;
  const twins = rateTwins(which, spinning);
  const [colourKey, colourLabel] = colourBy(front);
  const bases = available(front);
  const values = [...members.map((m) => m.scores[colourKey]), ...bases.map(([, b]) => b.scores[colourKey])].filter((v) => typeof v === "number");
  const cmin = Math.min(...values);
  const cmax = Math.max(...values) > cmin ? Math.max(...values) : cmin + 1;
  const order = [...members].sort((a, b) => a.scores[xKey] - b.scores[xKey]);
  // A member that breaks a constraint is drawn open, as a baseline that does: a search
  // other than NSGA-II keeps its best sequence when it breaks one (cem, random,
  // exhaustive, ppo with a penalty), which was drawn filled, as if feasible.
  const breaks = (m) => m.feasible === false;
  const traces = [
    {
      x: order.map((m) => m.scores[xKey]),
      y: order.map((m) => m.scores.accuracy),
      customdata: order.map((m) => m.index),
      text: order.map((m) => hover(`member ${m.index}${breaks(m) ? " — breaks a constraint" : ""}`, m.scores, m.sequence)),
      hovertemplate: "%{text}<extra></extra>",
      // Markers only: the front is non-dominated in every objective at once, so in this
      // plane of two of them its members need not lie on a line.
      mode: "markers",
      name: members.length > 1 ? "front members" : "best sequence",
      marker: {
        size: 11,
        symbol: order.map((m) => (breaks(m) ? "circle-open" : "circle")),
        color: order.map((m) => m.scores[colourKey]),
        colorscale: "Viridis",
        cmin,
        cmax,
        // An open marker is drawn in its line alone, in the marker's colour: thicker.
        line: { color: order.map((m) => (m.dominated_by.length ? DOMINATES : "#333")), width: order.map((m) => (m.dominated_by.length || breaks(m) ? 2.5 : 0.5)) },
        colorbar: {
          orientation: "h",
          title: { text: colourLabel, side: "right" },
          x: 0,
          xanchor: "left",
          len: 0.45,
          thickness: 12,
          yref: "container",
          y: 0.02,
          yanchor: "bottom",
        },
      },
    },
  ];
  bases.forEach(([name, base], i) => {
    const dominates = (base.dominates || []).length > 0;
    // Shown for comparison only (it dominates nothing): an open marker (in the legend
    // too), and its hover says so. It was drawn as the feasible ones were. (Its legend
    // entry keeps the name alone: a longer one, under a 375 px plot, left the plot no
    // height and Plotly threw "Something went wrong with axis scaling".)
    const breaks = base.feasible === false;
    const flag = dominates ? ` — dominates member${base.dominates.length > 1 ? "s" : ""} ${base.dominates.join(", ")}` : breaks ? " — breaks a constraint" : "";
    traces.push({
      x: [base.scores[xKey]],
      y: [base.scores.accuracy],
      text: [hover(`baseline ${name}${flag}`, base.scores, base.sequence)],
      hovertemplate: "%{text}<extra></extra>",
      mode: "markers",
      name: dominates ? `${name}: dominates` : name,
      marker: {
        size: 14,
        symbol: `${SYMBOLS[i % SYMBOLS.length]}${breaks ? "-open" : ""}`,
        color: [base.scores[colourKey]],
        colorscale: "Viridis",
        cmin,
        cmax,
        showscale: false,
        // An open marker is drawn in its line alone: thicker, in the marker's colour.
        line: breaks ? { width: 2.5 } : { color: dominates ? DOMINATES : "#222", width: dominates ? 3 : 1 },
      },
    });
  });
  // The rate in deg/s, and in rad/s on the top axis (the chosen member's marker stays
  // the last trace: markChosen moves it).
  traces.push(...twinTraces(twins));
  const chosen = members.find((m) => m.index === selected);
  traces.push({
    x: chosen ? [chosen.scores[xKey]] : [],
    y: chosen ? [chosen.scores.accuracy] : [],
    mode: "markers",
    name: "chosen member",
    hoverinfo: "skip",
    marker: { size: 22, symbol: "circle-open", color: "#1d2330", line: { width: 2 } },
  });
  // react, not newPlot: the chart is drawn again when its x axis is switched.
  await Plotly.newPlot(
    node,
    traces,
    layout(X_AXES[which].title(spinning), `${accuracyWord(front)} accuracy`, {
      height: 440,
      margin: { l: 60, r: 10, t: 16, b: 96 },
      ...twinAxes(twins, { anchor: "y" }),
    }),
    PLOT_CONFIG,
  );
  node.dataset.x = which;
  keepTwins(node, twins);
  if (!node.clicksHeard) {
    node.clicksHeard = true;
    node.on("plotly_click", (event) => {
      const point = event.points && event.points[0];
      if (point && point.curveNumber === 0) node.dispatchEvent(new CustomEvent("member", { detail: point.customdata }));
    });
  }
}

function markChosen(node, front, index) {
  const chosen = front.members.find((m) => m.index === index);
  Plotly.restyle(node, { x: [[chosen.scores[X_AXES[node.dataset.x || "total"].key]]], y: [[chosen.scores.accuracy]] }, [node.data.length - 1]);
}

// The buttons that switch the chart's x axis (null where the result has no commanded
// residual); `draw(which)` draws it.
function xSwitch(front, draw) {
  if (!hasCommanded(front)) return null;
  const buttons = Object.entries(X_AXES).map(([which, { button }]) => h("button", { type: "button", class: "secondary toggle", "data-x": which, onclick: () => draw(which) }, button));
  return {
    node: h("div", { class: "toolbar", role: "group", "aria-label": "the front chart's x axis", id: "front-x-axis" }, h("span", { class: "hint" }, "x axis"), buttons),
    show: (which) => buttons.forEach((b) => b.setAttribute("aria-pressed", String(b.dataset.x === which))),
  };
}

function memberTable(front, onPick) {
  const hasPropellant = front.members.some((m) => typeof m.scores.propellant_kg === "number");
  const columns = figures(hasPropellant);
  const rows = front.members.map((member) => {
    const radio = h("input", { type: "radio", name: "front-member", value: member.index, "aria-label": `choose member ${member.index}` });
    const dominated = member.dominated_by.length ? h("span", { class: "dominated" }, member.dominated_by.join(", ")) : "–";
    return h(
      "tr",
      { "data-member": member.index, class: member.dominated_by.length ? "dominated-row" : null, onclick: () => onPick(member.index) },
      h("td", { class: "select" }, radio),
      h("td", { class: "num", "data-key": "index" }, String(member.index)),
      columns.map(([key, , format]) => num(key, member.scores[key], format)),
      h("td", { "data-key": "dominated_by" }, dominated),
      // A searcher other than NSGA-II keeps its best sequence even when it breaks a bound.
      h(
        "td",
        { "data-key": "feasible" },
        member.feasible === false ? h("strong", { class: "dominated" }, "breaks a constraint") : member.feasible ? "yes" : "–",
        // The all-off end of the front: a classifier cannot be trained on it (the service refuses).
        member.fires === false ? h("span", { class: "muted" }, " · fires nothing: not trainable") : null,
      ),
    );
  });
  return h(
    "div",
    // Focusable, so a keyboard user can scroll a table wider than the page.
    { class: "table-scroll", tabindex: "0", role: "region", "aria-label": "front members" },
    h(
      "table",
      { id: "front-table" },
      h("thead", {}, h("tr", {}, h("th", { class: "select" }, h("span", { class: "visually-hidden" }, "choose")), h("th", { class: "num" }, "member"), columns.map(([, label]) => h("th", { class: "num" }, label)), h("th", {}, "dominated by"), h("th", {}, "within the constraints"))),
      h("tbody", {}, rows),
    ),
  );
}

function baselineTable(front) {
  const hasPropellant = front.members.some((m) => typeof m.scores.propellant_kg === "number");
  const columns = figures(hasPropellant).filter(([key]) => !["on_time_s", "duration_s"].includes(key));
  const rows = available(front).map(([name, base]) =>
    h(
      "tr",
      { "data-baseline": name, class: (base.dominates || []).length ? "dominated-row" : null },
      h("td", {}, name),
      columns.map(([key, , format]) => num(key, base.scores[key], format)),
      h("td", { "data-key": "dominates" }, (base.dominates || []).length ? h("strong", { class: "dominated" }, `members ${base.dominates.join(", ")}`) : "–"),
      // A baseline that breaks a constraint is shown for comparison only (it dominates nothing).
      h("td", { "data-key": "feasible" }, base.feasible === false ? h("strong", { class: "dominated" }, "breaks a constraint") : base.feasible ? "yes" : "–"),
      h("td", { class: "mono" }, sequenceText(base.sequence)),
    ),
  );
  return h(
    "div",
    { class: "table-scroll", tabindex: "0", role: "region", "aria-label": "baselines" },
    h(
      "table",
      { id: "front-baselines" },
      h("thead", {}, h("tr", {}, h("th", {}, "baseline"), columns.map(([, label]) => h("th", { class: "num" }, label)), h("th", {}, "dominates"), h("th", {}, "within the constraints"), h("th", {}, "levels"))),
      h("tbody", {}, rows),
    ),
  );
}

// Flights the page asks a plan to fly a candidate (how single flights spread around the
// nominal prediction); a sequence too long for the service's budget is planned without.
const PLAN_FLIGHTS = 200;

async function planBlob(job, index, format, flights) {
  const query = flights ? { member: index, format, flights } : { member: index, format };
  return request("GET", `/jobs/${encodeURIComponent(job.id)}/plan`, { query, raw: true });
}

// The member's plan with PLAN_FLIGHTS flights, or without when the service says that is
// more than it computes for one request (a 422 on `flights`): [document, flights].
async function memberPlan(job, index) {
  const path = `/jobs/${encodeURIComponent(job.id)}/plan`;
  try {
    return [await request("GET", path, { query: { member: index, flights: PLAN_FLIGHTS } }), PLAN_FLIGHTS];
  } catch (exc) {
    if (!(exc.status === 422 && (exc.errors || []).some((e) => e.loc.join(".") === "query.flights"))) throw exc;
    return [await request("GET", path, { query: { member: index } }), 0];
  }
}

// The chosen member: its sequence, a button that trains on it, its command plan (per
// candidate: residual rate and attitude change) and the plan's downloads.
async function showMember(holder, job, member, context) {
  clear(holder);
  const cancelled = job.status === "cancelled";
  if (job.status !== "succeeded" && !cancelled) {
    // The service plans a finished search's members, or a cancelled one's partial front.
    holder.append(
      h("h3", {}, `Member ${member.index}`),
      h("p", {}, "Sequence (level indices): ", h("span", { class: "mono", id: "front-member-sequence" }, sequenceText(member.sequence))),
      messageBox("notice", `This search is ${job.status}: its command plans and training on a member are offered once a search succeeds (or is cancelled with a partial front).`),
    );
    return;
  }
  const notice = h("div", { id: "front-train-notice" });
  const train = h(
    "button",
    {
      type: "button",
      id: "front-train",
      onclick: async () => {
        clear(notice);
        if (withoutKey(notice, "Training on this sequence")) return;
        train.disabled = true;
        // A cancelled search's member is trained as the sequence itself: the service
        // trains on a member by reference only for a search that succeeded.
        const params = cancelled ? { sequence: member.sequence } : { sequence: member.sequence, search_job_id: job.id, front_member: member.index };
        const body = { type: "train", scenario_id: job.scenario_id, seed: job.seed, params };
        try {
          await submitAndOpen(body);
        } catch (exc) {
          notice.append(messageBox("error", exc.message || String(exc)));
        } finally {
          train.disabled = false;
        }
      },
    },
    "Train on this sequence",
  );
  if (member.fires === false) {
    // The front's zero-impulse end: no torque, nothing to tell the candidates apart by
    // (the service refuses to train on it).
    train.disabled = true;
    train.title = "this member fires no thruster: nothing to train on";
  }
  const stem = `plan-${job.id.slice(0, 8)}-member-${member.index}`;
  // The downloads fly as many times as the page's plan did (known once it is computed).
  let flown = PLAN_FLIGHTS;
  const plan = h("div", { id: "front-plan" });
  const planDownloads = downloads(
    "front-plan-downloads",
    [
      { label: "CSV", filename: `${stem}.csv`, make: () => planBlob(job, member.index, "csv", flown) },
      { label: "JSON", filename: `${stem}.json`, make: () => planBlob(job, member.index, "json", flown) },
    ],
    { label: "Command plan" },
  );
  // put, not the DOM's append: append writes a null child as the text "null".
  put(
    holder,
    h("h3", {}, `Member ${member.index}`),
    h("p", {}, "Sequence (level indices): ", h("span", { class: "mono", id: "front-member-sequence" }, sequenceText(member.sequence))),
    cancelled ? messageBox("notice", "This search was cancelled: the member is from the partial front it had measured, and its plan says so.") : null,
    h("div", { class: "toolbar" }, train),
    notice,
    planDownloads,
    plan,
  );
  // The plan and its downloads are computed on request, which needs the key.
  planDownloads.hidden = true;
  await whenKeyed(plan, "The member's command plan", () => drawPlan(plan, planDownloads, job, member, context, (flights) => (flown = flights)));
}

// What the scenario's initial-rate spread adds to every flight's residual (the plan's
// `initial_rate_floor`), or nothing for a scenario that starts at rest.
function floorText(floor) {
  if (!floor) return "";
  return `The residual predicted here starts from rest: what the commands leave. Every flight also keeps the rate it started with (the scenario's initial-rate spread, σ ${quantity(floor.initial_rate_sigma_rad_s)} rad/s an axis), which no open-loop sequence removes: ${rateDeg(floor.mean_deg_s)} deg/s (${rateRad(floor.mean_rad_s)} rad/s) on average over flights, ${rateDeg(floor.p95_deg_s)} deg/s (${rateRad(floor.p95_rad_s)} rad/s) on 95 % of them. `;
}

// The member's command plan as a table, per candidate; `flewWith(flights)` learns how
// many flights the service flew (the downloads fly as many).
async function drawPlan(plan, planDownloads, job, member, context, flewWith) {
  planDownloads.hidden = false;
  plan.replaceChildren(h("p", { class: "muted" }, "Computing the command plan…"));
  try {
    const [document, flights] = await memberPlan(job, member.index);
    flewWith(flights);
    if (!context.alive() || !plan.isConnected) return;
    clear(plan);
    const spread = document.flights;
    // Each candidate's figures, in order: [key (a flights_ key reads c.flights), header].
    // Peak rates, as residual rates, in deg/s and rad/s. With flights: their percentile,
    // and the rate at least 95 % of all flights stay under with 95 % confidence (the
    // figure a front's per-flight bound reads).
    const columns = [
      // The nominal prediction starts from rest: its residual is the commanded one.
      ["residual_rate_deg_s", "commanded residual, from rest (deg/s)"],
      ["residual_rate_rad_s", "commanded residual, from rest (rad/s)"],
      ...(spread
        ? [
            // A flight's total: it adds the rate the flight started with.
            ["flights_residual_rate_mean_deg_s", `mean of the ${spread.flights_per_candidate} flights, ω(0) included (deg/s)`],
            ["flights_residual_rate_mean_rad_s", `mean of the ${spread.flights_per_candidate} flights, ω(0) included (rad/s)`],
            ["flights_residual_rate_p95_deg_s", `95th percentile of the ${spread.flights_per_candidate} flights (deg/s)`],
            ["flights_residual_rate_p95_rad_s", `95th percentile of the ${spread.flights_per_candidate} flights (rad/s)`],
            ["flights_residual_rate_p95_bound_deg_s", "residual, ≥ 95 % of flights under, 95 % conf. (deg/s)"],
            ["flights_residual_rate_p95_bound_rad_s", "residual, ≥ 95 % of flights under, 95 % conf. (rad/s)"],
            ["flights_residual_rate_max_deg_s", "fastest flight (deg/s)"],
            ["flights_residual_rate_max_rad_s", "fastest flight (rad/s)"],
          ]
        : []),
      ["end_rate_deg_s", "at the last command's end (deg/s)"],
      ["end_rate_rad_s", "at the last command's end (rad/s)"],
      ["peak_rate_deg_s", "peak rate (deg/s)"],
      ["peak_rate_rad_s", "peak rate (rad/s)"],
      ...(spread
        ? [
            ["flights_peak_rate_p95_bound_deg_s", "peak, ≥ 95 % of flights under, 95 % conf. (deg/s)"],
            ["flights_peak_rate_p95_bound_rad_s", "peak, ≥ 95 % of flights under, 95 % conf. (rad/s)"],
          ]
        : []),
      ["attitude_change_deg", "attitude change (deg)"],
    ];
    const figure = (c, key) => (key.startsWith("flights_") ? c.flights[key.slice("flights_".length)] : c[key]);
    put(
      plan,
      // A plan the service found doubtful (its rates far below the gyro noise: an
      // inertia typed in kg mm² as kg m², say) says so above its figures.
      warningsBox(document.warnings, "front-plan-warnings"),
      h("p", { class: "hint" }, `Predicted with every noise off: the residual rate once the actuation lag has delivered the torque still in it when the last command ends (the rate at that moment beside it), the peak rate (the largest at a gyro sample or once settled), and the rotation the body makes over its ${document.duration_s} s (quaternion kinematics of the predicted rates).${spread ? ` Single flights spread around that: the sequence flown ${spread.flights_per_candidate} times a candidate at the scenario's noise (seed ${spread.seed}); their 95th percentile, a rate at least 95 % of all flights stay under with 95 % confidence, and the fastest; and a peak rate at least 95 % of flights stay under, with 95 % confidence.` : " Too long to fly many times within one request: the nominal prediction alone."} ${floorText(document.initial_rate_floor)}Impulse ${quantity(document.propellant.impulse_nms)} N m s, on-time ${quantity(document.propellant.on_time_s)} s${document.propellant.propellant_kg === null ? "" : `, propellant ${quantity(document.propellant.propellant_kg)} kg`}.`),
      h(
        "div",
        // Focusable, so a keyboard user can scroll a table wider than the page.
        { class: "table-scroll", tabindex: "0", role: "region", "aria-label": "command plan per candidate" },
        h(
          "table",
          { id: "front-plan-table" },
          h("thead", {}, h("tr", {}, h("th", {}, "candidate"), columns.map(([, label]) => h("th", { class: "num" }, label)))),
          h(
            "tbody",
            {},
            document.candidates.map((c) => h("tr", { "data-candidate": c.name }, h("td", {}, c.name), columns.map(([key]) => num(key, figure(c, key), rateFormat(key))))),
          ),
        ),
      ),
    );
  } catch (exc) {
    if (!plan.isConnected) return;
    clear(plan);
    plan.append(messageBox("error", `The command plan: ${exc.message || String(exc)}`));
    // A saved key refused: drawn once the current one is saved at the top right.
    redrawWhenRekeyed(plan, exc, () => drawPlan(plan, planDownloads, job, member, context, flewWith));
  }
}

// The chosen member in the page's address (#/jobs/<id>?member=3), the other parts of its
// query kept: Back from a training started on it, a reload or a shared link shows it
// again (Back had returned to member 0).
function keepInAddress(index) {
  const [path, queryText = ""] = location.hash.split("?");
  const query = new URLSearchParams(queryText);
  query.set("member", String(index));
  history.replaceState(history.state, "", `${path}?${query}`);
}

// `scenario`: the search's scenario (null when it could not be read): where its flights
// start spinning (an initial-rate spread) the chart plots the commanded residual first.
export function frontPanel(job, context, scenario = null) {
  const front = job.result && job.result.front;
  if (!front || !(front.members || []).length) return null;
  const members = front.members;
  const pareto = job.result.method === "nsga2";
  const dominating = available(front).filter(([, base]) => (base.dominates || []).length);
  const plot = plotDiv("front-plot");
  const memberHolder = h("div", { id: "front-member" });
  const asked = Number(context.query && context.query.member);
  let chosen = members.some((m) => m.index === asked) ? asked : members[0].index;
  // |ω(0)| is in every member's total residual, and where it is most of it (0.466 to 0.481
  // deg/s on paper-in-orbit, over a 0.457 deg/s floor) the members stood in one column.
  const uncertainty = scenario && scenario.document && scenario.document.uncertainty;
  const spinning = Boolean(uncertainty && uncertainty.initial_rate_sigma_rad_s > 0);
  let xShown = spinning && hasCommanded(front) ? "commanded" : "total";
  const xButtons = xSwitch(front, async (which) => {
    xShown = which;
    xButtons.show(which);
    await drawPlot(plot, front, chosen, which, spinning);
  });
  const pick = (index, remember = true) => {
    chosen = index;
    if (remember && context.alive()) keepInAddress(index);
    for (const input of card.querySelectorAll("input[name='front-member']")) input.checked = Number(input.value) === index;
    for (const row of card.querySelectorAll("#front-table tbody tr")) row.classList.toggle("chosen", Number(row.dataset.member) === index);
    markChosen(plot, front, index);
    showMember(memberHolder, job, members.find((m) => m.index === index), context);
  };
  const [, colourLabel] = colourBy(front);
  const card = h(
    "div",
    { class: "card", id: "front-card" },
    h("h2", {}, pareto ? `Pareto front: ${members.length} sequence${members.length === 1 ? "" : "s"}` : "The best sequence on the operator's objectives"),
    h(
      "p",
      { class: "hint" },
      `${pareto ? "Non-dominated" : "Judged"} on ${(front.objectives || []).map((o) => OBJECTIVE_WORDS[o] || o).join(", ")}; the rates on a fresh draw (${front.fresh_realisations} realisations per candidate), the baselines on the same draws. Accuracy at the design noise (${designNoiseText(front)}): ${front.accuracy_source === "measured" ? `measured: the scenario's noise model as a Bayes classifier, tested on ${front.fresh_test_series} fresh series per candidate at each condition, every sequence on the same series (the search ranked by a prediction from the same model, kept beside it)` : "predicted from the scenario's own noise model (no draw: the same sequence, the same figure)"}. Colour: ${colourLabel}; a red outline marks a member a baseline dominates, an open symbol a member or baseline that breaks a constraint.${xButtons ? " The x axis: the residual rate the front is judged on (the rate each flight started with, ω(0), included), or the commanded residual, the part the sequence itself leaves (predicted from rest), which tells braking sequences apart where ω(0) is most of the total." : ""}`,
    ),
    rescoreCut(job, front),
    confirmationNote(front),
    dominating.length
      ? h(
          "div",
          { class: "message error", id: "front-dominated", role: "alert" },
          dominating.map(([name, base]) => `Baseline ${name} dominates member${base.dominates.length > 1 ? "s" : ""} ${base.dominates.join(", ")} of the front (no worse on every objective, better on one).`).join("\n"),
        )
      : null,
    xButtons && xButtons.node,
    plot,
    h("h3", {}, "Members"),
    memberTable(front, (index) => pick(index)),
    h("h3", {}, "Baselines on the same draw"),
    baselineTable(front),
    downloads(
      "front-downloads",
      [
        { label: "CSV", href: `/jobs/${encodeURIComponent(job.id)}/result?format=csv&table=front` },
        { label: "JSON", href: `/jobs/${encodeURIComponent(job.id)}/result?format=json&table=front` },
      ],
      { label: "Download the front" },
    ),
    memberHolder,
  );
  plot.addEventListener("member", (event) => pick(event.detail));
  return {
    node: card,
    async draw() {
      if (xButtons) xButtons.show(xShown);
      await drawPlot(plot, front, chosen, xShown, spinning);
      pick(chosen, false);
    },
  };
}
