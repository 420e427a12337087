// Scenarios: the list, one scenario (candidates with principal moments, thrusters, noise)
// and the form that creates one from a preset, from a stored scenario (clone and edit) or
// from a JSON file (what `inertia-id scenario --out` writes), field by field.

import { api } from "../api.js";
import { confirmAction } from "../components/dialog.js";
import { downloads } from "../components/downloads.js";
import { COLORS, DEG_PER_RAD, PLOT_CONFIG, layout, plotText, tightRange } from "../components/plots.js";
import { clear, h, jsonBlob, link, messageBox, plain, quantity, scrollRegion, showError, showFieldErrors, table, warningsBox, when } from "../ui.js";

const UNCERTAINTY_FIELDS = [
  ["duty_jitter_sigma", "duty jitter σ", "fraction of full duty, per firing thruster and step"],
  ["lowpass_time_constant_s", "actuation low-pass τ", "s"],
  ["thrust_scale_sigma", "thrust-scale error σ", "fraction, per thruster and realisation"],
  ["disturbance_torque_sigma_nm", "disturbance torque σ (process noise)", "N m per axis"],
  ["disturbance_interval_s", "disturbance interval", "s, how long one draw is held"],
  ["gyro_noise_sigma_rad_s", "gyro noise σ (measurement noise)", "rad/s per axis"],
  ["gyro_bias_rad_s", "gyro bias", "rad/s, three values x, y, z"],
  ["gyro_bias_sigma_rad_s", "gyro bias σ", "rad/s per axis and realisation"],
  ["initial_rate_sigma_rad_s", "initial rate σ", "rad/s per axis"],
];

const TIMING_FIELDS = [
  ["step_duration_s", "actuation step", "s"],
  ["integration_step_s", "RK4 step", "s"],
  ["sample_rate_hz", "gyro sample rate", "Hz"],
];

// A value or a list of them (the gyro bias: x, y, z), each written by `write`.
function eachWritten(value, write) {
  return Array.isArray(value) ? value.map(write).join(", ") : write(value);
}

// Per-thruster values (thrust, lever arm) in words: one value when every thruster has it.
function perThruster(values, unit) {
  return values.every((v) => v === values[0]) ? `${plain(values[0])} ${unit} each` : `${values.map((v) => plain(v)).join(", ")} ${unit} (thrusters 1 to ${values.length})`;
}

// What the propellant figures rest on: the thrust (or the lever arm it is derived from),
// the specific impulse and standard gravity; or that the scenario states none, so a plan
// gives the commanded impulse alone. A clone or an upload keeps them (the form below).
function propulsionText(thrusters) {
  const parts = [];
  if (Array.isArray(thrusters.thrust_n)) parts.push(`thrust ${perThruster(thrusters.thrust_n, "N")}`);
  if (Array.isArray(thrusters.lever_arm_m)) parts.push(`lever arm ${perThruster(thrusters.lever_arm_m, "m")} (thrust = |torque| / lever arm)`);
  if (typeof thrusters.specific_impulse_s === "number") parts.push(`specific impulse ${plain(thrusters.specific_impulse_s)} s`);
  if (parts.length === 0) return "Thrust and specific impulse not stated: plans give the commanded impulse (N m s), no propellant mass.";
  parts.push(`standard gravity ${plain(thrusters.standard_gravity_m_s2)} m/s²`);
  const text = parts.join(" · ");
  return `${text[0].toUpperCase()}${text.slice(1)}.`;
}

// A per-thruster field of the form: empty is "not stated" (null), one value is every
// thruster's, several are one per thruster (the service says which count it needs).
function perThrusterField(text) {
  const values = listOf(text);
  if (values.length === 0) return null;
  return values.length === 1 ? values[0] : values;
}

function listText(value) {
  if (value === null || value === undefined) return "";
  return (Array.isArray(value) ? value : [value]).map((v) => plain(v, null)).join(", ");
}

export async function renderList(root) {
  root.append(
    h("h1", {}, "Scenarios"),
    h("div", { class: "toolbar" }, link("#/scenarios/new", "New scenario", { class: "button", id: "new-scenario" })),
  );
  const page = await api.scenarios();
  if (page.items.length === 0) {
    root.append(messageBox("notice", "No scenarios yet. Create one from the paper preset to start."));
    return;
  }
  root.append(
    h(
      "div",
      { class: "card" },
      table(
        ["name", "candidates", "thrusters", "duty levels", "created", "id", h("span", { class: "visually-hidden" }, "actions")],
        page.items.map((s) => [
          link(`#/scenarios/${s.id}`, s.name),
          s.candidates.length,
          s.n_thrusters,
          s.n_levels,
          when(s.created_at),
          h("code", {}, s.id.slice(0, 8)),
          link(`#/scenarios/new?from=${s.id}`, "clone and edit"),
        ]),
        { id: "scenario-table" },
      ),
    ),
  );
}

export async function renderOne(root, context) {
  const [id] = context.params;
  const scenario = await api.scenario(id);
  const doc = scenario.document;
  const momentsPlot = h("div", { class: "plot short", id: "moments-plot" });
  const actions = h("div", { class: "toolbar" });
  const notice = h("div");
  actions.append(
    link(`#/jobs?scenario=${scenario.id}&type=search`, "Search for a sequence", { class: "button" }),
    link(`#/jobs?scenario=${scenario.id}&type=train`, "Train a classifier", { class: "button secondary" }),
    link(`#/scenarios/new?from=${scenario.id}`, "Clone and edit", { class: "button secondary", id: "clone-scenario" }),
    downloads("scenario-downloads", [{ label: "scenario (JSON)", filename: `scenario-${scenario.id.slice(0, 8)}.json`, make: async () => jsonBlob(doc) }]),
    h(
      "button",
      {
        class: "danger",
        onclick: async () => {
          const ok = await confirmAction({ title: `Delete scenario "${scenario.name}"?`, text: "A scenario that jobs or classifiers use is kept.", confirm: "Delete" });
          if (!ok) return;
          try {
            await api.deleteScenario(scenario.id);
            location.hash = "#/scenarios";
          } catch (exc) {
            showError(notice, exc);
          }
        },
      },
      "Delete",
    ),
  );
  root.append(
    h("h1", {}, `Scenario: ${scenario.name}`),
    h("p", { class: "muted" }, `id `, h("code", {}, scenario.id), " · created ", when(scenario.created_at)),
    actions,
    notice,
    // What the service found doubtful but stored (a thruster that gives no torque).
    warningsBox(scenario.warnings, "scenario-warnings"),
    h(
      "div",
      { class: "row" },
      h(
        "div",
        { class: "card grow" },
        h("h2", {}, "Inertia candidates"),
        // In a region a keyboard reaches: on a phone the tensors run past the card, which
        // scrolled with no way to it but a pointer (axe-core: scrollable-region-focusable).
        scrollRegion(
          "inertia candidates",
          table(
            ["candidate", "inertia tensor (kg m²)", "principal moments (kg m², ascending)"],
            scenario.candidates.map((c) => [
              c.name,
              h("span", { class: "mono" }, c.inertia_kg_m2.map((r) => `[${r.map((v) => quantity(v, 4)).join(", ")}]`).join(" ")),
              h("span", { class: "mono" }, c.principal_moments_kg_m2.map((v) => quantity(v, 4)).join(", ")),
            ]),
            { id: "candidate-table" },
          ),
        ),
      ),
      h("div", { class: "card grow" }, h("h2", {}, "Principal moments (kg m²)"), h("p", { class: "hint", id: "moments-spread" }, momentsSpreadText(scenario.candidates)), momentsPlot),
    ),
    h(
      "div",
      { class: "row" },
      h(
        "div",
        { class: "card grow" },
        h("h2", {}, "Thrusters"),
        h("p", { class: "hint" }, "Torque at full duty (N m), one column per thruster, numbered from 1."),
        scrollRegion(
          "thruster torques",
          table(
            ["axis", ...doc.thrusters.torque_matrix_nm[0].map((_, j) => `thruster ${j + 1}`)],
            doc.thrusters.torque_matrix_nm.map((row, i) => [["x", "y", "z"][i], ...row.map((v) => plain(v, 4))]),
            { class: "matrix", id: "thruster-table" },
          ),
        ),
        h("p", {}, "Duty levels: ", h("span", { class: "mono" }, doc.thrusters.levels.map((v) => plain(v)).join(", "))),
        h("p", { id: "propulsion" }, propulsionText(doc.thrusters)),
      ),
      h(
        "div",
        { class: "card grow" },
        h("h2", {}, "Timing and noise (1× level)"),
        h(
          "dl",
          { class: "kv" },
          TIMING_FIELDS.map(([key, label, unit]) => [h("dt", {}, label), h("dd", {}, `${plain(doc.timing[key])} ${unit}`)]),
          // A rate (gyro noise and bias, initial rate) in deg/s too, as a flight team reads it.
          UNCERTAINTY_FIELDS.map(([key, label, unit]) => [
            h("dt", {}, label),
            h("dd", {}, `${eachWritten(doc.uncertainty[key], (v) => plain(v))} (${unit})${key.endsWith("_rad_s") ? ` = ${eachWritten(doc.uncertainty[key], (v) => quantity(v * DEG_PER_RAD))} deg/s` : ""}`),
          ]),
        ),
      ),
    ),
  );
  // Markers, not bars: the candidates differ by a few per cent, which a bar from 0 hides. Each
  // moment gets its own panel with its own (never zero-based) range.
  const moments = [0, 1, 2];
  Plotly.newPlot(
    momentsPlot,
    moments.map((axis) => ({
      type: "scatter",
      mode: "markers+lines",
      name: ["smallest", "middle", "largest"][axis],
      x: scenario.candidates.map((c) => plotText(c.name)),
      y: scenario.candidates.map((c) => c.principal_moments_kg_m2[axis]),
      customdata: scenario.candidates.map((c) => quantity(c.principal_moments_kg_m2[axis], 4)),
      xaxis: "x",
      yaxis: axis === 0 ? "y" : `y${axis + 1}`,
      marker: { color: COLORS[axis], size: 9 },
      line: { color: COLORS[axis], width: 1, dash: "dot" },
      hovertemplate: "%{x}: %{customdata} kg m²<extra>%{fullData.name} moment</extra>",
    })),
    layout("candidate", "", {
      height: 460,
      showlegend: false,
      xaxis: { title: { text: "candidate" }, anchor: "y" },
      yaxis: { title: { text: "smallest" }, domain: [0, 0.29], range: tightRange(scenario.candidates.map((c) => c.principal_moments_kg_m2[0])) },
      yaxis2: { title: { text: "middle" }, domain: [0.355, 0.645], range: tightRange(scenario.candidates.map((c) => c.principal_moments_kg_m2[1])) },
      yaxis3: { title: { text: "largest" }, domain: [0.71, 1], range: tightRange(scenario.candidates.map((c) => c.principal_moments_kg_m2[2])) },
    }),
    PLOT_CONFIG,
  );
}

// How far apart the candidates' principal moments lie, each moment's range over its
// largest value, from the scenario's own candidates: the page said "the candidates differ
// by 5–15 %" (the paper preset's reductions) on every scenario, whatever its candidates.
export function momentsSpreadText(candidates) {
  const spreads = [0, 1, 2].map((axis) => {
    const moments = candidates.map((c) => c.principal_moments_kg_m2[axis]);
    const top = Math.max(...moments);
    return top > 0 ? (100 * (top - Math.min(...moments))) / top : 0;
  });
  const [smallest, middle, largest] = spreads.map((p) => `${quantity(p)} %`);
  return `Each moment on its own scale: from one candidate to another the smallest moment differs by up to ${smallest}, the middle by up to ${middle}, the largest by up to ${largest} (of its largest value).`;
}

// The form: a candidates table, the thruster matrix, levels, timing and noise, all
// prefilled from a preset; the server validates and its messages appear by the fields.
export async function renderNew(root, context) {
  const presets = await api.presets();
  const names = Object.keys(presets);
  const general = h("div", { id: "form-errors" });
  const source = context.query.from ? await api.scenario(context.query.from) : null;
  root.append(h("h1", {}, source ? `New scenario from "${source.name}"` : "New scenario"));

  const presetName = h("input", { id: "preset-name", name: "preset-name", value: "paper preset", size: 30 });
  const presetSelect = h("select", { id: "preset-select" }, names.map((n) => h("option", { value: n }, n)));
  const presetErrors = h("div", { id: "preset-errors" });
  const presetSubmit = h("button", { type: "submit", id: "create-preset" }, "Create from preset");
  const presetForm = h(
    "form",
    {
      class: "toolbar",
      id: "preset-form",
      onsubmit: async (event) => {
        event.preventDefault();
        // One at a time: a submission answered 502/503/504 is sent again after a wait (up
        // to 5 s); Enter pressed meanwhile sent a second one, with a new key: two stored.
        if (presetSubmit.disabled) return;
        presetSubmit.disabled = true;
        clear(presetErrors);
        try {
          const created = await api.createScenario({ preset: presetSelect.value, overrides: { name: presetName.value } });
          location.hash = `#/scenarios/${created.id}`;
        } catch (exc) {
          showError(presetErrors, exc);
        } finally {
          presetSubmit.disabled = false;
        }
      },
    },
    h("label", { for: "preset-select" }, "Preset"),
    presetSelect,
    h("label", { for: "preset-name" }, "name"),
    presetName,
    presetSubmit,
  );
  root.append(h("div", { class: "card" }, h("h2", {}, "Quick start"), presetForm, presetErrors));

  const formCard = h("div", { class: "card" });
  root.append(formCard);
  const fill = (doc, suffix = " (edited)") => {
    clear(formCard);
    formCard.append(h("h2", {}, "Or set every field"), buildForm(doc, general, suffix));
  };
  // A file's document fills the form only if nothing was loaded, chosen or typed since
  // the file was chosen: a slow read landed over a file or preset chosen after it, or
  // over what was typed in the form meanwhile.
  let choices = 0;
  for (const event of ["input", "change"]) formCard.addEventListener(event, () => (choices += 1));
  const uploadErrors = h("div", { id: "upload-errors" });
  const upload = h("input", { type: "file", id: "scenario-file", accept: ".json,application/json" });
  upload.addEventListener("change", async () => {
    const mine = ++choices;
    clear(uploadErrors);
    if (!upload.files.length) return;
    const file = upload.files[0];
    let doc;
    try {
      const text = await file.text();
      if (mine !== choices || !context.alive()) return;
      doc = JSON.parse(text);
    } catch (exc) {
      if (mine !== choices) return;
      uploadErrors.append(messageBox("error", `${file.name} is not JSON: ${exc.message}`));
      return;
    }
    // A document as `inertia-id scenario --out` writes it, or as GET /scenarios/{id} serves it.
    if (doc && doc.document && doc.document.inertia_candidates) doc = doc.document;
    const problem = documentProblem(doc);
    if (problem) {
      uploadErrors.append(messageBox("error", `${file.name} is not a scenario document: ${problem}`));
      return;
    }
    fill(doc, "");
  });
  const loader = h(
    "div",
    { class: "toolbar" },
    h("span", { class: "hint" }, "The form starts from a preset:"),
    names.map((n) => {
      const load = () => {
        choices += 1;
        fill(presets[n]);
      };
      return h("button", { type: "button", class: "secondary", onclick: load }, `load ${n}`);
    }),
    h("label", { for: "scenario-file" }, "or a scenario file (JSON, as inertia-id scenario --out writes):"),
    upload,
  );
  root.insertBefore(loader, formCard);
  root.insertBefore(uploadErrors, formCard);
  if (source) fill(source.document, " (copy)");
  else fill(presets[names[0]]);
}

// Why `doc` cannot fill the form (null if it can): the fields the form reads.
function documentProblem(doc) {
  if (!doc || typeof doc !== "object") return "expected a JSON object";
  if (!Array.isArray(doc.inertia_candidates) || !doc.inertia_candidates.length) {
    return doc.candidate_generator ? "its candidates are generated (candidate_generator): write them out with inertia-id scenario --out first" : "no inertia_candidates list";
  }
  for (const c of doc.inertia_candidates) {
    if (!c || !Array.isArray(c.inertia_kg_m2) || c.inertia_kg_m2.length !== 3) return `candidate ${JSON.stringify(c && c.name)} has no 3 × 3 inertia_kg_m2`;
  }
  const t = doc.thrusters;
  if (!t || !Array.isArray(t.torque_matrix_nm) || !Array.isArray(t.levels)) return "no thrusters.torque_matrix_nm and thrusters.levels";
  if (!doc.timing || !doc.uncertainty) return "no timing or uncertainty section";
  return null;
}

// A candidate row leaves with its message row, if it has one.
function clearRowError(row) {
  const next = row.nextElementSibling;
  if (next && next.classList.contains("field-error")) next.remove();
}

function numberOrText(text) {
  const trimmed = String(text).trim();
  if (trimmed !== "" && Number.isFinite(Number(trimmed))) return Number(trimmed);
  return trimmed;
}

function listOf(text) {
  return String(text)
    .split(/[,\s]+/)
    .filter((v) => v !== "")
    .map(numberOrText);
}

function buildForm(preset, general, suffix = " (edited)") {
  const fields = {};
  const nameInput = h("input", { id: "scenario-name", name: "name", value: `${preset.name}${suffix}`, size: 40 });
  fields.name = nameInput;

  // Candidates: name and the six inertia components.
  const COMPONENTS = [
    ["Ixx", 0, 0],
    ["Iyy", 1, 1],
    ["Izz", 2, 2],
    ["Ixy", 0, 1],
    ["Ixz", 0, 2],
    ["Iyz", 1, 2],
  ];
  const candidateBody = h("tbody", { id: "candidate-rows" });
  const candidateTable = h(
    "table",
    { class: "edit", id: "candidate-form" },
    h("thead", {}, h("tr", {}, h("th", {}, "candidate"), COMPONENTS.map(([n]) => h("th", {}, `${n} (kg m²)`)), h("th", {}, h("span", { class: "visually-hidden" }, "remove")))),
    candidateBody,
  );
  fields.inertia_candidates = candidateTable;
  const addCandidate = (candidate) => {
    const row = h(
      "tr",
      {},
      h("td", {}, h("input", { value: candidate.name, "aria-label": "candidate name", class: "cand-name" })),
      COMPONENTS.map(([n, i, j]) =>
        h("td", {}, h("input", { value: plain(candidate.inertia_kg_m2[i][j], null), "aria-label": n, class: `cand-${n}`, inputmode: "decimal" })),
      ),
      h("td", {}, h("button", { type: "button", class: "secondary", onclick: () => { clearRowError(row); row.remove(); } }, "remove")),
    );
    candidateBody.append(row);
  };
  preset.inertia_candidates.forEach(addCandidate);

  // Thrusters: a 3 × N matrix.
  const matrixHead = h("tr");
  const matrixBody = h("tbody");
  const matrixTable = h("table", { class: "edit matrix", id: "thruster-form" }, h("thead", {}, matrixHead), matrixBody);
  fields["thrusters.torque_matrix_nm"] = matrixTable;
  fields.thrusters = matrixTable;
  let matrix = preset.thrusters.torque_matrix_nm.map((r) => [...r]);
  const readMatrix = () =>
    [...matrixBody.querySelectorAll("tr:not(.field-error)")].map((tr) => [...tr.querySelectorAll("input")].map((input) => numberOrText(input.value)));
  const drawMatrix = () => {
    clear(matrixHead);
    clear(matrixBody);
    matrixHead.append(h("th", {}, "axis (N m)"), ...matrix[0].map((_, j) => h("th", {}, `thruster ${j + 1}`)));
    matrix.forEach((row, i) => {
      matrixBody.append(
        h("tr", {}, h("th", {}, ["x", "y", "z"][i]), row.map((v, j) => h("td", {}, h("input", { value: plain(v, null), "aria-label": `torque ${"xyz"[i]} of thruster ${j + 1}`, inputmode: "decimal" })))),
      );
    });
  };
  drawMatrix();
  const thrusterButtons = h(
    "div",
    { class: "toolbar" },
    h("button", { type: "button", class: "secondary", onclick: () => { matrix = readMatrix().map((r) => [...r, 0]); drawMatrix(); } }, "add thruster"),
    h("button", { type: "button", class: "secondary", onclick: () => { matrix = readMatrix().map((r) => r.slice(0, Math.max(1, r.length - 1))); drawMatrix(); } }, "remove last thruster"),
  );

  const levelsInput = h("input", { id: "levels", name: "levels", value: preset.thrusters.levels.map((v) => plain(v, null)).join(", "), size: 40 });
  fields["thrusters.levels"] = levelsInput;
  // Propulsion: what the propellant figures rest on. A clone or an uploaded file keeps it
  // (the form used to send the matrix and levels alone, and dropped it silently).
  const thrustInput = h("input", { id: "thrust-n", value: listText(preset.thrusters.thrust_n), size: 40, inputmode: "decimal" });
  const leverInput = h("input", { id: "lever-arm-m", value: listText(preset.thrusters.lever_arm_m), size: 40, inputmode: "decimal" });
  const ispInput = h("input", { id: "specific-impulse-s", value: listText(preset.thrusters.specific_impulse_s), inputmode: "decimal" });
  const gravityInput = h("input", { id: "standard-gravity", value: listText(preset.thrusters.standard_gravity_m_s2), inputmode: "decimal" });
  fields["thrusters.thrust_n"] = thrustInput;
  fields["thrusters.lever_arm_m"] = leverInput;
  fields["thrusters.specific_impulse_s"] = ispInput;
  fields["thrusters.standard_gravity_m_s2"] = gravityInput;

  const timingInputs = {};
  for (const [key] of TIMING_FIELDS) {
    timingInputs[key] = h("input", { id: `timing-${key}`, value: plain(preset.timing[key], null), inputmode: "decimal" });
    fields[`timing.${key}`] = timingInputs[key];
  }
  const noiseInputs = {};
  for (const [key] of UNCERTAINTY_FIELDS) {
    const value = preset.uncertainty[key];
    noiseInputs[key] = h("input", { id: `noise-${key}`, value: Array.isArray(value) ? value.map((v) => plain(v, null)).join(", ") : plain(value, null), inputmode: "decimal" });
    fields[`uncertainty.${key}`] = noiseInputs[key];
  }

  const labelled = (input, label, unit) => [h("label", { for: input.id }, label), h("div", {}, input, " ", h("span", { class: "hint" }, unit, input.degrees || ""))];
  // A rate (gyro noise and bias, initial rate) in deg/s too, as the scenario's page gives it
  // and a flight team reads it, kept to what is typed; the form still sends rad/s.
  for (const [key, input] of Object.entries(noiseInputs)) {
    if (!key.endsWith("_rad_s")) continue;
    input.degrees = h("output", { id: `${input.id}-deg`, for: input.id });
    const show = () => {
      // As it is sent: the bias a list, every other rate one value.
      const values = key === "gyro_bias_rad_s" ? listOf(input.value) : input.value.trim() === "" ? [] : [numberOrText(input.value)];
      input.degrees.textContent = values.length && values.every((v) => typeof v === "number") ? ` = ${values.map((v) => quantity(v * DEG_PER_RAD)).join(", ")} deg/s` : "";
    };
    input.addEventListener("input", show);
    show();
  }

  const submit = h("button", { type: "submit", id: "create-scenario" }, "Create scenario");
  const candidateRows = () => [...candidateBody.querySelectorAll("tr:not(.field-error)")];
  const form = h(
    "form",
    {
      id: "scenario-form",
      novalidate: true,
      onsubmit: async (event) => {
        event.preventDefault();
        const document_ = {
          name: nameInput.value,
          // Candidate rows only: a message row (tr.field-error) under a candidate is not one.
          inertia_candidates: candidateRows().map((tr) => {
            const inertia = [
              [0, 0, 0],
              [0, 0, 0],
              [0, 0, 0],
            ];
            for (const [n, i, j] of COMPONENTS) {
              const v = numberOrText(tr.querySelector(`.cand-${n}`).value);
              inertia[i][j] = v;
              inertia[j][i] = v;
            }
            return { name: tr.querySelector(".cand-name").value, inertia_kg_m2: inertia };
          }),
          candidate_generator: null,
          thrusters: {
            torque_matrix_nm: readMatrix(),
            levels: listOf(levelsInput.value),
            thrust_n: perThrusterField(thrustInput.value),
            lever_arm_m: perThrusterField(leverInput.value),
            specific_impulse_s: ispInput.value.trim() === "" ? null : numberOrText(ispInput.value),
            ...(gravityInput.value.trim() === "" ? {} : { standard_gravity_m_s2: numberOrText(gravityInput.value) }),
          },
          timing: Object.fromEntries(Object.entries(timingInputs).map(([k, input]) => [k, numberOrText(input.value)])),
          uncertainty: Object.fromEntries(
            Object.entries(noiseInputs).map(([k, input]) => [k, k === "gyro_bias_rad_s" ? listOf(input.value) : numberOrText(input.value)]),
          ),
        };
        // Rows are located by index: mark the candidate row the server names.
        const rowFields = { ...fields };
        candidateRows().forEach((tr, i) => {
          rowFields[`inertia_candidates.${i}`] = tr;
        });
        submit.disabled = true;
        try {
          const created = await api.createScenario({ scenario: document_ });
          location.hash = `#/scenarios/${created.id}`;
        } catch (exc) {
          showFieldErrors(exc, rowFields, general, form);
          general.scrollIntoView({ block: "nearest" });
        } finally {
          submit.disabled = false;
        }
      },
    },
    h("div", { class: "stack" }, labelled(nameInput, "name", "")),
    h("h3", {}, "Inertia candidates"),
    candidateTable,
    h("div", { class: "toolbar" }, h("button", { type: "button", class: "secondary", onclick: () => addCandidate({ name: `candidate ${candidateRows().length + 1}`, inertia_kg_m2: [[100, 0, 0], [0, 60, 0], [0, 0, 90]] }) }, "add candidate")),
    h("h3", {}, "Thrusters"),
    matrixTable,
    thrusterButtons,
    h("div", { class: "stack" }, labelled(levelsInput, "duty levels", "fractions of full duty, sorted, including 0 and 1")),
    h("h3", {}, "Propulsion (for propellant mass)"),
    h(
      "div",
      { class: "stack" },
      labelled(thrustInput, "thrust", "N: one value for every thruster, or one per thruster; empty when not stated"),
      labelled(leverInput, "lever arm", "m, instead of the thrust (thrust = |torque| / lever arm); empty when not stated"),
      labelled(ispInput, "specific impulse", "s; empty when not stated"),
      labelled(gravityInput, "standard gravity", "m/s²"),
    ),
    h("h3", {}, "Timing"),
    h("div", { class: "stack" }, TIMING_FIELDS.map(([key, label, unit]) => labelled(timingInputs[key], label, unit))),
    h("h3", {}, "Noise (the 1× level of the sweeps)"),
    h("div", { class: "stack" }, UNCERTAINTY_FIELDS.map(([key, label, unit]) => labelled(noiseInputs[key], label, unit))),
    general,
    h("div", { class: "toolbar" }, submit),
  );
  return form;
}
