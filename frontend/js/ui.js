// Small DOM and formatting helpers shared by every page and component: building
// elements, numbers, times (always with their time zone), status badges, messages and
// the service's field errors. Plots live in components/plots.js, tables in
// components/table.js.

// h("div", {class: "card", onclick: fn}, child, "text", [more children])
export function h(tag, attrs = {}, ...children) {
  const node = document.createElement(tag);
  for (const [name, value] of Object.entries(attrs || {})) {
    if (value === undefined || value === null || value === false) continue;
    if (name.startsWith("on") && typeof value === "function") {
      node.addEventListener(name.slice(2), value);
    } else if (name === "dataset") {
      Object.assign(node.dataset, value);
    } else if (value === true) {
      node.setAttribute(name, "");
    } else {
      node.setAttribute(name, String(value));
    }
  }
  append(node, children);
  return node;
}

// Appends children, flattening arrays and skipping null, undefined and false.
export function put(node, ...children) {
  append(node, children);
  return node;
}

function append(node, children) {
  for (const child of children) {
    if (child === undefined || child === null || child === false) continue;
    if (Array.isArray(child)) append(node, child);
    else node.append(child instanceof Node ? child : document.createTextNode(String(child)));
  }
}

export function clear(node) {
  while (node.firstChild) node.removeChild(node.firstChild);
  return node;
}

// Makes `node` read as `wanted` (built afresh to replace it), writing to the DOM only what
// differs: a node equal to `wanted` is left alone; an element of the same tag keeps itself,
// takes `wanted`'s attributes and has its children patched in turn; any other node is
// replaced by `wanted`. Returns the node now in place. Text the user selected, and the
// focus, stay in whatever did not change (a part drawn again whole lost them at each
// poll). For display-only nodes: the listeners on `wanted`'s nodes are not carried over
// to the nodes kept, so a part with listeners is put in whole instead.
export function patch(node, wanted) {
  if (node.isEqualNode(wanted)) return node;
  if (node.nodeType !== wanted.nodeType || node.nodeName !== wanted.nodeName) {
    node.replaceWith(wanted);
    return wanted;
  }
  if (node.nodeType !== Node.ELEMENT_NODE) {
    node.nodeValue = wanted.nodeValue;
    return node;
  }
  for (const name of node.getAttributeNames()) {
    if (!wanted.hasAttribute(name)) node.removeAttribute(name);
  }
  for (const name of wanted.getAttributeNames()) {
    const value = wanted.getAttribute(name);
    if (node.getAttribute(name) !== value) node.setAttribute(name, value);
  }
  const had = [...node.childNodes];
  const comes = [...wanted.childNodes];
  comes.forEach((child, i) => (i < had.length ? patch(had[i], child) : node.append(child)));
  for (const child of had.slice(comes.length)) child.remove();
  return node;
}

// The decimals that show `significant` significant digits of `value` (0 where its
// integer digits already do): with 1, the decimals that resolve a step of `value`.
export function decimalsFor(value, significant) {
  const abs = Math.abs(value);
  if (abs === 0 || !Number.isFinite(abs)) return 0;
  return Math.max(0, significant - 1 - Math.floor(Math.log10(abs)));
}

// A figure with `digits` decimals, but never fewer than `digits` significant digits
// (0.00213, not 0.002: fixed decimals alone left a rate of 2.1e-3 rad/s one digit);
// an integer as one, grouped; below 1e-3 or from 1e6, `digits` significant in
// exponent form.
export function fmt(value, digits = 3) {
  if (value === null || value === undefined || Number.isNaN(value)) return "–";
  if (typeof value !== "number") return String(value);
  if (Object.is(value, -0)) value = 0;
  if (Number.isInteger(value) && Math.abs(value) < 1e6) return value.toLocaleString("en");
  const abs = Math.abs(value);
  if (abs !== 0 && (abs < 1e-3 || abs >= 1e6)) return value.toExponential(digits - 1);
  return value.toFixed(Math.max(digits, decimalsFor(value, digits)));
}

// A physical quantity (impulse, propellant, a rate, an inertia, a duration) to
// `significant` significant digits, where fixed decimals lost them (0.45 N m s read
// 0.5, a residual of 0.0004 deg/s 0.000). A value those digits hold exactly is written
// as it is (0.45, 24, 15 and 0.5 alike: no padding, no bare integer beside padded
// decimals); one rounded to them keeps every digit, zeros included (0.0410 for
// 0.041037, 24.0 for 23.99999); a value with more integer digits keeps them all (1235,
// not 1.23e+3 or 1230).
export function quantity(value, significant = 3) {
  if (typeof value !== "number" || !Number.isFinite(value)) return "–";
  if (value === 0) return "0";
  const text = value.toPrecision(significant);
  if (Number(text) === value) return String(value);
  // Halves away from zero on both signs (Math.round took -1234.5 to -1234, 1234.5 to 1235).
  const whole = Math.sign(value) * Math.round(Math.abs(value));
  return Math.abs(value) >= 10 ** significant || text.includes("e+") ? String(whole) : text;
}

// A rate smaller than this is written 0 on the page: no gyro tells it from rest (1e-9
// deg/s is 3.6e-6 deg/h, under the best gyros' bias stability, about 1e-4 deg/h), while
// thrusters whose torques cancel leave some 1e-16 deg/s of double rounding, which read
// "3.79e-16 deg/s" (a front's figures). A command plan writes its own dust an exact 0,
// against its own scales (inertia_id/search/plan.py DUST_FRACTION).
export const RATE_RESOLUTION_DEG_S = 1e-9;

// A rate in deg/s (or rad/s, with `radians`) as a quantity, or 0 below the resolution.
export function rate(value, { radians = false } = {}) {
  const floor = radians ? (RATE_RESOLUTION_DEG_S * Math.PI) / 180 : RATE_RESOLUTION_DEG_S;
  return typeof value === "number" && Math.abs(value) < floor ? "0" : quantity(value);
}

export const rateDeg = (value) => rate(value);
export const rateRad = (value) => rate(value, { radians: true });

// A measured value ± its standard error: the error to two significant digits (below
// 1e-3 in exponent form, as fmt writes it), the value to the decimal of the error's last
// digit, and to three significant digits where the error is finer still (up to two
// decimals past the error's), so it carries the digits its uncertainty justifies
// (0.002134 ± 7.1e-5, not 0.002 ± 7.1e-5; 100.12 ± 0.53). Without a positive error, the
// value as a quantity.
export function measured(value, std) {
  if (typeof value !== "number" || !Number.isFinite(value)) return "–";
  if (typeof std !== "number" || !Number.isFinite(std) || std <= 0) {
    return std === 0 ? `${quantity(value)} ± 0` : quantity(value);
  }
  const magnitude = Math.max(Math.abs(value), std);
  if (std >= 100 || magnitude < 1e-4) {
    // Too large or too small for fixed decimals (1000000000 ± 12346 kept five digits of
    // its error; 1e-25 read 0.00000000000000000000): both in exponent form, the value's
    // mantissa down to the error's second significant digit.
    const exponent = (v) => Math.floor(Math.log10(Math.abs(v)));
    const digits = value === 0 ? 1 : Math.min(15, Math.max(1, exponent(value) - exponent(std) + 1));
    const shown = value === 0 ? "0" : value.toExponential(digits);
    return `${shown} ± ${std.toExponential(1)}`;
  }
  const byError = decimalsFor(std, 2);
  const decimals = Math.min(20, Math.max(byError, Math.min(decimalsFor(value, 3), byError + 2)));
  const text = value.toFixed(decimals);
  const error = std < 1e-3 ? fmt(std, 2) : std.toFixed(byError);
  return `${Number(text) === 0 ? text.replace("-", "") : text} ± ${error}`;
}

// A value as a person types it: at most `significant` significant digits, trailing zeros
// and the sign of zero dropped (2, 0.25, 1.41421, never -0 or 0.30000000000000004);
// `significant` null keeps every digit (the shortest text that reads back as the value),
// for a form that must give back what it was filled with.
export function plain(value, significant = 6) {
  if (typeof value !== "number" || !Number.isFinite(value)) return String(value);
  const rounded = significant === null ? value : Number(value.toPrecision(significant));
  return Object.is(rounded, -0) || rounded === 0 ? "0" : String(rounded);
}

// A probability as a percentage with two decimals; a tiny or near-certain one says so
// ("< 0.01 %", "> 99.99 %") rather than rounding to 0 or 100 %, which it is not.
export function probability(p) {
  if (typeof p !== "number" || !Number.isFinite(p)) return "–";
  const v = 100 * p;
  if (p > 0 && v < 0.01) return "< 0.01 %";
  if (p < 1 && v > 99.99) return "> 99.99 %";
  return `${v.toFixed(2)} %`;
}

// A score in [0, 1] (F1, accuracy) always with three decimals.
export function score(value) {
  return typeof value === "number" && Number.isFinite(value) ? value.toFixed(3) : "–";
}

export function seconds(value) {
  if (value === null || value === undefined || !Number.isFinite(value)) return "–";
  let s = Math.max(0, value);
  if (s < 60) return `${s.toFixed(s < 10 ? 1 : 0)} s`;
  const minutes = Math.floor(s / 60);
  s = Math.round(s - 60 * minutes);
  if (minutes < 60) return `${minutes} min ${s} s`;
  return `${Math.floor(minutes / 60)} h ${minutes % 60} min`;
}

export function duration(startIso, endIso) {
  if (!startIso) return "–";
  const end = endIso ? new Date(endIso) : new Date();
  return seconds((end - new Date(startIso)) / 1000);
}

const pad = (n) => String(n).padStart(2, "0");

// "2026-12-01 19:54:03 UTC": the service stores every time in UTC.
export function utcText(iso) {
  if (!iso) return "–";
  const d = new Date(iso);
  return `${d.getUTCFullYear()}-${pad(d.getUTCMonth() + 1)}-${pad(d.getUTCDate())} ${pad(d.getUTCHours())}:${pad(d.getUTCMinutes())}:${pad(d.getUTCSeconds())} UTC`;
}

// "2026-12-01 20:54:03 CET": the browser's own time zone, named.
export function localText(iso) {
  if (!iso) return "–";
  const d = new Date(iso);
  const zone = new Intl.DateTimeFormat("en", { timeZoneName: "short" }).formatToParts(d).find((p) => p.type === "timeZoneName");
  return `${d.getFullYear()}-${pad(d.getMonth() + 1)}-${pad(d.getDate())} ${pad(d.getHours())}:${pad(d.getMinutes())}:${pad(d.getSeconds())} ${zone ? zone.value : "local"}`;
}

// A time stamp as an element: UTC, and the local time with its zone beneath.
export function when(iso) {
  if (!iso) return h("span", { class: "muted" }, "–");
  return h("span", { class: "stamp", title: iso }, h("span", { class: "utc" }, utcText(iso)), h("span", { class: "local" }, localText(iso)));
}

// The same on one line, for running text: "… UTC (… CET)".
export function whenText(iso) {
  return iso ? `${utcText(iso)} (${localText(iso)})` : "–";
}

export function statusBadge(status) {
  return h("span", { class: `badge status-${status}` }, status);
}

export function progressBar(fraction, status) {
  const percent = Math.round(100 * Math.min(1, Math.max(0, fraction || 0)));
  return h(
    "div",
    { class: `progress status-${status}`, role: "progressbar", "aria-valuenow": percent, "aria-valuemin": 0, "aria-valuemax": 100, title: `${percent} %` },
    h("div", { class: "progress-fill", style: `width: ${percent}%` }),
    h("span", { class: "progress-text" }, `${percent} %`),
  );
}

// A message box for an error or a notice; `errors` are the service's {loc, msg} items.
export function messageBox(kind, text) {
  return h("div", { class: `message ${kind}`, role: kind === "error" ? "alert" : "status" }, text);
}

// What the service found doubtful but did not refuse (a command plan's or a training's
// `warnings`: a sequence predicted to peak far below the gyro noise): an amber notice
// with each warning's full text, or null when there is none.
export function warningsBox(warnings, id) {
  const shown = (warnings || []).filter((w) => typeof w === "string" && w);
  if (!shown.length) return null;
  return h("div", { class: "message warning", id, role: "status" }, shown.map((w) => h("p", { class: "warning-text" }, `Warning: ${w}`)));
}

export function showError(container, error) {
  clear(container);
  container.append(messageBox("error", error.message || String(error)));
}

// Removes what showFieldErrors put inside `scope` (a form): messages and marks.
export function clearFieldErrors(scope, general = null) {
  for (const old of scope.querySelectorAll(".field-error")) old.remove();
  for (const old of scope.querySelectorAll(".invalid")) old.classList.remove("invalid");
  if (general) clear(general);
}

// Puts each of the service's 422 messages next to the form field its `loc` names, and
// the rest (or all, when no field matches) into `general`. `fields` maps a dotted path
// suffix (e.g. "thrusters.levels" or "inertia_candidates.1") to the element to mark.
// Old messages inside `scope` (default: the document) go first. A table row's message
// goes in a row of its own, marked `.field-error`: a form that reads its rows back skips
// them (`tr:not(.field-error)`).
export function showFieldErrors(error, fields, general, scope = document) {
  clearFieldErrors(scope, general);
  const unplaced = [];
  for (const item of error.errors && error.errors.length ? error.errors : [{ loc: [], msg: error.message }]) {
    const path = item.loc.filter((p) => p !== "body" && p !== "scenario" && p !== "overrides").join(".");
    let best = null;
    for (const [name, element] of Object.entries(fields)) {
      // Also a name within the path: a search's constraint is refused at
      // params.constraints.<its name>, beside the constraints field (it went to the
      // general box, the field unmarked).
      if (path === name || path.startsWith(`${name}.`) || path.endsWith(`.${name}`) || path.includes(`.${name}.`)) {
        if (!best || name.length > best[0].length) best = [name, element];
      }
    }
    if (best) {
      const element = best[1];
      element.classList.add("invalid");
      const note = h("div", { class: "field-error", role: "alert" }, item.msg);
      // A table row gets its message in a row of its own, under it.
      element.after(element.tagName === "TR" ? h("tr", { class: "field-error" }, h("td", { colspan: 99 }, note)) : note);
    } else {
      unplaced.push(item.msg);
    }
  }
  if (unplaced.length) general.append(messageBox("error", unplaced.join("\n")));
}

// A row of tag chips.
export function tagChips(tags) {
  return (tags || []).map((tag) => h("span", { class: "tag" }, tag));
}

// "Copy" of an object for a download or a form: a Blob of pretty JSON.
export function jsonBlob(value) {
  return new Blob([JSON.stringify(value, null, 2)], { type: "application/json" });
}

export function sequenceText(sequence) {
  return JSON.stringify(sequence);
}

// A table from header names and rows of cells (cells may be nodes).
export function table(headers, rows, attrs = {}) {
  return h(
    "table",
    attrs,
    h("thead", {}, h("tr", {}, headers.map((name) => h("th", { scope: "col" }, name)))),
    h("tbody", {}, rows.map((cells) => h("tr", {}, cells.map((cell) => h("td", {}, cell))))),
  );
}

// `content` (a table wider than a phone) scrolling in a region a keyboard can reach and
// a screen reader names (`label`).
export function scrollRegion(label, content) {
  return h("div", { class: "table-scroll", tabindex: "0", role: "region", "aria-label": label }, content);
}

export function link(href, text, attrs = {}) {
  return h("a", { href, ...attrs }, text);
}
