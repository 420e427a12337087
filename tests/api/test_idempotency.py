"""``Idempotency-Key`` on the POSTs that store a row: a retry is answered, not redone.

Without the key, a scenario stored again makes a second one, and a rerun sent again
makes a second job once the first has finished (before, it is handed that one, 200): a
client whose answer was lost (a timeout) cannot retry safely. With it, the retry gets
the first answer back (``Idempotent-Replayed: true``) and nothing is made twice, also
when the identical requests are sent at once to a real server, on both databases.
"""

from __future__ import annotations

import os
import secrets
import shutil
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from datetime import timedelta
from pathlib import Path
from typing import Any

import httpx
import pytest
import uvicorn
from pydantic import TypeAdapter
from service_support import ROOT, free_port, writes_refused_while
from sqlalchemy import func, select, update

from app.api import jobs as jobs_api
from app.api import scenarios as scenarios_api
from app.api.idempotency import (
    IDEMPOTENCY_KEY_HEADER,
    LIVE_CLAIM,
    REPLAYED_HEADER,
    RETRY_AFTER_MAX,
    retry_after_s,
)
from app.main import create_app
from app.schemas import JobCreate
from app.security import hash_key
from service.config import Settings
from service.store import ApiKey, IdempotencyKeyRow, JobRow, ScenarioRow
from service.store import idempotency as store
from service.store.models import utcnow

from .support import Api, make_settings, served_in_thread

SEARCH: dict[str, Any] = {"method": "random", "sequence_length": 4, "timesteps": 64}


def _keyed(api: Api, key: str | bytes, other_key: str | None = None) -> dict[str, Any]:
    return {"X-API-Key": other_key or api.key, IDEMPOTENCY_KEY_HEADER: key}


def _count(api: Api, table: Any, *where: Any) -> int:
    with api.db.session() as session:
        return int(session.scalar(select(func.count()).select_from(table).where(*where)) or 0)


def _same_answer(replayed: dict[str, Any], first: dict[str, Any]) -> bool:
    """The first answer as it was, but for the time queued so far, which an answer
    computes when it is written (milliseconds apart for the first one)."""
    return {**replayed, "queue_time_s": None} == {**first, "queue_time_s": None}


def _rerun(scenario_id: str) -> dict[str, Any]:
    """A rerun: without a key, each one sent once the last one's job has finished makes
    a new job in its place (while that job waits or runs, it is handed that job, 200);
    with one, a replay is the first answer again (202 and the replay header)."""
    return {"type": "search", "scenario_id": scenario_id, "params": SEARCH, "rerun": True}


def test_a_rerun_sent_again_with_its_key_is_answered_as_the_first_and_makes_one_job(
    api: Api,
) -> None:
    scenario = api.create_scenario()["id"]
    headers = _keyed(api, "rerun-7f3c")
    first = api.client.post("/jobs", json=_rerun(scenario), headers=headers)
    again = api.client.post("/jobs", json=_rerun(scenario), headers=headers)
    assert first.status_code == 202, first.text
    assert REPLAYED_HEADER.lower() not in first.headers
    assert again.status_code == 202, again.text
    assert again.headers[REPLAYED_HEADER] == "true"
    assert _same_answer(again.json(), first.json())
    assert _count(api, JobRow) == 1
    # The key changes nothing else: a rerun with a new key, once the job has finished,
    # is a new job (while it waits it is that job, 200, as without a key).
    with api.db.session() as session:
        session.execute(update(JobRow).values(status="succeeded"))
    third = api.client.post("/jobs", json=_rerun(scenario), headers=_keyed(api, "rerun-8a01"))
    assert third.status_code == 202 and third.json()["id"] != first.json()["id"]


def test_a_scenario_stored_again_with_its_key_is_the_first_and_a_reused_job_replays_200(
    api: Api,
) -> None:
    headers = _keyed(api, '"scenario one"')  # the draft's form: a quoted string
    first = api.client.post("/scenarios", json={"preset": "paper"}, headers=headers)
    again = api.client.post("/scenarios", json={"preset": "paper"}, headers=headers)
    assert (first.status_code, again.status_code) == (201, 201), again.text
    assert again.headers[REPLAYED_HEADER] == "true"
    assert again.json()["id"] == first.json()["id"]
    assert _count(api, ScenarioRow) == 1
    # The job that stands is handed back (200, reused), and so is its replay.
    body = {"type": "search", "scenario_id": first.json()["id"], "params": SEARCH}
    assert api.submit("search", first.json()["id"], params=SEARCH).status_code == 202
    reused = api.client.post("/jobs", json=body, headers=_keyed(api, "plain"))
    replayed = api.client.post("/jobs", json=body, headers=_keyed(api, "plain"))
    assert (reused.status_code, replayed.status_code) == (200, 200)
    assert _same_answer(replayed.json(), reused.json()) and replayed.json()["reused"] is True


def test_a_key_used_for_another_request_is_422_naming_it(api: Api) -> None:
    scenario = api.create_scenario()["id"]
    headers = _keyed(api, "k-1")
    assert api.client.post("/jobs", json=_rerun(scenario), headers=headers).status_code == 202
    other = {**_rerun(scenario), "seed": 5}
    refused = api.client.post("/jobs", json=other, headers=headers)
    assert refused.status_code == 422, refused.text
    (error,) = refused.json()["detail"]
    assert error["loc"] == ["header", IDEMPOTENCY_KEY_HEADER]
    assert "'k-1'" in error["msg"] and "POST /jobs" in error["msg"]
    # Another route is another request too.
    on_scenarios = api.client.post("/scenarios", json={"preset": "paper"}, headers=headers)
    assert on_scenarios.status_code == 422 and "'k-1'" in on_scenarios.text
    assert _count(api, JobRow) == 1 and _count(api, ScenarioRow) == 1


@pytest.mark.parametrize(
    ("key", "quoted"),
    [
        # An empty key is said to be empty: the 422 said "must be 1 to 255 printable
        # ASCII characters", as for a character no key holds.
        ("", "Idempotency-Key is empty (got '')"),
        ("   ", "Idempotency-Key holds only spaces (got '   ')"),
        ('""', "Idempotency-Key is an empty quoted string (got '\"\"')"),
        ('"  "', "Idempotency-Key quotes only spaces (got '\"  \"')"),
        ("x" * 256, "at most 255 characters, got 256"),
        ("café".encode(), "'caf"),
        ("a\tb", "'a\\tb'"),
    ],
)
def test_a_key_no_client_would_send_is_422_naming_it(
    api: Api, key: str | bytes, quoted: str
) -> None:
    response = api.client.post("/scenarios", json={"preset": "paper"}, headers=_keyed(api, key))
    assert response.status_code == 422, response.text
    (error,) = response.json()["detail"]
    assert error["loc"] == ["header", IDEMPOTENCY_KEY_HEADER]
    assert quoted in error["msg"]
    assert _count(api, ScenarioRow) == 0


@pytest.mark.parametrize(
    ("key", "why"),
    [
        ('"unterminated', "not a Structured Field string"),
        ('"bad\\x escape"', "not a Structured Field string"),
        ('"closed"then-more', "not a Structured Field string"),
        ("a, b", "is a list"),
        ('"a", "b"', "is a list"),
        # A comma inside quotes is no list: the '=' before it is what no bare key holds
        # (before: "a comma outside a quoted string").
        ('tok="x,y"', "has '=' at character 4, which a bare key may not hold"),
        # Bare keys are sf-tokens: a quote, a backslash, a space or a ';' in one would
        # make the structured field something else (before: each taken as a key, 201).
        ('ab"c', "has a double quote at character 3"),
        ("ab\\c", "has a backslash at character 3"),
        ("two words", "has a space at character 4"),
        ("k;v=1", "has ';' at character 2"),
        ('"k";v=1', "has parameters"),
    ],
)
def test_a_key_that_is_not_one_key_or_not_the_drafts_string_is_422_naming_it(
    api: Api, key: str, why: str
) -> None:
    """The draft's field is one sf-string (RFC 8941). A bare sf-token (Stripe's keys, a
    UUID) is taken as it is, but a value that opens a quoted string and breaks it, a
    bare value with a character no token holds, or a list of keys, is not some other
    key: kept as one, a retry with the key the client meant would miss it. The 422 names
    the character and where it is."""
    response = api.client.post("/scenarios", json={"preset": "paper"}, headers=_keyed(api, key))
    assert response.status_code == 422, response.text
    (error,) = response.json()["detail"]
    assert error["loc"] == ["header", IDEMPOTENCY_KEY_HEADER]
    assert IDEMPOTENCY_KEY_HEADER in error["msg"] and repr(key) in error["msg"]
    assert why in error["msg"]
    assert _count(api, ScenarioRow) == 0 and _count(api, IdempotencyKeyRow) == 0


def test_a_comma_inside_the_drafts_quoted_string_is_part_of_one_key(api: Api) -> None:
    quoted = api.client.post("/scenarios", json={"preset": "paper"}, headers=_keyed(api, '"a, b"'))
    assert quoted.status_code == 201, quoted.text
    with api.db.session() as session:
        assert session.scalars(select(IdempotencyKeyRow.key)).all() == ["a, b"]


def test_the_drafts_escapes_are_read_and_a_bare_token_is_taken_as_sent(api: Api) -> None:
    """``\\"`` and ``\\\\`` in the quoted string stand for a quote and a backslash; a bare
    key with a leading digit (a UUID), any of the token's punctuation or base64's
    trailing "=" padding is kept as is."""
    sent = [
        '"say \\"hi\\" \\\\o/"',
        "550e8400-e29b-41d4-a716-446655440000",
        "*k_1.2~a:b/c!#$%&'+^`|",
        "q83vEjRWeJA+/w==",
    ]
    for key in sent:
        made = api.client.post("/scenarios", json={"preset": "paper"}, headers=_keyed(api, key))
        assert made.status_code == 201, made.text
    with api.db.session() as session:
        assert sorted(session.scalars(select(IdempotencyKeyRow.key)).all()) == sorted(
            ['say "hi" \\o/', sent[1], sent[2], sent[3]]
        )


def _claim_as_the_api(api: Api, key: str, body: dict[str, Any], *, age: timedelta) -> None:
    """Claim ``key`` for ``body`` on POST /jobs as a request begun ``age`` ago that was
    never answered (still running, or its process died)."""
    parsed = TypeAdapter(JobCreate).validate_python(body)
    found = store.claim(
        api.db,
        client=hash_key(api.key),
        key=key,
        route="POST /jobs",
        digest=store.fingerprint("POST /jobs", parsed.model_dump(mode="json")),
        ttl=timedelta(days=1),
        now=utcnow() - age,
    )
    assert found.outcome == store.NEW


def test_a_request_still_in_progress_is_409_and_a_dead_ones_key_is_taken_over(api: Api) -> None:
    scenario = api.create_scenario()["id"]
    _claim_as_the_api(api, "busy", _rerun(scenario), age=timedelta(seconds=1))
    busy = api.client.post("/jobs", json=_rerun(scenario), headers=_keyed(api, "busy"))
    assert busy.status_code == 409, busy.text
    assert "'busy'" in busy.json()["detail"] and busy.headers["retry-after"] == "1"
    assert _count(api, JobRow) == 0
    # A claim older than the lease was a request whose API process died: the next one runs.
    _claim_as_the_api(api, "dead", _rerun(scenario), age=store.CLAIM_LEASE + timedelta(seconds=5))
    taken = api.client.post("/jobs", json=_rerun(scenario), headers=_keyed(api, "dead"))
    assert taken.status_code == 202, taken.text
    again = api.client.post("/jobs", json=_rerun(scenario), headers=_keyed(api, "dead"))
    assert again.headers[REPLAYED_HEADER] == "true" and again.json()["id"] == taken.json()["id"]


def test_a_409s_retry_after_grows_with_the_claims_age_bounded_and_within_its_lease(
    api: Api,
) -> None:
    """A claim just taken belongs to a request being answered: ask again in 1 s. One held
    past LIVE_CLAIM may be a request still waiting (on SQLite's 30 s write lock) or a dead
    process's: the wait is a fifth of its age, at most RETRY_AFTER_MAX, never past the
    lease's end. Before, past LIVE_CLAIM it was the lease's rest: 108 s for a live request
    held 12 s, whose key would be free a second later."""
    scenario = api.create_scenario()["id"]
    for key, age in (("fresh", timedelta(seconds=2)), ("nearly-live", LIVE_CLAIM / 2)):
        _claim_as_the_api(api, key, _rerun(scenario), age=age)
        busy = api.client.post("/jobs", json=_rerun(scenario), headers=_keyed(api, key))
        assert busy.status_code == 409 and busy.headers["retry-after"] == "1", busy.text
    _claim_as_the_api(api, "held-up", _rerun(scenario), age=timedelta(seconds=12))
    held_up = api.client.post("/jobs", json=_rerun(scenario), headers=_keyed(api, "held-up"))
    assert held_up.status_code == 409, held_up.text
    # 12 s and the time this request took to arrive, over 5, rounded up.
    assert held_up.headers["retry-after"] in ("3", "4"), held_up.headers
    detail = held_up.json()["detail"]
    assert f"send it again in {held_up.headers['retry-after']} s" in detail, detail
    assert "at the latest, when its lease ends" in detail, detail
    _claim_as_the_api(api, "stale", _rerun(scenario), age=timedelta(seconds=60))
    stale = api.client.post("/jobs", json=_rerun(scenario), headers=_keyed(api, "stale"))
    assert stale.status_code == 409 and stale.headers["retry-after"] == "10", stale.headers
    assert _count(api, JobRow) == 0
    # The rule itself: a fifth of the age past LIVE_CLAIM, rounded up; at most
    # RETRY_AFTER_MAX; never past the lease's end, and never 0.
    now = utcnow()
    assert retry_after_s(now - LIVE_CLAIM, now) == 2
    assert retry_after_s(now - timedelta(seconds=20.5), now) == 5
    assert retry_after_s(now - timedelta(seconds=90), now) == RETRY_AFTER_MAX.seconds
    assert retry_after_s(now - (store.CLAIM_LEASE - timedelta(seconds=3.5)), now) == 4
    assert retry_after_s(now - (store.CLAIM_LEASE - timedelta(milliseconds=300)), now) == 1
    assert retry_after_s(None, now) == 1


_CLAIM_AND_DIE = """
import os, signal, sys
from datetime import timedelta
from service.store import idempotency as store
from service.store.session import Database

client, key, route, digest = sys.argv[2:6]
found = store.claim(
    Database(sys.argv[1]), client=client, key=key, route=route, digest=digest,
    ttl=timedelta(days=1),
)
assert found.outcome == store.NEW, found
os.kill(os.getpid(), signal.SIGKILL)  # killed mid-request: nothing let go
"""


def test_a_key_claimed_by_a_process_since_killed_is_taken_over_at_once(api: Api) -> None:
    """An API process killed with a request in flight (or while the database refused the
    release of a failed one) leaves its claim behind. Its token names the process: a
    process of the same host sees it is gone and runs the retry at once. Before, the
    retry was a 409 until the lease's end, 2 minutes after the claim."""
    scenario = api.create_scenario()["id"]
    parsed = TypeAdapter(JobCreate).validate_python(_rerun(scenario))
    digest = store.fingerprint("POST /jobs", parsed.model_dump(mode="json"))
    argv = [api.db.url, hash_key(api.key), "killed", "POST /jobs", digest]
    died = subprocess.run(
        [sys.executable, "-c", _CLAIM_AND_DIE, *argv],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=ROOT,  # this checkout's code, first on the child's path ("-c" puts its cwd there)
    )
    assert died.returncode == -9, died.stderr
    with api.db.session() as session:
        (left,) = session.scalars(select(IdempotencyKeyRow)).all()
    assert left.key == "killed" and left.answer_status is None and store.claimer_died(left.claim)
    retried = api.client.post("/jobs", json=_rerun(scenario), headers=_keyed(api, "killed"))
    assert retried.status_code == 202, retried.text
    assert _count(api, JobRow) == 1
    # A live process's claim is never taken over: this one's, and one with no process
    # in it (made on another host, or before claims named their process).
    assert not store.claimer_died(store.claim_token())
    assert not store.claimer_died(secrets.token_hex(16))


_CLAIM_IN_ANOTHER_CLOCK = """
import sys
from datetime import timedelta
from service.store import idempotency as store
from service.store.session import Database

client, key, route, digest = sys.argv[2:6]
found = store.claim(
    Database(sys.argv[1]), client=client, key=key, route=route, digest=digest,
    ttl=timedelta(days=1),
)
print(found.outcome)
"""


def test_a_live_claim_is_409_to_a_process_in_another_time_namespace(api: Api) -> None:
    """A process in another time namespace (``unshare --time --boottime``, CRIU) reads
    every start in ``/proc/<pid>/stat`` shifted by its boot-time offset: it took this live
    process's claim for a dead one's and ran the request again (two API servers on one
    database made two scenarios for one key; before: ``new``). A process whose clock
    differs cannot tell, and leaves the claim to its lease."""
    scenario = api.create_scenario()["id"]
    body = _rerun(scenario)
    _claim_as_the_api(api, "live-other-clock", body, age=timedelta(seconds=1))
    parsed = TypeAdapter(JobCreate).validate_python(body)
    digest = store.fingerprint("POST /jobs", parsed.model_dump(mode="json"))
    argv = [api.db.url, hash_key(api.key), "live-other-clock", "POST /jobs", digest]
    unshare = shutil.which("unshare")
    if unshare is None:
        pytest.skip("no unshare(1) to start a process in another time namespace")
    other_clock = [unshare, "--time", "--boottime", "100000", "--fork"]
    probe = subprocess.run([*other_clock, "true"], capture_output=True, text=True, timeout=60)
    if probe.returncode != 0:
        pytest.skip(f"cannot make a time namespace here: {probe.stderr.strip()}")
    judged = subprocess.run(
        [*other_clock, sys.executable, "-c", _CLAIM_IN_ANOTHER_CLOCK, *argv],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=ROOT,
    )
    assert judged.returncode == 0, judged.stderr
    assert judged.stdout.strip() == store.IN_PROGRESS, judged.stdout


def test_no_claim_is_judged_dead_where_proc_is_another_pid_namespaces(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Where ``/proc`` is not this process's PID namespace's (``unshare --pid`` without
    ``--mount-proc``: ``/proc/self`` is another number than ``os.getpid()``), ``/proc/<pid>``
    is another process than the pid ``os.kill`` reaches, and a live claim's start was read
    from a stranger: nothing there is judged dead, and no token names its process."""
    print_token = "from service.store import idempotency as s; print(s.claim_token())"
    made = subprocess.run(
        [sys.executable, "-c", print_token],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=ROOT,
    )
    assert made.returncode == 0, made.stderr
    exited = made.stdout.strip()
    assert store.claimer_died(exited)  # its process is gone: with our own /proc, told
    readlink = os.readlink

    def from_another_namespace(path: str) -> str:
        return "4194303" if path == "/proc/self" else readlink(path)

    monkeypatch.setattr(os, "readlink", from_another_namespace)
    assert not store.claimer_died(exited)
    assert not store.claimer_died(store.claim_token())


def _take_over_after_the_lease(api: Api, key: str, route: str, sent: Any) -> store.Claim:
    """What a request with ``key`` sent to ``route`` (its body ``sent``, the route's
    model) does once the lease of the claim on it has run out: take the key over."""
    return store.claim(
        api.db,
        client=hash_key(api.key),
        key=key,
        route=route,
        digest=store.fingerprint(route, sent.model_dump(mode="json")),
        ttl=timedelta(days=1),
        now=utcnow() + store.CLAIM_LEASE + timedelta(seconds=5),
    )


def test_a_request_whose_claim_was_taken_over_keeps_nothing_and_is_409(
    api: Api, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A live request can lose its claim: held past the lease (a lock waited on for
    minutes), or its process taken for dead. The request that took the key over does the
    work; the first one must keep nothing. Before, its answer matched no row and was
    dropped, its scenario committed all the same (201): one key, two scenarios once the
    taker was answered too."""
    body = {"preset": "paper"}
    build = scenarios_api._build
    taken: list[store.Claim] = []

    def taken_over_meanwhile(sent: Any) -> Any:
        taken.append(_take_over_after_the_lease(api, "outlived", "POST /scenarios", sent))
        return build(sent)

    monkeypatch.setattr(scenarios_api, "_build", taken_over_meanwhile)
    first = api.client.post("/scenarios", json=body, headers=_keyed(api, "outlived"))
    assert [claim.outcome for claim in taken] == [store.NEW]
    assert first.status_code == 409, first.text
    assert "took the key over" in first.json()["detail"] and first.headers["retry-after"] == "1"
    assert _count(api, ScenarioRow) == 0
    with api.db.session() as session:
        (row,) = session.scalars(select(IdempotencyKeyRow)).all()
    assert row.claim == taken[0].token and row.answer_status is None  # the taker's, intact


def test_a_rerun_whose_claim_was_taken_over_makes_no_job_and_is_409(
    api: Api, monkeypatch: pytest.MonkeyPatch
) -> None:
    """As above, on POST /jobs: a rerun (each one makes a new job) whose key a later
    request took over while it was checked stores no job (before: 202 and its job)."""
    scenario = api.create_scenario()["id"]
    check = jobs_api._check_search
    taken: list[store.Claim] = []

    def taken_over_meanwhile(sent: Any, found: Any) -> None:
        taken.append(_take_over_after_the_lease(api, "outlived-rerun", "POST /jobs", sent))
        check(sent, found)

    monkeypatch.setattr(jobs_api, "_check_search", taken_over_meanwhile)
    first = api.client.post("/jobs", json=_rerun(scenario), headers=_keyed(api, "outlived-rerun"))
    assert [claim.outcome for claim in taken] == [store.NEW]
    assert first.status_code == 409 and "took the key over" in first.json()["detail"], first.text
    assert _count(api, JobRow) == 0


def test_a_failed_request_keeps_no_answer_and_expired_keys_are_new_and_deleted(api: Api) -> None:
    missing = {"type": "search", "scenario_id": "0" * 32, "params": SEARCH}
    for _ in range(2):
        gone = api.client.post("/jobs", json=missing, headers=_keyed(api, "fails"))
        assert gone.status_code == 404 and REPLAYED_HEADER.lower() not in gone.headers
    assert _count(api, IdempotencyKeyRow) == 0
    headers = _keyed(api, "old")
    first = api.client.post("/scenarios", json={"preset": "paper"}, headers=headers)
    with api.db.session() as session:
        session.execute(update(IdempotencyKeyRow).values(expires_at=utcnow() - timedelta(1)))
    later = api.client.post("/scenarios", json={"preset": "paper"}, headers=headers)
    assert later.status_code == 201 and REPLAYED_HEADER.lower() not in later.headers
    assert later.json()["id"] != first.json()["id"]
    # Any claim deletes what expired: only the new row is left.
    api.client.post("/scenarios", json={"preset": "paper"}, headers=_keyed(api, "new"))
    with api.db.session() as session:
        session.execute(
            update(IdempotencyKeyRow)
            .where(IdempotencyKeyRow.key == "old")
            .values(expires_at=utcnow() - timedelta(1))
        )
    api.client.post("/scenarios", json={"preset": "paper"}, headers=_keyed(api, "newer"))
    assert _count(api, IdempotencyKeyRow) == 2


def test_keys_belong_to_their_api_key(api: Api) -> None:
    other = secrets.token_urlsafe(24)
    with api.db.session() as session:
        session.add(ApiKey(key_hash=hash_key(other)))
    mine = api.client.post("/scenarios", json={"preset": "paper"}, headers=_keyed(api, "same"))
    again = api.client.post("/scenarios", json={"preset": "paper"}, headers=_keyed(api, "same"))
    theirs = api.client.post(
        "/scenarios", json={"preset": "paper"}, headers=_keyed(api, "same", other)
    )
    assert again.json()["id"] == mine.json()["id"]
    assert theirs.status_code == 201 and REPLAYED_HEADER.lower() not in theirs.headers
    assert theirs.json()["id"] != mine.json()["id"]


def _at_once(count: int, send: Callable[[], httpx.Response]) -> list[Any]:
    barrier = threading.Barrier(count)
    answers: list[Any] = [None] * count

    def run(index: int) -> None:
        barrier.wait()
        try:
            answers[index] = send()
        except Exception as exc:
            answers[index] = exc

    threads = [threading.Thread(target=run, args=(i,)) for i in range(count)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(120)
    return answers


def test_identical_posts_with_one_key_sent_at_once_to_a_server_make_one_row(
    tmp_path: Path, database_url: str
) -> None:
    """8 identical POSTs /scenarios (then reruns) with one key, each on its own
    connection, released together at a real uvicorn: one is done, each other one is
    its replay or a 409 (the first still in progress), and one row is made."""
    key = secrets.token_urlsafe(24)
    settings: Settings = make_settings(
        tmp_path / "data", database_url, INERTIA_ID_API_KEY=key, INERTIA_ID_VERDICT_PROCESS="off"
    )
    app = create_app(settings)
    port = free_port()
    config = uvicorn.Config(app, host="127.0.0.1", port=port, lifespan="off", log_level="warning")
    base = f"http://127.0.0.1:{port}"
    clients = 8

    def burst(path: str, body: dict[str, Any], idempotency_key: str) -> list[httpx.Response]:
        def send() -> httpx.Response:
            with httpx.Client(base_url=base, timeout=60) as client:
                return client.post(
                    path, json=body, headers={"X-API-Key": key, "Idempotency-Key": idempotency_key}
                )

        answers = _at_once(clients, send)
        assert all(isinstance(a, httpx.Response) for a in answers), answers
        done = [a for a in answers if a.status_code in (201, 202)]
        fresh = [a for a in done if REPLAYED_HEADER.lower() not in a.headers]
        assert len(fresh) == 1, [(a.status_code, a.text[:80]) for a in answers]
        assert {a.json()["id"] for a in done} == {fresh[0].json()["id"]}
        assert all(a.status_code in (201, 202, 409) for a in answers)
        return answers

    with served_in_thread(app, config):
        burst("/scenarios", {"preset": "paper"}, "burst-scenario")
        with app.state.db.session() as session:
            (scenario,) = session.scalars(select(ScenarioRow.id)).all()
        burst("/jobs", _rerun(scenario), "burst-rerun")
        with app.state.db.session() as session:
            assert session.scalar(select(func.count()).select_from(JobRow)) == 1


def test_a_job_made_before_its_request_failed_is_its_keys_answer_not_made_again(
    api: Api, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The job is committed (so a worker can claim it) before the rest of the request
    runs: a request that fails after that (here: noting the send; as well, a process
    killed there) made its job, and its retry must get that job, not make a second."""
    from starlette.testclient import TestClient

    from service.store import jobs as job_store

    scenario = api.create_scenario()["id"]
    headers = _keyed(api, "made-then-failed")

    def broken(*args: Any, **kwargs: Any) -> None:
        raise RuntimeError("the database went away")

    monkeypatch.setattr(job_store, "mark_sent", broken)
    with TestClient(api.app, raise_server_exceptions=False) as client:
        failed = client.post("/jobs", json=_rerun(scenario), headers=headers)
    assert failed.status_code == 500
    assert _count(api, JobRow) == 1
    monkeypatch.undo()
    again = api.client.post("/jobs", json=_rerun(scenario), headers=headers)
    assert again.status_code == 202, again.text
    assert again.headers.get(REPLAYED_HEADER) == "true"
    assert _count(api, JobRow) == 1
    with api.db.session() as session:
        (made,) = session.scalars(select(JobRow.id)).all()
    assert again.json()["id"] == made


def test_two_keys_in_one_request_are_422_naming_both(api: Api) -> None:
    """Two ``Idempotency-Key`` lines (a client's and a proxy's, say) are two keys: taking
    one of them silently would replay, or not, by a key the client may not retry with."""
    headers = [
        ("X-API-Key", api.key),
        (IDEMPOTENCY_KEY_HEADER, "k-a"),
        (IDEMPOTENCY_KEY_HEADER, "k-b"),
    ]
    response = api.client.post("/scenarios", json={"preset": "paper"}, headers=headers)
    assert response.status_code == 422, response.text
    (error,) = response.json()["detail"]
    assert error["loc"] == ["header", IDEMPOTENCY_KEY_HEADER]
    assert "'k-a'" in error["msg"] and "'k-b'" in error["msg"]
    assert _count(api, ScenarioRow) == 0 and _count(api, IdempotencyKeyRow) == 0


def test_the_schema_documents_the_keys_answers_headers(api: Api) -> None:
    """A client generated from /openapi.json learns of the replay's header and the
    409's wait, and of what a key may hold, not only of the request header."""
    paths = api.client.get("/openapi.json").json()["paths"]
    for path, codes in (("/jobs", ("200", "202")), ("/scenarios", ("201",))):
        operation = paths[path]["post"]
        (header,) = (p for p in operation["parameters"] if p["name"] == IDEMPOTENCY_KEY_HEADER)
        # Beside the anyOf or in its string branch: either applies to the strings only.
        variant = next(s for s in header["schema"]["anyOf"] if s.get("type") == "string")
        constraints = {**header["schema"], **variant}
        assert constraints.get("minLength") == 1 and "pattern" in constraints
        for code in codes:
            assert REPLAYED_HEADER in operation["responses"][code]["headers"], (path, code)
        assert "Retry-After" in operation["responses"]["409"]["headers"]


def test_a_request_whose_commit_failed_lets_its_key_go(api: Api) -> None:
    """The answer is committed with the scenario, after the route returned: when that
    commit fails nothing was stored, and the retry must run, not meet its own claim
    (a 409 for the 2 minutes of the lease)."""
    from sqlalchemy import event
    from sqlalchemy.exc import OperationalError
    from starlette.testclient import TestClient

    def note(connection: Any, cursor: Any, statement: str, *args: Any) -> None:
        if statement.lstrip().upper().startswith("INSERT INTO SCENARIOS"):
            connection.info["stores_a_scenario"] = True

    def refuse(connection: Any) -> None:
        if connection.info.pop("stores_a_scenario", False):
            raise OperationalError("COMMIT", {}, Exception("the disk is full"))

    engine = api.db.engine
    headers = _keyed(api, "commit-fails")
    event.listen(engine, "before_cursor_execute", note)
    event.listen(engine, "commit", refuse)
    try:
        with TestClient(api.app, raise_server_exceptions=False) as client:
            failed = client.post("/scenarios", json={"preset": "paper"}, headers=headers)
    finally:
        event.remove(engine, "before_cursor_execute", note)
        event.remove(engine, "commit", refuse)
    assert failed.status_code >= 500
    assert _count(api, ScenarioRow) == 0
    again = api.client.post("/scenarios", json={"preset": "paper"}, headers=headers)
    assert again.status_code == 201, again.text
    assert REPLAYED_HEADER.lower() not in again.headers
    assert _count(api, ScenarioRow) == 1


def _read_only_after_the_claim(monkeypatch: pytest.MonkeyPatch, refusing: threading.Event) -> None:
    """The database turns read-only right after a request claimed its key: the route's
    write and the key's release are refused (SQLITE_READONLY, PostgreSQL 25006)."""
    original = store.claim

    def claim_then_refuse(*args: Any, **kwargs: Any) -> store.Claim:
        found = original(*args, **kwargs)
        refusing.set()
        return found

    monkeypatch.setattr(store, "claim", claim_then_refuse)


def test_a_key_whose_request_met_a_read_only_database_is_free_once_it_takes_writes(
    api: Api, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The request is a 503 and cannot let its key go (the release is a write too). The
    retry sent once the database takes writes again must run, not meet the dead claim:
    before, it was a 409 for the 2 minutes of the lease."""
    from starlette.testclient import TestClient

    refusing = threading.Event()
    headers = _keyed(api, "read-only-then-back")
    with writes_refused_while(refusing):
        _read_only_after_the_claim(monkeypatch, refusing)
        with TestClient(api.app, raise_server_exceptions=False) as client:
            failed = client.post("/scenarios", json={"preset": "paper"}, headers=headers)
        monkeypatch.undo()
        assert failed.status_code == 503, failed.text
        assert "read-only" in failed.text
        assert _count(api, ScenarioRow) == 0
        refusing.clear()
        again = api.client.post("/scenarios", json={"preset": "paper"}, headers=headers)
    assert again.status_code == 201, again.text
    assert REPLAYED_HEADER.lower() not in again.headers
    assert _count(api, ScenarioRow) == 1


def test_a_claim_the_read_only_database_kept_is_let_go_without_a_request(
    api: Api, monkeypatch: pytest.MonkeyPatch
) -> None:
    """With no request to this process after the database takes writes again (the retry
    went to another API worker), the process that failed lets the key go by itself."""
    from starlette.testclient import TestClient

    refusing = threading.Event()
    with writes_refused_while(refusing):
        _read_only_after_the_claim(monkeypatch, refusing)
        with TestClient(api.app, raise_server_exceptions=False) as client:
            failed = client.post(
                "/scenarios", json={"preset": "paper"}, headers=_keyed(api, "left-behind")
            )
        monkeypatch.undo()
        assert failed.status_code == 503, failed.text
        assert _count(api, IdempotencyKeyRow) == 1
        refusing.clear()
        # Polled, not timed: it goes once a retry of the release meets a writable database.
        deadline = time.monotonic() + 60
        while _count(api, IdempotencyKeyRow) and time.monotonic() < deadline:
            time.sleep(0.2)
    assert _count(api, IdempotencyKeyRow) == 0


def _refused_releases(monkeypatch: pytest.MonkeyPatch) -> list[str]:
    """Every release refused (the database read-only); the keys tried by requests, not
    by the background thread, in order."""
    tried: list[str] = []

    def refused(db: Any, *, client: str, key: str, token: str) -> None:
        if threading.current_thread().name != "idempotency-releases":
            tried.append(key)
        raise RuntimeError("cannot execute DELETE in a read-only transaction")

    monkeypatch.setattr(store, "release", refused)
    return tried


def test_a_keyed_request_tries_only_its_own_keys_pending_release(
    api: Api, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Other keys this process could not let go are left to their own retries and the
    background thread: before, every keyed request first tried each of them (a write
    each, refused while the database is: 20 dead claims cost a request 20 refused
    deletes, 0.22 s and 20 PostgreSQL sessions opened)."""
    pending = store.pending_releases(api.db)
    client = hash_key(api.key)
    for n in range(20):
        pending.add(client=client, key=f"dead-{n}", token=secrets.token_hex(8), claimed_at=utcnow())
    tried = _refused_releases(monkeypatch)
    made = api.client.post("/scenarios", json={"preset": "paper"}, headers=_keyed(api, "other"))
    assert made.status_code == 201, made.text
    assert tried == []
    # Its own retry still tries its own dead claim first.
    pending.add(client=client, key="mine", token=secrets.token_hex(8), claimed_at=utcnow())
    api.client.post("/scenarios", json={"preset": "paper"}, headers=_keyed(api, "mine"))
    assert tried == ["mine"]
    monkeypatch.undo()
    pending.flush()
    assert len(pending) == 0


def test_a_round_of_pending_releases_stops_at_the_first_refusal(
    api: Api, monkeypatch: pytest.MonkeyPatch
) -> None:
    """While the database refuses writes, the rest would be refused too: before, each
    round (every second) tried every one."""
    pending = store.PendingReleases(api.db, interval_s=3600)
    for n in range(5):
        pending.add(client="c", key=f"dead-{n}", token=secrets.token_hex(8), claimed_at=utcnow())
    tried = _refused_releases(monkeypatch)
    pending.flush()
    assert len(tried) == 1 and len(pending) == 5
    monkeypatch.undo()
    pending.flush()
    assert len(pending) == 0
