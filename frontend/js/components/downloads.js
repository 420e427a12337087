// Download buttons: every result a page shows, as files, from the API when it serves
// them (a plain link: downloads need no key) or from data the page holds.
//
//   downloads("search-downloads", [
//     { label: "JSON", href: `/jobs/${id}/result` },
//     { label: "CSV: curve", href: `/jobs/${id}/result?format=csv&table=curve` },
//     { label: "verdict (JSON)", filename: "verdict.json", make: async () => jsonBlob(verdict) },
//   ]);
//
// `jobDownloads(job)` gives a finished job's items from the vocabulary: the whole result
// as JSON, each of its type's tables (GET /vocabulary result_tables) as CSV, and its
// metric series; a new table of a job type appears here without a change.

import { h, messageBox } from "../ui.js";
import { vocabulary } from "../vocabulary.js";

function saveBlob(blob, filename) {
  const url = URL.createObjectURL(blob);
  const a = h("a", { href: url, download: filename, style: "display: none" });
  document.body.append(a);
  a.click();
  a.remove();
  setTimeout(() => URL.revokeObjectURL(url), 1000);
}

export function downloads(id, items, { label = "Download" } = {}) {
  const notice = h("span", { class: "download-notice" });
  const buttons = items.map((item) => {
    if (item.href) return h("a", { class: "button secondary small", href: item.href, download: "", "data-download": item.label }, item.label);
    return h(
      "button",
      {
        type: "button",
        class: "secondary small",
        "data-download": item.label,
        onclick: async () => {
          notice.replaceChildren();
          try {
            saveBlob(await item.make(), item.filename);
          } catch (exc) {
            notice.append(messageBox("error", exc.message || String(exc)));
          }
        },
      },
      item.label,
    );
  });
  return h("div", { class: "toolbar downloads", id, role: "group", "aria-label": label }, h("span", { class: "hint" }, `${label}:`), buttons, notice);
}

export function jobDownloads(job) {
  const base = `/jobs/${encodeURIComponent(job.id)}`;
  const tables = vocabulary().result_tables[job.type] || [];
  return [
    { label: "JSON", href: `${base}/result` },
    ...tables.map((t) => ({ label: `CSV: ${t.name}`, href: `${base}/result?format=csv&table=${t.name}` })),
    { label: "CSV: metrics", href: `${base}/metrics?format=csv` },
  ];
}
