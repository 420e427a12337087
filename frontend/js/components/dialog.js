// A confirmation asked in the page (a modal <dialog>), never the browser's confirm():
// it names what will happen, and Escape or "Keep" leaves everything as it was.
//
//   if (await confirmAction({ title: "Cancel job 1a2b3c4d?", text: "...", confirm: "Cancel job" })) ...

import { h } from "../ui.js";

export function confirmAction({ title, text = "", confirm = "Confirm", keep = "Keep it", danger = true }) {
  return new Promise((resolve) => {
    const yes = h("button", { type: "button", class: danger ? "danger" : "", id: "confirm-yes" }, confirm);
    const no = h("button", { type: "button", class: "secondary", id: "confirm-no" }, keep);
    const dialog = h(
      "dialog",
      { class: "confirm", "aria-labelledby": "confirm-title" },
      h("h2", { id: "confirm-title" }, title),
      text ? h("p", {}, text) : null,
      h("div", { class: "toolbar" }, yes, no),
    );
    // Focus goes back where it was (the button that asked), or to the page's main
    // region when that button is gone (a cancel replaces it): never left on <body>.
    const opener = document.activeElement;
    const done = (answer) => {
      dialog.close();
      dialog.remove();
      resolve(answer);
      setTimeout(() => {
        const target = opener && opener.isConnected ? opener : document.getElementById("page");
        if (target) target.focus();
      });
    };
    yes.addEventListener("click", () => done(true));
    no.addEventListener("click", () => done(false));
    dialog.addEventListener("cancel", (event) => {
      event.preventDefault();
      done(false);
    });
    document.body.append(dialog);
    dialog.showModal();
    no.focus();
  });
}
