"""The dashboard against a careless or hostile user (a review in Chromium found each of
these): names that Plotly would read as markup, a slow page that the next one was drawn
over, a link to a deleted scenario, a list that took the keyboard focus every 2 s, a
malformed route, a refused key, a phone's width and a vocabulary that failed once.

Each test makes what it needs through the API; no job here runs to the end.
"""

from __future__ import annotations

import json
import re
from collections.abc import Callable
from typing import Any

import pytest
from dashboard_support import API_KEY, Dashboard, axe_violations, one_held

KEY_STORAGE = "inertia-id-api-key"
#: Names a user could type, each of which Plotly would draw as markup if given as is.
HOSTILE = [
    '<a href="https://evil.example/">none ejected</a>',
    "payload 1 ejected",
    '<span style="fill:transparent">payload 2 ejected</span>',
    "payload 3 ejected",
    "<b>payload 3 ejected</b> %{y} & more",
]


def _save_key(dashboard: Dashboard, key: str | None = API_KEY) -> None:
    """Put ``key`` (None: no key) in the page's storage and load the page again, as a
    user's next visit would find it: the page reads the storage when it loads (a change
    made in the page itself fires no "storage" event)."""
    dashboard.page.goto(f"{dashboard.service.base_url}/#/scenarios")
    if key is None:
        dashboard.page.evaluate("k => localStorage.removeItem(k)", KEY_STORAGE)
    else:
        dashboard.page.evaluate("([k, v]) => localStorage.setItem(k, v)", [KEY_STORAGE, key])
    dashboard.page.reload()
    dashboard.page.wait_for_selector("#page h1")


def _scenario(dashboard: Dashboard, names: list[str], name: str = "hostile names") -> str:
    client = dashboard.service.client
    document = client.get("/scenarios/presets").json()["paper"]
    document.pop("candidate_generator")
    document["name"] = name
    document["inertia_candidates"] = [
        {"name": n, "inertia_kg_m2": [[10 + k, 0, 0], [0, 12 + k, 0], [0, 0, 14 + 2 * k]]}
        for k, n in enumerate(names)
    ]
    answer = client.post("/scenarios", json={"scenario": document})
    assert answer.status_code == 201, answer.text
    return str(answer.json()["id"])


def _queued_search(dashboard: Dashboard, scenario_id: str, name: str) -> str:
    """A search job with ``name``, cancelled at once: its page and lists are what count."""
    client = dashboard.service.client
    answer = client.post(
        "/jobs",
        json={
            "type": "search",
            "scenario_id": scenario_id,
            "name": name,
            "rerun": True,
            "params": {"method": "random", "sequence_length": 2, "timesteps": 64},
        },
    )
    assert answer.status_code == 202, answer.text
    job_id = str(answer.json()["id"])
    client.post(f"/jobs/{job_id}/cancel")
    return job_id


def _plot_text(dashboard: Dashboard, plot_id: str) -> dict[str, Any]:
    """What a Plotly chart drew: its text, and any links or styled spans in it."""
    return dict(
        dashboard.page.evaluate(
            """id => {
              const svg = document.getElementById(id);
              return {
                text: [...svg.querySelectorAll('text')].map((t) => t.textContent),
                links: svg.querySelectorAll('.main-svg a').length,
                styled: [...svg.querySelectorAll('tspan[style]')].map((t) => t.textContent),
              };
            }""",
            plot_id,
        )
    )


def test_names_are_drawn_as_written_not_as_plotly_markup(dashboard: Dashboard) -> None:
    _save_key(dashboard)
    scenario_id = _scenario(dashboard, HOSTILE)
    dashboard.open(f"#/scenarios/{scenario_id}")
    dashboard.page.wait_for_selector("#moments-plot .xtick")
    drawn = _plot_text(dashboard, "moments-plot")
    # Each name is a tick label, character for character: no link, no hidden or bold
    # text, no %{y} substituted.
    assert drawn["links"] == 0 and drawn["styled"] == []
    for name in HOSTILE:
        assert name in drawn["text"], (name, drawn["text"])

    job_id = _queued_search(dashboard, scenario_id, '<a href="https://evil.example/">sign in</a>')
    dashboard.open(f"#/compare?type=search&ids={job_id}")
    dashboard.page.wait_for_selector("#compare-reward .main-svg")
    # The curves are empty until the search reports, and Plotly lists no empty trace in
    # a legend: the traces the page made are drawn with a point each, as Plotly would.
    legend = dashboard.page.evaluate(
        """async (id) => {
          const probe = document.createElement('div');
          document.body.append(probe);
          const traces = document.getElementById(id).data.map(
            (t) => ({ x: [0], y: [0], name: t.name, showlegend: true }));
          await Plotly.newPlot(probe, traces, { showlegend: true });
          const out = {
            text: [...probe.querySelectorAll('.legend text')].map((t) => t.textContent),
            links: probe.querySelectorAll('.main-svg a').length,
          };
          Plotly.purge(probe);
          probe.remove();
          return out;
        }""",
        "compare-reward",
    )
    assert legend["links"] == 0
    # A hover shows a trace's name in full: Plotly cut it at 15 characters of the
    # escaped text ("Tank AB & C" read "Tank AB &amp...").
    assert (
        dashboard.page.evaluate(
            "() => document.getElementById('compare-reward')._fullLayout.hoverlabel.namelength"
        )
        == -1
    )
    assert any(
        t.startswith('<a href="https://evil.example/">sign in</a> (') for t in legend["text"]
    )


def test_a_slow_page_is_never_drawn_under_the_next(dashboard: Dashboard) -> None:
    _save_key(dashboard)
    scenario_id = _scenario(dashboard, [*HOSTILE[1:4], "stowed", "deployed"], "slow one")
    page = dashboard.page

    def slow(route: Any) -> None:
        page.wait_for_timeout(3000)
        route.continue_()

    page.route(f"**/scenarios/{scenario_id}", slow)
    page.goto(f"{dashboard.service.base_url}/#/scenarios/{scenario_id}")
    page.wait_for_timeout(300)
    page.evaluate("() => { location.hash = '#/identify' }")
    page.wait_for_selector("#page h1")
    page.wait_for_timeout(4500)  # the scenario's answer has come by now
    headings = page.eval_on_selector_all("#page h1", "nodes => nodes.map((n) => n.textContent)")
    assert headings == ["Identify telemetry"], headings
    page.unroute(f"**/scenarios/{scenario_id}")


def test_a_link_to_a_deleted_scenario_selects_none_and_says_so(dashboard: Dashboard) -> None:
    _save_key(dashboard)
    _scenario(dashboard, [*HOSTILE[1:4], "stowed", "deployed"], "present")
    gone = _scenario(dashboard, [*HOSTILE[1:4], "stowed", "deployed"], "deleted")
    assert dashboard.service.client.delete(f"/scenarios/{gone}").status_code == 204
    dashboard.open(f"#/jobs?scenario={gone}&type=search")
    note = dashboard.page.text_content("#job-form-missing") or ""
    assert f"scenario {gone}" in note and "does not have" in note
    assert dashboard.page.eval_on_selector("#search-scenario", "s => s.value") == ""
    # The form cannot be sent as it stands: the browser asks for a scenario, and nothing
    # is sent to one the user did not choose.
    posted: list[str] = []
    dashboard.page.on("request", lambda r: posted.append(r.url) if r.method == "POST" else None)
    dashboard.page.click("#submit-job")
    assert dashboard.page.eval_on_selector("#search-scenario", "s => s.validity.valueMissing")
    dashboard.page.wait_for_timeout(500)
    assert posted == []
    assert dashboard.service.client.get("/jobs", params={"scenario_id": gone}).json()["total"] == 0


def test_the_job_list_keeps_the_keyboard_focus_and_a_selection(dashboard: Dashboard) -> None:
    _save_key(dashboard)
    scenario_id = _scenario(dashboard, [*HOSTILE[1:4], "stowed", "deployed"], "focus")
    _queued_search(dashboard, scenario_id, "copy my id")
    dashboard.open("#/jobs")
    page = dashboard.page
    page.wait_for_selector("#jobs-rows tr[data-id]")
    page.focus("#jobs button.sort[data-sort='name']")
    page.wait_for_timeout(2600)  # past a poll
    focused = page.evaluate(
        "() => document.activeElement.dataset.sort || document.activeElement.tagName"
    )
    assert focused == "name"
    # Sorting by keyboard still redraws at once.
    page.keyboard.press("Enter")
    page.wait_for_selector("#jobs th[aria-sort='ascending'] button[data-sort='name']")
    assert page.evaluate("() => document.activeElement.dataset.sort") == "name"
    # A selection in the list outlives the polls.
    page.evaluate(
        """() => {
          const cell = document.querySelector('#jobs-rows tr[data-id] td:nth-child(2)');
          const range = document.createRange();
          range.selectNodeContents(cell);
          const s = getSelection();
          s.removeAllRanges();
          s.addRange(range);
        }"""
    )
    selected = page.evaluate("() => getSelection().toString()")
    page.wait_for_timeout(2600)
    assert selected and page.evaluate("() => getSelection().toString()") == selected


def test_a_malformed_route_is_no_page_not_an_uncaught_error(dashboard: Dashboard) -> None:
    dashboard.page.goto(f"{dashboard.service.base_url}/#/jobs/%")
    dashboard.page.wait_for_selector("#page .message.error")
    assert "no page at #/jobs/%" in (dashboard.page.text_content("#page") or "")


def test_a_refused_key_says_what_to_do_in_the_form_and_in_the_key_box(
    dashboard: Dashboard,
) -> None:
    _save_key(dashboard)
    scenario_id = _scenario(dashboard, [*HOSTILE[1:4], "stowed", "deployed"], "keys")
    _save_key(dashboard, None)
    posted: list[str] = []
    dashboard.page.on("request", lambda r: posted.append(r.url) if r.method == "POST" else None)
    dashboard.open(f"#/jobs?scenario={scenario_id}&type=search")
    dashboard.page.click("#submit-job")
    dashboard.page.wait_for_selector("#job-form .message.error")
    shown = dashboard.page.text_content("#job-form") or ""
    assert "missing API key" in shown and "at the top right" in shown
    assert posted == []  # known to be a 401: not sent, so no console error either
    dashboard.console.expect("status of 401")  # the refused key's answer, below
    # A key the service has stopped accepting: the box no longer says "saved".
    _save_key(dashboard, "an-old-key-" + "x" * 30)
    dashboard.open(f"#/jobs?scenario={scenario_id}&type=search")
    assert dashboard.page.text_content("#api-key-state") == "saved"
    dashboard.page.click("#submit-job")
    dashboard.page.wait_for_selector("#job-form .message.error")
    assert "the saved API key was refused" in (dashboard.page.text_content("#job-form") or "")
    assert (
        dashboard.page.text_content("#api-key-state") == "saved key refused: enter the current one"
    )
    _save_key(dashboard)


@pytest.mark.without_api_key
def test_a_key_checked_slowly_keeps_what_is_typed_next_and_the_later_keys_answer(
    dashboard: Dashboard,
) -> None:
    # The key box checks a key (GET /auth/check) before saving it. A slow answer emptied
    # the box the user had gone on typing in, and an answer for a key entered before the
    # last one said "wrong key" over the later one's "saved". The checks are held here.
    dashboard.console.expect("status of 401")
    page = dashboard.page
    dashboard.open("#/scenarios")
    held: list[Any] = []
    page.route("**/auth/check", lambda route: held.append(route))

    def enter(key: str) -> Any:
        page.fill("#api-key", key)
        page.press("#api-key", "Enter")
        return one_held(page, held)

    def answered(check: Any) -> None:
        with page.expect_response("**/auth/check"):
            check.continue_()
        # The page's handler of that answer runs before the next task: a round trip.
        page.evaluate("() => new Promise((done) => setTimeout(done, 100))")

    saved = "() => document.getElementById('api-key-state').textContent === 'saved'"
    try:
        right = enter(API_KEY)
        page.fill("#api-key", "being typed")
        answered(right)
        page.wait_for_function(saved)
        assert page.input_value("#api-key") == "being typed"
        wrong = enter("a-wrong-key-" + "x" * 30)
        right = enter(API_KEY)
        answered(right)
        page.wait_for_function(saved)
        answered(wrong)
        assert page.text_content("#api-key-state") == "saved"
        stored = page.evaluate("k => localStorage.getItem(k)", KEY_STORAGE)
        assert stored == API_KEY
    finally:
        page.unroute("**/auth/check")


@pytest.mark.parametrize("route", ["#/jobs", "#/identify", "#/scenarios/new"])
def test_a_phone_wide_window_does_not_widen_the_page(dashboard: Dashboard, route: str) -> None:
    dashboard.page.set_viewport_size({"width": 375, "height": 800})
    dashboard.open(route)
    dashboard.page.wait_for_load_state("networkidle")
    width = dashboard.page.evaluate("() => document.documentElement.scrollWidth")
    widest = dashboard.page.evaluate(
        """() => [...document.querySelectorAll('body *')]
          .filter((e) => e.getBoundingClientRect().right > 376)
          .filter((e) => !e.closest('.table-scroll'))
          .slice(0, 6)
          .map((e) => {
            const right = Math.round(e.getBoundingClientRect().right);
            return `${e.tagName.toLowerCase()}#${e.id}.${e.className}: ${right}`;
          })"""
    )
    assert width <= 375, f"{route} is {width} px wide in a 375 px window: {widest}"
    for selector in ("nav a[data-nav='identify']", "#api-key"):
        box = dashboard.page.locator(selector).bounding_box()
        assert box is not None and box["x"] + box["width"] <= 375, (selector, box)


def test_a_classifier_of_a_long_sequence_does_not_widen_the_identify_page(
    dashboard: Dashboard,
) -> None:
    """The classifier menu names each classifier's sequence: one of 12 steps made the
    menu 1,322 px wide (an 8-step one), and a 1,280 px laptop window scrolled sideways,
    the ends of the form's hints out of sight. The menu now keeps to its column."""
    client = dashboard.service.client
    scenario = client.post("/scenarios", json={"preset": "paper"})
    assert scenario.status_code == 201, scenario.text
    sequence = [[4, 4, 4, 0, 0, 0], [0, 0, 0, 4, 4, 4]] * 6
    params = {"sequence": sequence, "kind": "nearest-centroid", "n_realisations": 5}
    submitted = client.post(
        "/jobs",
        json={"type": "train", "scenario_id": scenario.json()["id"], "seed": 0, "params": params},
    )
    assert submitted.status_code == 202, submitted.text
    job_id = submitted.json()["id"]
    job = dashboard.service.until(
        lambda: (j := dashboard.service.job(job_id))["status"] in ("succeeded", "failed") and j,
        300,
        "the training finished",
    )
    assert job["status"] == "succeeded", job["error"]
    dashboard.page.set_viewport_size({"width": 1280, "height": 800})
    dashboard.open(f"#/identify?classifier={job['result']['classifier_id']}")
    dashboard.page.wait_for_load_state("networkidle")
    width = dashboard.page.evaluate("() => document.documentElement.scrollWidth")
    assert width <= 1280, f"#/identify is {width} px wide in a 1280 px window"
    menu = dashboard.page.locator("#identify-classifier").bounding_box()
    assert menu is not None and menu["x"] + menu["width"] <= 1280, menu


def test_a_vocabulary_that_failed_once_is_read_again_at_the_next_link(
    dashboard: Dashboard,
) -> None:
    page = dashboard.page
    dashboard.console.expect("Failed to load resource")
    page.route("**/vocabulary", lambda route: route.fulfill(status=503, body="busy"))
    page.goto(f"{dashboard.service.base_url}/#/jobs")
    page.wait_for_selector("#page .message.error")
    assert "vocabulary could not be read" in (page.text_content("#page") or "")
    page.unroute("**/vocabulary")
    page.click("nav a[data-nav='scenarios']")
    page.wait_for_selector("#page h1")
    assert page.text_content("#page h1") == "Scenarios"


def test_a_job_page_says_when_the_service_stops_answering(dashboard: Dashboard) -> None:
    """It went on saying "running", the failed polls in the console alone."""
    import json

    _save_key(dashboard)
    scenario_id = _scenario(dashboard, [*HOSTILE[1:4], "stowed", "deployed"], "polls")
    job_id = _queued_search(dashboard, scenario_id, "followed")
    page = dashboard.page
    dashboard.console.expect("Failed to load resource")

    def running(route: Any) -> None:
        answer = route.fetch()
        job = answer.json()
        job["status"], job["finished_at"] = "running", None
        route.fulfill(response=answer, body=json.dumps(job))

    pattern = f"**/jobs/{job_id}"
    page.route(pattern, running)
    dashboard.open(f"#/jobs/{job_id}")
    page.unroute(pattern)
    page.route(pattern, lambda route: route.abort())
    page.wait_for_selector("#poll-state .message.error", timeout=10_000)
    assert "Not updated since" in (page.text_content("#poll-state") or "")
    page.unroute(pattern)
    page.wait_for_function("() => !document.querySelector('#poll-state .message')")


def _as_running(answer: Any) -> str:
    """A job's answer as a job still running would give it (the page keeps polling)."""
    job = answer.json()
    job["status"], job["finished_at"], job["result"] = "running", None, None
    return json.dumps(job)


def _running_on(renamed_after: int | None = None) -> Callable[[Any], None]:
    """A route handler that answers a job's GETs as running, its run time moved on at
    each answer (60 s plus the answer's count) and its cancel not yet asked (the button
    takes the focus: disabled, it would not); past ``renamed_after`` answers, renamed and
    retagged elsewhere. Other methods (a save) go through."""
    answers = [0]

    def running(route: Any) -> None:
        if route.request.method != "GET":
            route.continue_()
            return
        answer = route.fetch()
        job = json.loads(_as_running(answer))
        answers[0] += 1
        job["started_at"], job["run_time_s"] = job["created_at"], 60.0 + answers[0]
        job["cancel_requested"] = False
        if renamed_after is not None and answers[0] > renamed_after:
            job["name"], job["tags"] = "renamed elsewhere", ["elsewhere"]
        route.fulfill(response=answer, body=json.dumps(job))

    return running


def _two_polls(dashboard: Dashboard, job_id: str) -> None:
    """Wait for the job page's next two polls of the job to be answered and handled."""
    page = dashboard.page
    for _ in range(2):
        with page.expect_response(lambda r: r.url.endswith(f"/jobs/{job_id}")):
            pass
        # The page's handler of that answer runs before the next task: a round trip.
        page.evaluate("() => new Promise((done) => setTimeout(done, 100))")


def test_labels_saved_while_a_poll_is_answered_are_not_put_back_by_its_answer(
    dashboard: Dashboard,
) -> None:
    # A running job's page polls GET /jobs/{id}. A poll sent before the labels were saved
    # and answered after drew the old name and tags back into the header. That poll is
    # held here (answered with the job as it was before) until the save has been drawn.
    _save_key(dashboard)
    scenario_id = _scenario(dashboard, ["stowed", "deployed"], "labels and polls")
    job_id = _queued_search(dashboard, scenario_id, "before the save")
    page = dashboard.page
    held: list[Any] = []
    holding = [False]

    def running(route: Any) -> None:
        if route.request.method != "GET":
            route.continue_()
        elif holding[0]:
            held.append(route)
        else:
            answer = route.fetch()
            route.fulfill(response=answer, body=_as_running(answer))

    pattern = f"**/jobs/{job_id}"
    page.route(pattern, running)
    try:
        dashboard.open(f"#/jobs/{job_id}")
        page.wait_for_selector("#job-name", state="attached")
        holding[0] = True
        with page.expect_request(lambda r: r.url.endswith(f"/jobs/{job_id}")):
            pass
        slow = one_held(page, held)
        holding[0] = False
        answer = slow.fetch()  # the job as it was before the save
        page.click("#job-header summary >> text=name and tags")
        page.fill("#job-name", "after the save")
        page.fill("#job-tags", "saved")
        page.click("#save-labels")
        page.wait_for_function(
            "() => document.querySelector('h1').textContent.includes('after the save')"
        )
        assert answer.json()["name"] == "before the save"
        with page.expect_response(lambda r: r.url.endswith(f"/jobs/{job_id}")):
            slow.fulfill(response=answer, body=_as_running(answer))
        # The page's handler of that answer runs before the next task: a round trip.
        page.evaluate("() => new Promise((done) => setTimeout(done, 100))")
        assert page.input_value("#job-name") == "after the save"
        assert page.inner_text("#job-header .tag") == "saved"
    finally:
        page.unroute(pattern)


def test_a_running_jobs_parameters_opened_stay_open_through_its_polls(
    dashboard: Dashboard,
) -> None:
    # A running job's header is drawn again at every poll: the "parameters" the user had
    # opened closed every 2 s.
    _save_key(dashboard)
    scenario_id = _scenario(dashboard, ["stowed", "deployed"], "open parameters")
    job_id = _queued_search(dashboard, scenario_id, "parameters read")
    page = dashboard.page

    def running(route: Any) -> None:
        answer = route.fetch()
        route.fulfill(response=answer, body=_as_running(answer))

    pattern = f"**/jobs/{job_id}"
    page.route(pattern, running)
    try:
        dashboard.open(f"#/jobs/{job_id}")
        page.click("#job-header summary >> text=parameters")
        assert page.is_visible("#job-header pre")
        _two_polls(dashboard, job_id)
        assert page.is_visible("#job-header pre")
        assert '"method": "random"' in page.inner_text("#job-header pre")
    finally:
        page.unroute(pattern)


def test_a_running_jobs_header_keeps_a_selection_and_the_focus_through_its_polls(
    dashboard: Dashboard,
) -> None:
    # A running job's header was cleared and drawn again at every poll (2 s): the job id
    # the user had selected to copy was lost, and the focus left the cancel button. Only
    # what changed is written now: here the run time, which each answer moves on.
    # Before: the selection read '' after the first poll.
    _save_key(dashboard)
    scenario_id = _scenario(dashboard, ["stowed", "deployed"], "header selection")
    job_id = _queued_search(dashboard, scenario_id, "selected")
    page = dashboard.page
    pattern = f"**/jobs/{job_id}"
    page.route(pattern, _running_on())
    try:
        dashboard.open(f"#/jobs/{job_id}")
        page.wait_for_selector("#cancel-job")
        selected = page.evaluate(
            """() => {
                const range = document.createRange();
                range.selectNodeContents(document.querySelector('#job-header dd code'));
                getSelection().removeAllRanges();
                getSelection().addRange(range);
                return getSelection().toString();
            }"""
        )
        assert selected == job_id
        ran = page.inner_text("#job-duration")
        _two_polls(dashboard, job_id)
        assert page.evaluate("() => getSelection().toString()") == job_id
        assert page.inner_text("#job-duration") != ran, "the run time was not drawn again"
        page.focus("#cancel-job")
        _two_polls(dashboard, job_id)
        assert page.evaluate("() => document.activeElement?.id") == "cancel-job"
    finally:
        page.unroute(pattern)


def test_a_running_jobs_status_and_run_time_update_while_its_labels_are_edited(
    dashboard: Dashboard,
) -> None:
    # The whole header's redraw was skipped while the name-and-tags editor was open: the
    # run time stood still, and a job that went on running read as it was when the user
    # began typing. Only the editor is left alone now (a poll with other labels, another
    # client's rename, would have put it in anew, the text typed lost).
    # Before: the run time read as before the two polls.
    _save_key(dashboard)
    scenario_id = _scenario(dashboard, ["stowed", "deployed"], "labels while running")
    job_id = _queued_search(dashboard, scenario_id, "editing")
    page = dashboard.page
    pattern = f"**/jobs/{job_id}"
    page.route(pattern, _running_on(renamed_after=1))
    try:
        dashboard.open(f"#/jobs/{job_id}")
        page.wait_for_selector("#cancel-job")
        page.click("#job-header summary >> text=name and tags")
        page.fill("#job-name", "typed, not saved")
        page.focus("#job-name")
        ran = page.inner_text("#job-duration")
        _two_polls(dashboard, job_id)
        assert page.inner_text("#job-duration") != ran, "the run time was not drawn again"
        assert page.inner_text("#job-header .tag") == "elsewhere"
        assert page.is_visible("#job-name")
        assert page.input_value("#job-name") == "typed, not saved"
        assert page.evaluate("() => document.activeElement?.id") == "job-name"
    finally:
        page.unroute(pattern)


def test_compare_names_ids_it_does_not_know(dashboard: Dashboard) -> None:
    dashboard.console.expect("status of 404")
    dashboard.open("#/compare?type=search&ids=zzz")
    dashboard.page.wait_for_selector("#page .message")
    text = dashboard.page.text_content("#page") or ""
    assert "No search run has the id zzz (unknown, deleted, or a run of another type)" in text


def test_the_job_lists_filters_and_sort_survive_a_reload_and_back(dashboard: Dashboard) -> None:
    """Reload or Back from a job returned the list to page 1, sorted by created, with
    every filter cleared."""
    _save_key(dashboard)
    scenario_id = _scenario(dashboard, [*HOSTILE[1:4], "stowed", "deployed"], "kept list")
    job_id = _queued_search(dashboard, scenario_id, "kept")
    page = dashboard.page
    dashboard.open("#/jobs")
    page.wait_for_selector("#jobs-rows tr[data-id]")
    page.select_option("#jobs-filter-status", "cancelled")
    page.click("#jobs button.sort[data-sort='name']")
    page.wait_for_function("() => location.hash.includes('list_sort=name')")
    assert "list_status=cancelled" in page.evaluate("() => location.hash")
    page.reload()
    page.wait_for_selector("#jobs-rows tr[data-id]")
    assert page.eval_on_selector("#jobs-filter-status", "s => s.value") == "cancelled"
    assert page.locator("#jobs th[aria-sort='ascending'] button[data-sort='name']").count() == 1
    statuses = page.eval_on_selector_all(
        "#jobs-rows tr[data-id]", "rows => rows.map((r) => r.dataset.status)"
    )
    assert statuses and set(statuses) == {"cancelled"}
    page.click(f"#jobs-rows tr[data-id='{job_id}'] a")
    page.wait_for_function("id => location.hash.startsWith(`#/jobs/${id}`)", arg=job_id)
    page.go_back()
    page.wait_for_selector("#jobs-rows tr[data-id]")
    assert page.eval_on_selector("#jobs-filter-status", "s => s.value") == "cancelled"


@pytest.mark.parametrize("width", [1440, 375])
def test_every_page_passes_axe_core(dashboard: Dashboard, width: int) -> None:
    """An audit with axe-core found low-contrast progress figures, unnamed table columns,
    a table that scrolled out of a keyboard's reach and a skipped heading level. At a
    phone's width too: there a scenario's candidates table (its tensors) ran past its
    card, which scrolled with no way for a keyboard to reach it."""
    dashboard.page.set_viewport_size({"width": width, "height": 900})
    _save_key(dashboard)
    scenario_id = _scenario(dashboard, [*HOSTILE[1:4], "stowed", "deployed"], "audited")
    job_id = _queued_search(dashboard, scenario_id, "audited search")
    routes = [
        "#/scenarios",
        f"#/scenarios/{scenario_id}",
        "#/scenarios/new",
        "#/jobs?type=search",
        "#/jobs?type=train",
        "#/jobs?type=sweep",
        f"#/jobs/{job_id}",
        "#/classifiers",
        f"#/compare?type=search&ids={job_id}",
        "#/identify",
    ]
    found = {}
    for route in routes:
        dashboard.open(route)
        dashboard.page.wait_for_load_state("networkidle")
        problems = axe_violations(dashboard)
        if problems:
            found[route] = problems
    assert found == {}, "\n".join(f"{r}: {p}" for r, p in found.items())


def test_the_confirm_dialog_gives_the_focus_back(dashboard: Dashboard) -> None:
    """Closing it with its buttons left the focus on <body> when the list had redrawn the
    row that opened it (a running job's row changes at every poll)."""
    _save_key(dashboard)
    scenario_id = _scenario(dashboard, [*HOSTILE[1:4], "stowed", "deployed"], "dialog")
    client = dashboard.service.client
    params = {"method": "random", "sequence_length": 4, "timesteps": 20480}
    answer = client.post(
        "/jobs",
        json={"type": "search", "scenario_id": scenario_id, "params": params, "rerun": True},
    )
    job_id = answer.json()["id"]
    page = dashboard.page
    try:
        dashboard.open("#/jobs")
        button = f"#jobs-rows tr[data-id='{job_id}'] button.danger"
        page.wait_for_selector(button)
        page.focus(button)
        page.keyboard.press("Enter")
        page.wait_for_selector("#confirm-no")
        page.wait_for_timeout(2500)  # a poll redraws the row behind the dialog
        page.keyboard.press("Enter")  # "Keep it running": the focused, safe choice
        page.wait_for_function("() => !document.querySelector('dialog.confirm')")
        page.wait_for_timeout(300)
        assert page.evaluate("() => document.activeElement !== document.body")
    finally:
        client.post(f"/jobs/{job_id}/cancel")


def test_the_keyboard_skips_the_header_and_moves_between_form_tabs(dashboard: Dashboard) -> None:
    """No skip link put eight header stops before every page's content, and the job
    form's tabs were three Tab stops that no arrow key moved between."""
    _save_key(dashboard)
    _scenario(dashboard, [*HOSTILE[1:4], "stowed", "deployed"], "keyboard")
    page = dashboard.page
    dashboard.open("#/jobs")
    page.keyboard.press("Tab")
    assert page.evaluate("() => document.activeElement.id") == "skip-link"
    page.keyboard.press("Enter")
    assert page.evaluate("() => document.activeElement.id") == "page"
    assert page.evaluate("() => location.hash") == "#/jobs"
    page.focus("#tab-search")
    page.keyboard.press("ArrowRight")
    assert page.evaluate("() => document.activeElement.id") == "tab-train"
    assert page.get_attribute("#tab-train", "aria-selected") == "true"
    assert page.get_attribute("#job-form-panel", "aria-labelledby") == "tab-train"
    page.keyboard.press("End")
    assert page.evaluate("() => document.activeElement.id") == "tab-sweep"
    page.keyboard.press("ArrowRight")  # wraps around
    assert page.evaluate("() => document.activeElement.id") == "tab-search"
    # One Tab stop for the list: Tab leaves it for the chosen panel.
    assert [page.get_attribute(f"#tab-{t}", "tabindex") for t in ("search", "train", "sweep")] == [
        "0",
        "-1",
        "-1",
    ]


def test_a_key_saved_or_removed_in_another_tab_shows_in_this_one(dashboard: Dashboard) -> None:
    """Two tabs of the dashboard: the key entered in one is the key the other sends (both
    read the same storage), so the other's key box says so without a reload. Before, it
    kept saying "not set" while its requests carried the key."""
    _save_key(dashboard, None)
    dashboard.open("#/scenarios")
    assert dashboard.page.text_content("#api-key-state") == "not set"
    other = dashboard.page.context.new_page()
    try:
        other.set_default_timeout(30_000)
        other.goto(f"{dashboard.service.base_url}/#/scenarios")
        other.wait_for_selector("#page h1")
        other.fill("#api-key", API_KEY)
        other.click("#api-key-form button")
        other.wait_for_function(
            "() => document.getElementById('api-key-state').textContent === 'saved'"
        )
        dashboard.page.wait_for_function(
            "() => document.getElementById('api-key-state').textContent === 'saved'"
        )
        other.fill("#api-key", "")
        other.click("#api-key-form button")
        dashboard.page.wait_for_function(
            "() => document.getElementById('api-key-state').textContent === 'not set'"
        )
    finally:
        other.close()
    _save_key(dashboard)


def test_the_health_badge_says_which_worker_is_warming_up(dashboard: Dashboard) -> None:
    """/health lists a worker whose task process is being replaced as warming (status
    still ok); the badge said "ok · 1 worker" and its tooltip named it as any other."""
    service = dashboard.service
    answer = service.client.get("/health").json()
    name = "celery@replaced"
    answer["workers"] |= {
        "count": 1,
        "names": [name],
        "warming": [{"name": name, "warming_s": 7.4}],
    }
    dashboard.page.route(
        f"{service.base_url}/health",
        lambda route: route.fulfill(
            status=200, content_type="application/json", body=json.dumps(answer)
        ),
    )
    dashboard.open("#/scenarios")
    badge = dashboard.page.locator("#health")
    dashboard.page.wait_for_function(
        "() => document.getElementById('health').textContent.includes('warming')"
    )
    assert badge.text_content() == f"{answer['status']} · 1 worker (1 warming up)"
    assert f"workers: {name} (warming up, 7 s)" in (badge.get_attribute("title") or "")
    # A worker without its incarnation lock is named as one that takes no job.
    answer["workers"] |= {
        "warming": [],
        "without_lock": [{"name": name, "without_lock_s": 12.2}],
    }
    dashboard.page.reload()
    dashboard.page.wait_for_function(
        "() => document.getElementById('health').title.includes('without its lock')"
    )
    assert f"workers: {name} (without its lock for 12 s: takes no job)" in (
        badge.get_attribute("title") or ""
    )
    dashboard.page.unroute(f"{service.base_url}/health")


def test_run_it_again_sent_twice_makes_one_new_job(dashboard: Dashboard) -> None:
    # Two tabs on the same "Reused an earlier result" notice, or a click sent again: the
    # rerun names the job it replaces (rerun_of), so the second is handed the first's job
    # (before: a `rerun: true` alone, and the second click made and ran a second job).
    _save_key(dashboard)
    client = dashboard.service.client
    scenario_id = _scenario(dashboard, ["stowed", "deployed", "ejected"], "clicked twice")
    body = {
        "type": "search",
        "scenario_id": scenario_id,
        "params": {"method": "random", "sequence_length": 2, "timesteps": 64},
    }
    answer = client.post("/jobs", json=body)
    assert answer.status_code == 202, answer.text
    standing = str(answer.json()["id"])
    first, second = dashboard.page, dashboard.page.context.new_page()
    route = f"{dashboard.service.base_url}/#/jobs/{standing}?reused=1"
    for page in (first, second):
        page.goto(route)
        page.wait_for_selector("#reused-notice #rerun-job")
    made, bodies = [], []
    for page in (first, second):
        with page.expect_response(
            lambda r: r.url.endswith("/jobs") and r.request.method == "POST"
        ) as sent:
            page.click("#rerun-job")
        bodies.append(sent.value.request.post_data_json)
        page.wait_for_function("id => !location.hash.includes(id)", arg=standing)
        made.append((sent.value.status, page.url.split("#/jobs/")[1].split("?")[0]))
    second.close()
    fresh = made[0][1]
    assert made == [(202, fresh), (200, fresh)], made
    assert fresh != standing
    assert [(b["rerun"], b.get("rerun_of")) for b in bodies] == [(True, standing)] * 2
    listed = client.get("/jobs", params={"scenario_id": scenario_id, "limit": 50}).json()
    assert sorted(job["id"] for job in listed["items"]) == sorted([standing, fresh])
    for job_id in (standing, fresh):
        client.post(f"/jobs/{job_id}/cancel")


def _answering(body: str) -> Callable[[Any], None]:
    """A route handler that answers 200 with the JSON ``body``."""

    def answer(route: Any) -> None:
        route.fulfill(status=200, content_type="application/json", body=body)

    return answer


def test_a_submission_handed_a_job_still_running_says_so_not_reused_result(
    dashboard: Dashboard,
) -> None:
    """A job still queued or running has no result: the notice said "Reused an earlier
    result" for it too (a plain submission or rerun is handed the run under way)."""
    _save_key(dashboard)
    client = dashboard.service.client
    scenario_id = _scenario(dashboard, ["stowed", "deployed", "ejected"], "still running")
    answer = client.post(
        "/jobs",
        json={
            "type": "search",
            "scenario_id": scenario_id,
            "params": {"method": "random", "sequence_length": 2, "timesteps": 64},
        },
    )
    assert answer.status_code == 202, answer.text
    job_id = str(answer.json()["id"])
    client.post(f"/jobs/{job_id}/cancel")
    page = dashboard.page
    for status, words, button in (
        ("running", "Handed the identical job", "Start a second run anyway"),
        ("queued", "Handed the identical job", "Start a second run anyway"),
        ("succeeded", "Reused an earlier result", "Run it again"),
    ):
        shown = client.get(f"/jobs/{job_id}").json() | {"status": status}
        url = f"{dashboard.service.base_url}/jobs/{job_id}"
        page.route(url, _answering(json.dumps(shown)))
        try:
            page.goto("about:blank")  # the same route opened again would draw nothing new
            page.goto(f"{dashboard.service.base_url}/#/jobs/{job_id}?reused=1")
            notice = page.wait_for_selector("#reused-notice #rerun-job")
            text = page.inner_text("#reused-notice")
            assert words in text, (status, text)
            assert f"still {status}" in text or status == "succeeded", (status, text)
            assert notice.inner_text() == button, (status, notice.inner_text())
        finally:
            page.unroute(url)


def test_the_health_badge_names_a_worker_whose_process_is_gone(dashboard: Dashboard) -> None:
    """/health lists a killed worker (its incarnation lock free) apart, in workers.gone,
    neither counted nor named as live; the badge's tooltip named warming and lockless
    workers but said nothing of a gone one."""
    service = dashboard.service
    answer = service.client.get("/health").json()
    answer["workers"] |= {
        "count": 1,
        "names": ["celery@restarted"],
        "gone": [{"name": "celery@killed", "silent_s": 9.6}],
    }
    dashboard.page.route(
        f"{service.base_url}/health",
        lambda route: route.fulfill(
            status=200, content_type="application/json", body=json.dumps(answer)
        ),
    )
    try:
        dashboard.open("#/scenarios")
        badge = dashboard.page.locator("#health")
        dashboard.page.wait_for_function(
            "() => document.getElementById('health').title.includes('workers:')"
        )
        title = badge.get_attribute("title") or ""
        assert "workers: celery@restarted\n" in title, title
        assert title.endswith(
            "\ngone: celery@killed (process gone, its lock free; last beat 10 s ago)"
        ), title
        assert badge.text_content() == f"{answer['status']} · 1 worker"
    finally:
        dashboard.page.unroute(f"{service.base_url}/health")


def test_the_health_badge_says_the_workers_are_unknown_while_writes_are_refused(
    dashboard: Dashboard,
) -> None:
    """While the database refuses writes their beats are refused too: /health says the
    workers' state is unknown since their last stored beat. The badge said "degraded · 0
    workers" and its tooltip "workers: none seen" while they beat on."""
    service = dashboard.service
    answer = service.client.get("/health").json()
    detail = (
        "the workers' state is unknown since 2026-12-05T22:05:29Z (their last beat stored): "
        "the database refuses writes, their heartbeats included; live then: w1@vm"
    )
    answer["status"] = "degraded"
    answer["workers"] |= {
        "ok": False,
        "count": 0,
        "names": [],
        "state_unknown_since": "2026-12-05T22:05:29.365099Z",
        "last_known": ["w1@vm"],
        "detail": detail,
    }
    dashboard.page.route(
        f"{service.base_url}/health",
        lambda route: route.fulfill(
            status=200, content_type="application/json", body=json.dumps(answer)
        ),
    )
    try:
        dashboard.open("#/scenarios")
        badge = dashboard.page.locator("#health")
        dashboard.page.wait_for_function(
            "() => document.getElementById('health').title.includes('workers:')"
        )
        title = badge.get_attribute("title") or ""
        assert title.endswith(f"\nworkers: {detail}"), title
        assert badge.text_content() == "degraded · workers unknown"
    finally:
        dashboard.page.unroute(f"{service.base_url}/health")


def test_broken_json_in_an_overrides_box_is_named_before_anything_is_sent(
    dashboard: Dashboard,
) -> None:
    # Sent as typed, "{bad" came back "Input should be a valid dictionary, got '{bad'":
    # now the form says the box's JSON is broken, and why, and sends nothing.
    _save_key(dashboard)
    scenario_id = _scenario(dashboard, ["stowed", "deployed", "ejected"], "broken json")
    dashboard.open(f"#/jobs?scenario={scenario_id}&type=search")
    page = dashboard.page
    posted: list[str] = []
    page.on("request", lambda r: posted.append(r.url) if r.method == "POST" else None)
    for method, box, label in (
        ("ppo", "#search-ppo", "PPO overrides"),
        ("nsga2", "#search-nsga2", "NSGA-II settings"),
    ):
        page.select_option("#search-method", method)
        page.fill(box, '{"population": 8,')
        page.click("#submit-job")
        shown = page.wait_for_selector(f"{box} + .field-error").inner_text()
        assert shown.startswith(f"{label}: not valid JSON: "), shown
        assert "valid dictionary" not in shown and len(shown) > len(label) + 20, shown
        assert page.locator(".field-error").count() == 1
        assert page.eval_on_selector("#submit-job", "b => !b.disabled")
        page.fill(box, "{}")
    page.wait_for_timeout(300)
    assert posted == []


def test_broken_json_in_the_design_noise_constraints_or_sequence_is_named_before_sending(
    dashboard: Dashboard,
) -> None:
    # Sent as typed, a design noise of "[[1, 1]" came back from the service quoted as a
    # string ("Input should be a valid list", the text echoed), and so did a training's
    # sequence: now the form names the box, says its JSON is broken and why, and sends
    # nothing, as the overrides boxes do.
    _save_key(dashboard)
    scenario_id = _scenario(dashboard, ["stowed", "deployed", "ejected"], "broken json boxes")
    dashboard.open(f"#/jobs?scenario={scenario_id}&type=search")
    page = dashboard.page
    posted: list[str] = []
    page.on("request", lambda r: posted.append(r.url) if r.method == "POST" else None)
    page.select_option("#search-method", "nsga2")
    for box, label, broken in (
        ("#search-design_noise", "design noise", "[[1, 1]"),
        ("#search-constraints", "constraints", '{"max_impulse_nms": 20,'),
    ):
        kept = page.input_value(box)
        page.fill(box, broken)
        page.click("#submit-job")
        shown = page.wait_for_selector(f"{box} + .field-error").inner_text()
        assert shown.startswith(f"{label}: not valid JSON: "), shown
        assert broken not in shown and len(shown) > len(label) + 20, shown
        assert page.locator(".field-error").count() == 1
        page.fill(box, kept)
    page.click("#tab-train")
    # The box is filled with the scenario's hand-designed sequence once it is fetched.
    page.wait_for_function("() => document.getElementById('train-sequence').value !== ''")
    page.fill("#train-sequence", "[[4, 4, 4, 0, 0, 0], [4, 4")
    page.click("#submit-job")
    shown = page.wait_for_selector("#train-sequence + .field-error").inner_text()
    assert shown.startswith("sequence: not valid JSON: "), shown
    assert page.locator(".field-error").count() == 1
    assert page.eval_on_selector("#submit-job", "b => !b.disabled")
    page.wait_for_timeout(300)
    assert posted == []


def test_an_emptied_design_noise_box_is_left_out_not_sent_empty(dashboard: Dashboard) -> None:
    # The box is filled with the default design noise; an operator who cleared it (it is
    # NSGA-II's) had every search refused, a CEM one too: sent as "", the service answered
    # 422 "Input should be a valid list, got ''". Left out, the service's default is taken.
    _save_key(dashboard)
    scenario_id = _scenario(dashboard, ["stowed", "deployed", "ejected"], "emptied noise")
    dashboard.open(f"#/jobs?scenario={scenario_id}&type=search")
    page = dashboard.page
    page.select_option("#search-method", "cem")
    page.fill("#search-timesteps", "8")
    page.fill("#search-design_noise", "  ")
    with page.expect_response(lambda r: r.url.endswith("/jobs")) as sent:
        page.click("#submit-job")
    assert sent.value.status == 202, sent.value.text()
    assert page.locator(".field-error").count() == 0
    job = sent.value.json()
    default = dashboard.service.client.get("/vocabulary").json()["default_design_noise"]
    assert job["params"]["design_noise"] == default
    service = dashboard.service
    service.client.post(f"/jobs/{job['id']}/cancel")
    service.until(
        lambda: service.job(job["id"])["status"] in ("succeeded", "failed", "cancelled"),
        120,
        "the search ends",
    )


def test_a_job_forms_refused_fields_are_shown_next_to_them(dashboard: Dashboard) -> None:
    # The service locates a job's field where the client sent it (["body", "seed"], not
    # under the job union's tag): the form still puts each message next to its input.
    _save_key(dashboard)
    scenario_id = _scenario(dashboard, ["stowed", "deployed", "ejected"], "refused fields")
    page = dashboard.page
    dashboard.console.expect(r"status of 422")
    dashboard.open(f"#/jobs?scenario={scenario_id}&type=search")
    page.fill("#search-seed", "x")
    page.fill("#search-sequence_length", "0")
    with page.expect_response(lambda r: r.url.endswith("/jobs")) as sent:
        page.click("#submit-job")
    locs = [e["loc"] for e in sent.value.json()["detail"]]
    assert sorted(locs) == [["body", "params", "sequence_length"], ["body", "seed"]], locs
    seed = page.wait_for_selector("#search-seed + .field-error").inner_text()
    assert "got 'x'" in seed, seed
    length = page.wait_for_selector("#search-sequence_length + .field-error").inner_text()
    assert "greater than or equal to 1" in length, length
    dashboard.open(f"#/jobs?scenario={scenario_id}&type=train")
    # Playwright's fill selects the box, then types: a default landing between the two
    # is kept with the typed text after it (the form keeps what is typed after that).
    page.wait_for_function("document.querySelector('#train-sequence').value !== ''")
    page.fill("#train-sequence", "[[4, 4, 4, 0, 0, 0]]")
    page.fill("#train-n_realisations", "lots")
    with page.expect_response(lambda r: r.url.endswith("/jobs")) as sent:
        page.click("#submit-job")
    assert [e["loc"] for e in sent.value.json()["detail"]] == [["body", "params", "n_realisations"]]
    shown = page.wait_for_selector("#train-n_realisations + .field-error").inner_text()
    assert "got 'lots'" in shown, shown


def test_a_sequence_typed_before_the_default_arrives_is_kept(dashboard: Dashboard) -> None:
    # The train form fills the hand-designed sequence when GET .../baselines answers. A
    # slow answer (a loaded machine: CI) landed on what the user had typed meanwhile: the
    # box read the default followed by the typed text, broken JSON, and the job was never
    # sent. The baselines' answer is held here until the sequence has been typed.
    _save_key(dashboard)
    scenario_id = _scenario(dashboard, ["stowed", "deployed"], "typed before the default")
    other = _scenario(dashboard, ["stowed", "ejected"], "another default")
    page = dashboard.page

    held: list[Any] = []
    baselines = re.compile(r"/scenarios/[^/]+/baselines")
    page.route(baselines, lambda route: held.append(route))
    try:
        dashboard.open(f"#/jobs?scenario={scenario_id}&type=train")
        page.wait_for_selector("#train-sequence")
        page.click("#train-sequence")
        page.keyboard.insert_text("[[4, 4, 4, 0, 0, 0]]")
        with page.expect_response(baselines) as answered:
            one_held(page, held).continue_()
        assert answered.value.ok
        # The page's handler of that answer runs before the next task: a round trip.
        page.evaluate("() => new Promise((done) => setTimeout(done, 100))")
        assert page.input_value("#train-sequence") == "[[4, 4, 4, 0, 0, 0]]"
        # Choosing a scenario in the form is a new start: its default replaces the box.
        page.select_option("#train-scenario", other)
        with page.expect_response(baselines):
            one_held(page, held).continue_()
        page.wait_for_function(
            "() => !document.querySelector('#train-sequence').value.includes('4, 4, 4')"
        )
        assert json.loads(page.input_value("#train-sequence"))
    finally:
        page.unroute(baselines)


def test_a_job_forms_time_limit_is_sent_refused_beside_its_box_and_shown(
    dashboard: Dashboard,
) -> None:
    # The API takes time_limit_s for every job type; the form had no box for it. Empty, it
    # is not sent (the service's ceiling holds); refused, the 422 is shown beside it.
    _save_key(dashboard)
    scenario_id = _scenario(dashboard, ["stowed", "deployed"], "time limits")
    page = dashboard.page
    client = dashboard.service.client
    dashboard.console.expect(r"status of 422")
    dashboard.open(f"#/jobs?scenario={scenario_id}&type=search")
    page.select_option("#search-method", "random")
    page.fill("#search-sequence_length", "2")
    page.fill("#search-timesteps", "64")
    page.fill("#search-seed", "x")
    with page.expect_response(lambda r: r.url.endswith("/jobs")) as sent:
        page.click("#submit-job")
    assert "time_limit_s" not in (sent.value.request.post_data_json or {})["params"]
    page.wait_for_selector("#search-seed + .field-error")
    # The box says the service's floor (1 s) before a value under it is refused.
    hint = page.inner_text("#search-time_limit_s ~ .hint")
    assert "at least 1;" in hint, hint
    page.fill("#search-seed", "3")
    for typed, said in [
        ("-1", "greater than or equal to 1"),
        ("0.5", "greater than or equal to 1, got 0.5"),
        ("abc", "valid number"),
    ]:
        page.fill("#search-time_limit_s", typed)
        with page.expect_response(lambda r: r.url.endswith("/jobs")) as sent:
            page.click("#submit-job")
        assert sent.value.status == 422
        locs = [e["loc"] for e in sent.value.json()["detail"]]
        assert locs == [["body", "params", "time_limit_s"]], locs
        shown = page.wait_for_selector("#search-time_limit_s + .field-error").inner_text()
        assert said in shown, (typed, shown)
    page.fill("#search-time_limit_s", "30")
    page.click("#submit-job")
    page.wait_for_url(re.compile(r"#/jobs/[^?]+"))
    job_id = page.url.split("#/jobs/")[1].split("?")[0]
    client.post(f"/jobs/{job_id}/cancel")
    assert client.get(f"/jobs/{job_id}").json()["params"]["time_limit_s"] == 30
    assert page.wait_for_selector("#job-time-limit").inner_text() == "30 s (asked)"

    # A training past its limit fails naming it: the page says it stopped on it, read
    # from the job's stopped, whatever the error's words (it matched them before).
    def timed_out(route: Any) -> None:
        answer = route.fetch()
        job = answer.json()
        job["status"], job["stopped"] = "failed", "time_limit"
        job["error"] = "JobTimeLimitExceeded: ran out at 30 s"
        route.fulfill(response=answer, body=json.dumps(job))

    pattern = f"**/jobs/{job_id}"
    page.route(pattern, timed_out)
    try:
        dashboard.open(f"#/jobs/{job_id}?again=1")
        shown = page.wait_for_selector("#job-time-limit >> text=stopped").inner_text()
        assert shown == "30 s (asked); stopped on it", shown
    finally:
        page.unroute(pattern)

    # The train and sweep forms have the box too; more than the service's ceiling is
    # refused with the service's words beside it.
    dashboard.open(f"#/jobs?scenario={scenario_id}&type=train")
    page.wait_for_function("document.querySelector('#train-sequence').value !== ''")
    page.fill("#train-time_limit_s", "1e9")
    with page.expect_response(lambda r: r.url.endswith("/jobs")) as sent:
        page.click("#submit-job")
    assert sent.value.request.post_data_json["params"]["time_limit_s"] == 1e9
    shown = page.wait_for_selector("#train-time_limit_s + .field-error").inner_text()
    assert "ceiling" in shown, shown
    page.click("#tab-sweep")
    assert page.is_visible("#sweep-time_limit_s")


def test_a_hex_time_limit_or_multiple_is_sent_as_typed_not_as_another_number(
    dashboard: Dashboard,
) -> None:
    # Number("0x10") is 16: a time limit typed "0x10" was sent as 16 s (and queued), a
    # multiple "0x10" as 16, neither what the box showed. Sent as typed, the service's 422
    # names it beside the box; decimal text is still sent as a number.
    _save_key(dashboard)
    scenario_id = _scenario(dashboard, ["stowed", "deployed"], "hex boxes")
    page = dashboard.page
    client = dashboard.service.client
    dashboard.console.expect(r"status of 422")
    jobs = client.get("/jobs").json()["total"]
    dashboard.open(f"#/jobs?scenario={scenario_id}&type=train")
    page.wait_for_function("document.querySelector('#train-sequence').value !== ''")
    page.fill("#train-time_limit_s", " 0x10 ")
    with page.expect_response(lambda r: r.url.endswith("/jobs")) as sent:
        page.click("#submit-job")
    assert sent.value.request.post_data_json["params"]["time_limit_s"] == "0x10"
    assert sent.value.status == 422
    shown = page.wait_for_selector("#train-time_limit_s + .field-error").inner_text()
    assert "0x10" in shown, shown
    assert client.get("/jobs").json()["total"] == jobs
    page.click("#tab-sweep")
    page.fill("#sweep-multiples", "0x10, 1e-1, 2")
    with page.expect_response(lambda r: r.url.endswith("/jobs")) as sent:
        page.click("#submit-job")
    assert sent.value.request.post_data_json["params"]["multiples"] == ["0x10", 0.1, 2]
    assert sent.value.status == 422
    assert client.get("/jobs").json()["total"] == jobs


def test_the_parameters_a_sequence_cannot_see_are_one_it_or_several_them(
    dashboard: Dashboard,
) -> None:
    # One parameter read "this sequence hardly excites Ixx: it cannot see them".
    _save_key(dashboard)
    shown = dashboard.page.evaluate(
        """async () => {
            const page = await import("/static/js/pages/identify.js");
            return [page.notExcitedText(["Ixx"]), page.notExcitedText(["Ixy", "Iyz"])];
        }"""
    )
    assert shown == [
        "this sequence hardly excites Ixx: it cannot see it",
        "this sequence hardly excites Ixy, Iyz: it cannot see them",
    ]


def test_opening_a_route_of_the_same_page_waits_for_the_new_page(dashboard: Dashboard) -> None:
    # From one jobs route to another only the hash changes: the test helper's open used
    # to return on the old page's h1, before the new page was drawn.
    _save_key(dashboard)
    scenario_id = _scenario(dashboard, ["stowed", "deployed"], "same page, new route")
    page = dashboard.page
    for kind in ("search", "train", "search"):
        dashboard.open(f"#/jobs?scenario={scenario_id}&type={kind}")
        chosen = page.query_selector("#tab-" + kind)
        assert chosen is not None and chosen.get_attribute("aria-selected") == "true", kind
    # The same address again is drawn afresh.
    page.evaluate("() => document.querySelector('#page h1').setAttribute('data-mine', '')")
    dashboard.open(f"#/jobs?scenario={scenario_id}&type=search")
    assert page.query_selector("#page h1[data-mine]") is None


def test_a_constraint_or_setting_with_a_bad_value_is_named_not_called_a_dictionary(
    dashboard: Dashboard,
) -> None:
    # helper-174's review: "max_final_rate_deg_s=abc" (or "=1e400", "=", "0.5 deg/s")
    # was sent as the whole text and came back "Input should be a valid dictionary, got
    # 'max_final_rate_deg_s=abc'", the message the JSON boxes were mended away from;
    # and 1e400 in a JSON box (the NSGA-II settings, the design noise, a constraints
    # object) became null on its way (JSON.stringify of Infinity): "NSGA-II population
    # must be an integer in 4..10000, got None", a value nobody typed.
    _save_key(dashboard)
    scenario_id = _scenario(dashboard, ["stowed", "deployed", "ejected"], "bad values")
    dashboard.open(f"#/jobs?scenario={scenario_id}&type=search")
    page = dashboard.page
    dashboard.console.expect("status of 422")
    page.select_option("#search-method", "nsga2")
    for box, typed in (
        ("#search-constraints", "max_final_rate_deg_s=abc"),
        ("#search-constraints", "max_final_rate_deg_s=0.5 deg/s"),
        ("#search-nsga2", '{"population": 1e400}'),
        ("#search-design_noise", "[[1e400, 1]]"),
    ):
        kept = page.input_value(box)
        page.fill(box, typed)
        page.click("#submit-job")
        shown = page.wait_for_selector(f"{box} + .field-error").inner_text()
        assert "valid dictionary" not in shown, (typed, shown)
        assert "None" not in shown, (typed, shown)
        page.fill(box, kept)
