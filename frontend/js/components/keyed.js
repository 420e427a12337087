// A part of a page that only the API key opens (a simulated response, a command plan):
// drawn at once when a key is saved; without one, a notice that says where the key is,
// and drawn when one is saved. An action that needs the key (train, cancel, save labels,
// identify) clicked without one shows the same notice instead of sending its request.
// A request the service is known to refuse is never sent: the browser logs every 401 as
// a console error, and the page would show one per part.

import { KEY_HINT, getApiKey } from "../api.js";
import { messageBox } from "../ui.js";

// Runs `draw()` (what it returns is returned) when a key is saved; else puts the notice
// "<what> needs the API key: …" in `holder` and runs `draw` once a key is saved while
// `holder` is still on the page.
export async function whenKeyed(holder, what, draw) {
  if (getApiKey()) return draw();
  const notice = keyNotice(what);
  holder.append(notice);
  onceKeyed(holder, () => {
    notice.remove();
    draw();
  });
  return null;
}

// Runs `then()` at the first key saved while `holder` is still on the page; listens no
// more once it ran or `holder` left the page.
function onceKeyed(holder, then) {
  const saved = () => {
    if (!holder.isConnected) {
      window.removeEventListener("api-key-changed", saved);
      return;
    }
    if (!getApiKey()) return;
    window.removeEventListener("api-key-changed", saved);
    then();
  };
  window.addEventListener("api-key-changed", saved);
}

// After `draw` failed on `exc`: when the service refused the saved key (a 401; the
// service restarted with a new key, say), runs `draw()` again once a key is saved while
// `holder` is still on the page, as `whenKeyed` does where none was saved. The part had
// stayed on the refusal, "enter the current one at the top right", after the user did
// just that, until the page was reloaded.
export function redrawWhenRekeyed(holder, exc, draw) {
  if (!exc || exc.status !== 401) return;
  onceKeyed(holder, draw);
}

// For an action whose request needs the key: false when a key is saved (go on and send
// it); else true, with the notice "<what> needs the API key: …" in `holder` (one, however
// often it is clicked), which goes once a key is saved: the action then works as usual.
export function withoutKey(holder, what) {
  if (getApiKey()) return false;
  for (const old of holder.querySelectorAll(".needs-key")) old.remove();
  const notice = keyNotice(what);
  holder.append(notice);
  const saved = () => {
    if (notice.isConnected && !getApiKey()) return;
    window.removeEventListener("api-key-changed", saved);
    notice.remove();
  };
  window.addEventListener("api-key-changed", saved);
  return true;
}

function keyNotice(what) {
  const notice = messageBox("notice", `${what} needs the API key: ${KEY_HINT}.`);
  notice.classList.add("needs-key");
  return notice;
}
