// A data table over a paged, sorted, filtered API list (GET /jobs, GET /classifiers):
// the server sorts, filters and pages; the table draws one page, its header buttons sort,
// its toolbar filters, its pager pages, and an optional first column selects rows
// (kept across pages and refreshes).
//
// `onState(state)` is told of every sort, filter and page the user chooses.
//
//   const runs = dataTable({
//     id: "job-table",
//     columns: [{ key: "name", label: "run", sort: "name", cell: (job) => ... }, ...],
//     filters: [{ name: "q", label: "search", type: "text" },
//               { name: "status", label: "status", options: [["", "any"], ["running", "running"]] }],
//     load: (query) => api.jobs(query),          // query: {sort, order, limit, offset, ...filters}
//     initial: { sort: "created", order: "desc" },
//     select: { label: (row) => `select ${row.id}`, onChange: (ids) => ... },   // optional
//   });
//   card.append(runs.node); await runs.refresh(); context.every(2000, runs.refresh);
//
// `columns` may be a function of the current filters (columns that depend on a type).

import { clear, h, messageBox } from "../ui.js";

export function dataTable({ id, columns, filters = [], load, initial = {}, pageSize = 25, select = null, empty = "nothing here yet", rowAttrs = () => ({}), onState = null }) {
  const state = { sort: "created", order: "desc", limit: pageSize, offset: 0, ...initial };
  const selected = new Set(select && select.initial ? select.initial : []);
  const head = h("thead");
  const body = h("tbody", { id: `${id}-rows` });
  const count = h("span", { class: "muted", id: `${id}-count` });
  const notice = h("div");
  const prev = h("button", { type: "button", class: "secondary", id: `${id}-prev`, onclick: () => page(-1) }, "‹ previous");
  const next = h("button", { type: "button", class: "secondary", id: `${id}-next`, onclick: () => page(1) }, "next ›");
  let last = { items: [], total: 0 };
  let generation = 0;

  const currentColumns = () => (typeof columns === "function" ? columns(state) : columns);

  const controls = filters.map((filter) => {
    const inputId = `${id}-filter-${filter.name}`;
    let input;
    if (filter.options) {
      input = h("select", { id: inputId }, filter.options.map(([value, label]) => h("option", { value, selected: String(state[filter.name] ?? "") === value }, label)));
      input.addEventListener("change", () => set(filter.name, input.value));
    } else {
      input = h("input", { id: inputId, type: "search", size: filter.size || 16, placeholder: filter.placeholder || "", value: state[filter.name] || "" });
      let timer = null;
      input.addEventListener("input", () => {
        clearTimeout(timer);
        timer = setTimeout(() => set(filter.name, input.value.trim()), 300);
      });
    }
    return h("label", { class: "filter", for: inputId }, h("span", {}, filter.label), input);
  });

  function set(name, value) {
    state[name] = value;
    state.offset = 0;
    refresh({ user: true });
  }

  function page(direction) {
    const offset = state.offset + direction * state.limit;
    if (offset < 0 || offset >= last.total) return;
    state.offset = offset;
    refresh({ user: true });
  }

  function sortBy(key) {
    if (state.sort === key) state.order = state.order === "desc" ? "asc" : "desc";
    else {
      state.sort = key;
      state.order = key === "name" ? "asc" : "desc";
    }
    state.offset = 0;
    refresh({ user: true });
  }

  // What has the keyboard focus in the table (a sort button, a row's checkbox or link),
  // to give it back after the rows are drawn again.
  function focusedPlace() {
    const focused = document.activeElement;
    if (!focused || !(head.contains(focused) || body.contains(focused))) return null;
    const row = focused.closest("tr");
    const cell = focused.closest("td, th");
    return { sort: focused.dataset.sort || null, id: row ? row.dataset.id : null, cell: cell ? cell.cellIndex : -1, tag: focused.tagName };
  }

  function refocus(place) {
    if (!place) return;
    let target = null;
    if (place.sort) target = [...head.querySelectorAll("button[data-sort]")].find((b) => b.dataset.sort === place.sort);
    else if (place.id) {
      const row = [...body.rows].find((r) => r.dataset.id === place.id);
      const cell = row && place.cell >= 0 ? row.cells[place.cell] : null;
      target = cell ? cell.querySelector(place.tag.toLowerCase()) : null;
    }
    if (target) target.focus({ preventScroll: true });
  }

  // Text the user has selected in the table (to copy an id or a name).
  function holdsSelection() {
    const selection = window.getSelection();
    return Boolean(selection && !selection.isCollapsed && selection.rangeCount && node.contains(selection.getRangeAt(0).commonAncestorContainer));
  }

  function drawHead(cols) {
    clear(head);
    const cells = [];
    if (select) cells.push(h("th", { class: "select", scope: "col" }, h("span", { class: "visually-hidden" }, "select")));
    for (const col of cols) {
      const attrs = { scope: "col", class: col.num ? "num" : "" };
      if (col.sort) {
        const active = state.sort === col.sort;
        attrs["aria-sort"] = active ? (state.order === "asc" ? "ascending" : "descending") : "none";
        const arrow = active ? (state.order === "asc" ? " ▲" : " ▼") : "";
        cells.push(h("th", attrs, h("button", { type: "button", class: "sort", "data-sort": col.sort, title: `sort by ${col.label}`, onclick: () => sortBy(col.sort) }, col.label, col.unit ? h("span", { class: "unit" }, ` (${col.unit})`) : null, arrow)));
      } else {
        // A column without a visible title (row actions) still names itself to a screen reader.
        const label = col.label || h("span", { class: "visually-hidden" }, col.key);
        cells.push(h("th", attrs, label, col.unit ? h("span", { class: "unit" }, ` (${col.unit})`) : null));
      }
    }
    head.append(h("tr", {}, cells));
  }

  // `user`: the user sorted, filtered or paged. A poll (no argument) draws nothing when the
  // page is what is shown already, and waits while text in the table is selected: drawn
  // again every 2 s, the rows took the keyboard focus and any selection away.
  let shown = null;
  async function refresh({ user = false } = {}) {
    const mine = ++generation;
    // The page keeps what the user chose (filters, sort, page) in its address.
    if (user && onState) onState({ ...state });
    const query = {};
    for (const [name, value] of Object.entries(state)) if (value !== "" && value !== null && value !== undefined) query[name] = value;
    let data;
    try {
      data = await load(query);
    } catch (exc) {
      if (mine !== generation) return;
      clear(notice);
      notice.append(messageBox("error", exc.message || String(exc)));
      return;
    }
    if (mine !== generation) return;
    clear(notice);
    last = data;
    const cols = currentColumns();
    const signature = JSON.stringify([data, cols.map((c) => c.key), state, [...selected]]);
    if (!user && (signature === shown || holdsSelection())) return;
    shown = signature;
    const place = focusedPlace();
    drawHead(cols);
    clear(body);
    for (const row of data.items) {
      const cells = [];
      if (select) {
        cells.push(
          h(
            "td",
            { class: "select" },
            h("input", {
              type: "checkbox",
              "aria-label": select.label(row),
              checked: selected.has(row.id),
              disabled: select.enabled ? !select.enabled(row) : false,
              onchange: (event) => {
                if (event.target.checked) selected.add(row.id);
                else selected.delete(row.id);
                select.onChange([...selected]);
              },
            }),
          ),
        );
      }
      for (const col of cols) cells.push(h("td", { class: col.num ? "num" : "" }, col.cell(row)));
      body.append(h("tr", { dataset: { id: row.id }, ...rowAttrs(row) }, cells));
    }
    if (!data.items.length) body.append(h("tr", {}, h("td", { colspan: cols.length + (select ? 1 : 0), class: "muted" }, empty)));
    const first = data.total ? state.offset + 1 : 0;
    count.textContent = `${first}–${state.offset + data.items.length} of ${data.total}`;
    prev.disabled = state.offset === 0;
    next.disabled = state.offset + state.limit >= data.total;
    refocus(place);
  }

  const node = h(
    "div",
    { class: "data-table", id },
    filters.length ? h("div", { class: "toolbar filters" }, controls) : null,
    notice,
    h("div", { class: "table-scroll", tabindex: "0", role: "region", "aria-label": `${id} list` }, h("table", { id: `${id}-table` }, head, body)),
    h("div", { class: "toolbar pager" }, prev, next, count),
  );
  return { node, refresh, state, selected };
}
