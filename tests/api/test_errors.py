"""The caller's fault is a 422 naming the value; our fault is a 500 with a request id."""

from __future__ import annotations

import json
import logging
import re
import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from fastapi.routing import APIRoute
from service_support import SilentableProxy
from sqlalchemy import event, make_url

import app.api.identify
import app.main
from app.api import ROUTERS
from app.api.routing import UniqueKeysRoute
from app.verdicts import VerdictProcess
from inertia_id import InputError

from .support import GOOD_SEQUENCE, Api, TestClient, make_settings, read_only_postgres


def _identify(api: Api, classifier_id: str) -> object:
    telemetry = {"time_s": [0.05 * (i + 1) for i in range(80)], "omega_rad_s": [[0, 0, 0]] * 80}
    # As a real server answers: an unhandled error becomes the 500 response, not a raise.
    client = TestClient(api.app, raise_server_exceptions=False)
    return client.post(
        "/identify",
        json={"classifier_id": classifier_id, "telemetry": telemetry},
        headers=api.auth,
    )


@pytest.fixture
def threads(api: Api, make_api: Callable[..., Api]) -> Api:
    """An app that identifies on its compute threads (verdict process off), so that the
    core's ``identify`` can be replaced here; the verdict process raises what the core
    raises in the API process the same way (see the last test)."""
    return make_api(api.settings.model_copy(update={"verdict_process": "off"}), api.key)


@pytest.mark.parametrize("through", ["threads", "verdict process"])
def test_a_bug_in_the_core_is_a_500_with_a_request_id_not_a_422(
    api: Api,
    threads: Api,
    through: str,
    classifier: object,
    monkeypatch: pytest.MonkeyPatch,
    caplog: pytest.LogCaptureFixture,
) -> None:
    if through == "threads":
        api = threads
    scenario_id = api.create_scenario()["id"]
    classifier_id = api.insert_classifier(scenario_id, classifier)  # type: ignore[arg-type]

    def buggy(*_args: object, **_kwargs: object) -> None:
        raise ValueError("operands could not be broadcast together with shapes (80,3) (79,3)")

    async def buggy_process(*_args: object, **_kwargs: object) -> None:
        # What run_in_executor re-raises when the child's verdict raised.
        buggy()

    monkeypatch.setattr(app.api.identify, "identify", buggy)
    monkeypatch.setattr(VerdictProcess, "verdict", buggy_process)
    with caplog.at_level(logging.ERROR):
        response = _identify(api, classifier_id)
    assert response.status_code == 500  # type: ignore[attr-defined]
    request_id = response.headers["X-Request-ID"]  # type: ignore[attr-defined]
    detail = response.json()["detail"]  # type: ignore[attr-defined]
    assert request_id in detail and "defect of the service" in detail
    # No internals in the answer; all of them in the log, under the same id.
    assert "broadcast" not in response.text  # type: ignore[attr-defined]
    logged = [r for r in caplog.records if request_id in r.getMessage()]
    assert logged and logged[0].exc_info is not None
    assert "broadcast" in str(logged[0].exc_info[1])


def test_the_cores_input_error_is_a_422_quoting_the_value(
    threads: Api, classifier: object, monkeypatch: pytest.MonkeyPatch
) -> None:
    api = threads
    scenario_id = api.create_scenario()["id"]
    classifier_id = api.insert_classifier(scenario_id, classifier)  # type: ignore[arg-type]

    def refuses(*_args: object, **_kwargs: object) -> None:
        raise InputError("telemetry spans 0 s to 1 s but the sequence needs 4 s, got 1.0")

    monkeypatch.setattr(app.api.identify, "identify", refuses)
    response = _identify(api, classifier_id)
    assert response.status_code == 422  # type: ignore[attr-defined]
    assert "got 1.0" in response.json()["detail"][0]["msg"]  # type: ignore[attr-defined]


@pytest.mark.parametrize(
    ("method", "path", "allowed"),
    [
        ("DELETE", "/jobs/0123", "GET, HEAD, PATCH"),
        ("PUT", "/scenarios/0123/plan", "GET, HEAD, POST"),
        ("DELETE", "/jobs", "GET, HEAD, POST"),
        ("HEAD", "/identify", "POST"),
    ],
)
def test_a_method_a_path_does_not_take_is_405_listing_every_method_it_does(
    api: Api, method: str, path: str, allowed: str
) -> None:
    """RFC 9110: a 405's ``Allow`` lists the methods the resource supports. Starlette's
    router listed those of the first route matching the path: ``DELETE /jobs/{id}``
    answered ``Allow: PATCH`` (hiding GET), ``PUT /scenarios/{id}/plan`` ``Allow: GET``
    (hiding POST), and the detail was "Method Not Allowed", naming neither."""
    response = api.client.request(method, path, headers=api.auth)
    assert response.status_code == 405
    assert response.headers["allow"] == allowed
    if method != "HEAD":
        assert response.json()["detail"] == (
            f"method {method} is not allowed on {path}; it takes {allowed}"
        )
    # Every method listed is taken: none of them is a 405.
    for listed in allowed.split(", "):
        assert api.client.request(listed, path, headers=api.auth).status_code != 405, listed


def test_only_a_unions_tags_are_dropped_from_where_an_error_is_located() -> None:
    """A key the body lacks is a union member's tag only when named as pydantic names a
    type: a field a model's own validator put there (a renamed or copied key) stays."""
    from app.api.errors import _located

    body = {"params": {"limit": "x", "start": {"a": 1}}}
    refused = [
        {"loc": ("body", "params", "ceiling", "int"), "msg": "m", "type": "int_type"},
        {"loc": ("body", "params", "ceiling"), "msg": "m", "type": "int_type"},
        {
            "loc": ("body", "params", "start", "float"),
            "msg": "Input should be a",
            "type": "float_type",
        },
        {
            "loc": ("body", "params", "start", "str"),
            "msg": "Input should be b",
            "type": "string_type",
        },
    ]
    assert [(e["loc"], e["msg"]) for e in _located(refused, body)] == [
        (("body", "params", "ceiling", "int"), "m"),
        (("body", "params", "ceiling"), "m"),
        (("body", "params", "start"), "Input should be a or b"),
    ]


def test_every_answer_carries_a_request_id_and_a_plausible_one_is_kept(api: Api) -> None:
    assert len(api.get("/health").headers["X-Request-ID"]) >= 8
    kept = api.client.get("/health", headers={"X-Request-ID": "client-trace-0001"})
    assert kept.headers["X-Request-ID"] == "client-trace-0001"
    replaced = api.client.get("/health", headers={"X-Request-ID": "<script>"})
    assert replaced.headers["X-Request-ID"] != "<script>"


def test_a_bad_train_sequence_is_a_422_naming_the_level(api: Api) -> None:
    scenario_id = api.create_scenario()["id"]
    bad = [[9, *GOOD_SEQUENCE[0][1:]]]
    response = api.submit("train", scenario_id, params={"sequence": bad})
    assert response.status_code == 422
    assert "level index 9" in response.text


@pytest.mark.parametrize(
    ("body", "fragment"),
    [
        ('{"scenario_id": "x", "seed": ' + "9" * 5000 + "}", "Exceeds the limit (4300 digits)"),
        ("[" * 100_000 + "]" * 100_000, "maximum recursion depth exceeded"),
    ],
)
def test_a_json_body_past_what_the_parser_takes_is_a_422_saying_why(
    api: Api, body: str, fragment: str
) -> None:
    """FastAPI answered these 400 "There was an error parsing the body", naming nothing
    (a reviewer's schemathesis-style probe); every JSON route now says what was wrong."""
    for route in ("/jobs", f"/scenarios/{api.create_scenario()['id']}/plan"):
        response = api.post_raw_json(route, body)
        assert response.status_code == 422, (route, response.text)
        message = response.json()["detail"][0]["msg"]
        assert message.startswith("request body is not acceptable JSON") and fragment in message
    # The other HTTP errors are FastAPI's as before.
    assert api.get("/jobs/nope").status_code == 404
    assert api.client.post("/jobs", json={}).status_code == 401


def _duplicate_refused(response: object, loc: list[str | int], key: str) -> None:
    assert response.status_code == 422, response.text  # type: ignore[attr-defined]
    (error,) = response.json()["detail"]  # type: ignore[attr-defined]
    assert error["loc"] == loc and error["type"] == "value_error"
    assert error["msg"].startswith(f"duplicate key {key!r} in ")


def test_a_json_body_with_a_key_given_twice_is_a_422_naming_the_key_and_the_object(
    api: Api, classifier: object
) -> None:
    """``json.loads`` keeps the last of two values without a word: a flight team's body
    with two ``omega_rad_s`` was judged on the second, a scenario with two
    ``inertia_candidates`` stored with the second (a hostile review)."""
    scenario = api.get(f"/scenarios/{api.create_scenario()['id']}").json()["document"]
    candidates = '"inertia_candidates": ' + json.dumps(scenario["inertia_candidates"])
    body = json.dumps({"scenario": scenario}).replace(candidates, f"{candidates}, {candidates}")
    response = api.post_raw_json("/scenarios", body)
    _duplicate_refused(response, ["body", "scenario"], "inertia_candidates")
    assert "in object at scenario" in response.json()["detail"][0]["msg"]

    scenario_id = api.create_scenario()["id"]
    plan = '{"sequence": [[4, 4, 4, 0, 0, 0]], "sequence": [[0, 0, 0, 4, 4, 4]]}'
    response = api.post_raw_json(f"/scenarios/{scenario_id}/plan", plan)
    _duplicate_refused(response, ["body"], "sequence")
    assert "in the top-level object" in response.json()["detail"][0]["msg"]
    job = f'{{"type": "train", "scenario_id": "{scenario_id}", "seed": 1, "seed": 2}}'
    _duplicate_refused(api.post_raw_json("/jobs", job), ["body"], "seed")
    assert not api.queued_messages()

    classifier_id = api.insert_classifier(scenario_id, classifier)  # type: ignore[arg-type]
    rates = '"omega_rad_s": ' + json.dumps([[0.0, 0.0, 0.0]] * 80)
    telemetry = f'{{"time_s": {[0.05 * (i + 1) for i in range(80)]}, {rates}, {rates}}}'
    body = f'{{"classifier_id": "{classifier_id}", "telemetry": {telemetry}}}'
    for route in ("/identify", "/identify/partial"):
        response = api.post_raw_json(route, body)
        _duplicate_refused(response, ["body", "telemetry"], "omega_rad_s")
        msg = response.json()["detail"][0]["msg"]
        assert msg == "duplicate key 'omega_rad_s' in object at telemetry"

    sequence = '[[4,4,4,0,0,0], {"a": 1, "a": 2}]'
    response = api.get_with_key(f"/scenarios/{scenario_id}/response", params={"sequence": sequence})
    _duplicate_refused(response, ["query", "sequence", 1], "a")


def test_every_api_route_refuses_a_key_given_twice(api: Api) -> None:
    """A router added without the route class would take the last of two keys again (the
    app includes the routers of ``ROUTERS``; the dashboard and the docs add GETs of their
    own)."""
    routes = [*api.app.routes, *(route for router in ROUTERS for route in router.routes)]
    routes = [r for r in routes if isinstance(r, APIRoute) and r.methods - {"GET", "HEAD"}]
    assert len(routes) > 5
    assert [r.path for r in routes if not isinstance(r, UniqueKeysRoute)] == []


@pytest.mark.parametrize(
    ("pragma", "says"),
    [
        # Each SQLite connection limited to the pages the file has: the next page is
        # SQLITE_FULL, "database or disk is full", as on a full disk.
        ("max_page_count", "the disk that holds it is full"),
        # query_only: SQLITE_READONLY, "attempt to write a readonly database".
        ("query_only", "it is read-only"),
    ],
)
def test_a_database_that_cannot_store_is_a_503_saying_why_not_unreachable(
    api: Api, pragma: str, says: str, caplog: pytest.LogCaptureFixture
) -> None:
    # Before: both were "the database cannot be reached; try again shortly", while /health
    # said the database was reachable: the operator was sent to the network, not the disk.
    if api.db.engine.dialect.name != "sqlite":
        pytest.skip("SQLite's per-connection limits stand in for a full or read-only disk")
    with api.db.engine.connect() as connection:
        pages = connection.exec_driver_sql("PRAGMA page_count").scalar()
    value = pages if pragma == "max_page_count" else 1

    def limit(dbapi_connection: Any, _record: Any) -> None:
        dbapi_connection.execute(f"PRAGMA {pragma} = {value}")

    event.listen(api.db.engine, "connect", limit)
    api.db.engine.dispose()
    try:
        with caplog.at_level(logging.ERROR, logger="app.api.errors"):
            # Scenarios until one needs a page the file may not have (a few fit in the
            # free room of its last pages).
            for _ in range(50):
                response = api.post("/scenarios", json={"preset": "paper"})
                if response.status_code != 201:
                    break
    finally:
        event.remove(api.db.engine, "connect", limit)
        api.db.engine.dispose()
    assert response.status_code == 503, response.text
    detail = response.json()["detail"]
    assert says in detail and "cannot be reached" not in detail
    assert response.headers["Retry-After"] == "30"
    assert "database cannot store" in caplog.text
    # Once the database takes writes again, so does the service.
    assert api.post("/scenarios", json={"preset": "paper"}).status_code == 201


def test_a_read_only_postgresql_is_a_503_saying_so_not_a_500(
    api: Api, caplog: pytest.LogCaptureFixture
) -> None:
    # Before: a write in a read-only transaction (SQLSTATE 25006: a hot standby, or
    # default_transaction_read_only on) is an InternalError, answered as a defect, 500.
    if api.db.engine.dialect.name != "postgresql":
        pytest.skip("a PostgreSQL database set read-only")
    with read_only_postgres(api), caplog.at_level(logging.ERROR, logger="app.api.errors"):
        response = api.post("/scenarios", json={"preset": "paper"})
        # Reads go on.
        assert api.get("/scenarios").status_code == 200
    assert response.status_code == 503, response.text
    assert response.json()["detail"] == (
        "the database takes no writes: it is read-only; make it writable, then try again"
    )
    assert response.headers["Retry-After"] == "30"
    assert "database cannot store (read-only)" in caplog.text
    assert api.post("/scenarios", json={"preset": "paper"}).status_code == 201


def _answered_within(seconds: float, api: Api, path: str) -> Any:
    """``api.get(path)``'s response, asked on a thread of its own; a failure if it still
    waits after ``seconds`` (a bound well past the one the API is meant to keep)."""
    outcome: list[Any] = []
    thread = threading.Thread(target=lambda: outcome.append(api.get(path)), daemon=True)
    thread.start()
    thread.join(seconds)
    if thread.is_alive() or not outcome:
        pytest.fail(f"GET {path} still waited {seconds:g} s after the database fell silent")
    return outcome[0]


@pytest.mark.parametrize("database_url", ["postgresql"], indirect=True)
def test_a_database_gone_silent_is_a_503_not_a_request_left_waiting(
    make_api: Callable[..., Api],
    tmp_path: Path,
    database_url: str,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The API's database stops answering, its packets lost rather than refused (a
    partition, a firewall, a dead host). Before, a request that needed a new connection
    waited for ever on its connect (libpq's default; the kernel's SYN retries, about
    130 s, where nothing takes the connection), holding its request slot and its
    caller. Now libpq gives the connect up after DATABASE_SILENT_S (2 s here, libpq's
    least), and the request is the 503 an unreachable database gets; /health says so."""
    monkeypatch.setattr(app.main, "DATABASE_SILENT_S", 2.0)
    url = make_url(database_url)
    proxy = SilentableProxy(url.host or "127.0.0.1", url.port or 5432)
    try:
        through = url.set(host="127.0.0.1", port=proxy.port).render_as_string(hide_password=False)
        api = make_api(make_settings(tmp_path, through))
        assert api.get("/jobs").status_code == 200
        proxy.silence()
        # The pool's connections let go of (as after their server went away): the next
        # request connects anew, to a proxy that takes the connection and never answers.
        api.db.dispose()
        response = _answered_within(30.0, api, "/jobs")
        assert response.status_code == 503
        assert response.json() == {"detail": "the database cannot be reached; try again shortly"}
        health = _answered_within(30.0, api, "/health")
        assert health.status_code == 200
        assert health.json()["database"] == {
            "ok": False,
            "takes_writes": None,
            "detail": "postgresql unreachable",
        }
    finally:
        proxy.close()


@pytest.mark.parametrize("database_url", ["postgresql"], indirect=True)
def test_a_statement_the_database_never_answers_is_a_503_not_a_request_left_waiting(
    make_api: Callable[..., Api],
    tmp_path: Path,
    database_url: str,
    monkeypatch: pytest.MonkeyPatch,
    caplog: pytest.LogCaptureFixture,
) -> None:
    """The API's database behind a proxy that still acknowledges what is sent but passes
    nothing on (frozen): no network bound fires (the kernel acknowledges), and a
    server-side statement_timeout cannot (the server hears nothing). Before, a request
    over a pooled connection waited for ever (still waiting 30 s on, measured). Now a
    statement unanswered INERTIA_ID_DATABASE_ANSWER_TIMEOUT_S (2 s here) after it was
    sent has its connection cut: the request is the 503 an unreachable database gets,
    and the pool discards that connection."""
    monkeypatch.setattr(app.main, "DATABASE_SILENT_S", 2.0)
    url = make_url(database_url)
    proxy = SilentableProxy(url.host or "127.0.0.1", url.port or 5432)
    try:
        through = url.set(host="127.0.0.1", port=proxy.port).render_as_string(hide_password=False)
        api = make_api(make_settings(tmp_path, through, INERTIA_ID_DATABASE_ANSWER_TIMEOUT_S=2.0))
        assert api.get("/jobs").status_code == 200
        # The pool keeps its connection open: the next request's ping goes out on it.
        proxy.silence()
        with caplog.at_level(logging.WARNING):
            response = _answered_within(30.0, api, "/jobs")
        assert response.status_code == 503, response.text
        assert response.json() == {"detail": "the database cannot be reached; try again shortly"}
        assert response.headers["Retry-After"] == "5"
        assert "gave no answer to a statement within 2 s" in caplog.text
        # Once the database answers again, so does the API, on a new connection.
        proxy.speak_again()
        assert api.get("/jobs").status_code == 200
    finally:
        proxy.close()


@pytest.mark.parametrize("database_url", ["postgresql"], indirect=True)
def test_a_slow_database_that_answers_within_the_bound_is_not_cut(database_url: str) -> None:
    """The answer bound cuts a statement that gets no answer, not a server that is slow:
    a statement answered after most of the bound is kept, and so is a connection that
    runs statements back to back for longer than the bound, each answered in time."""
    from sqlalchemy import text

    from service.store import Database

    database = Database(database_url, answer_within_s=3.0)
    try:
        with database.session() as session:
            assert session.execute(text("SELECT pg_sleep(1.5), 7")).one()[1] == 7
        with database.session() as session:
            for step in range(22):  # about 4.4 s of statements on one connection
                assert (
                    session.execute(text("SELECT pg_sleep(0.2), :n"), {"n": step}).one()[1] == step
                )
    finally:
        database.dispose()


@pytest.mark.parametrize("database_url", ["postgresql"], indirect=True)
def test_a_statement_waiting_on_a_row_lock_past_the_bound_is_not_cut(database_url: str) -> None:
    """A statement the server is at work on (here, waiting for a row lock another
    transaction holds for longer than the answer bound) is slow, not unanswered: it is
    not cut. Before, it was cut at the bound (the request a 503 "cannot be reached",
    from a database that answered), and its backend went on waiting for the lock, its
    client gone."""
    import psycopg
    from sqlalchemy import text

    from service.store import Database

    raw = make_url(database_url).set(drivername="postgresql").render_as_string(hide_password=False)
    with psycopg.connect(raw, autocommit=True) as setup:
        setup.execute("CREATE TABLE answer_bound_lock (id int PRIMARY KEY, n int)")
        setup.execute("INSERT INTO answer_bound_lock VALUES (1, 0)")
    database = Database(database_url, answer_within_s=1.0)
    holder = psycopg.connect(raw)
    try:
        holder.execute("SELECT n FROM answer_bound_lock WHERE id = 1 FOR UPDATE")
        waiter_pid: list[int] = []
        with psycopg.connect(raw, autocommit=True) as watch:

            def release_once_waiting() -> None:
                # Released once the session below has waited on the lock for 4 bounds.
                for _look in range(600):
                    rows = watch.execute(
                        "SELECT pid FROM pg_stat_activity WHERE wait_event_type = 'Lock' "
                        "AND query LIKE '%answer_bound_lock%FOR UPDATE%'"
                    ).fetchall()
                    if rows:
                        waiter_pid.append(rows[0][0])
                        break
                    threading.Event().wait(0.05)
                threading.Event().wait(4.0)
                holder.commit()

            releaser = threading.Thread(target=release_once_waiting)
            releaser.start()
            with database.session() as session:
                session.execute(
                    text("SELECT n FROM answer_bound_lock WHERE id = 1 FOR UPDATE")
                ).all()
                session.execute(text("UPDATE answer_bound_lock SET n = n + 1 WHERE id = 1"))
            releaser.join()
        assert waiter_pid
        with database.session() as session:
            assert session.execute(text("SELECT n FROM answer_bound_lock")).scalar_one() == 1
    finally:
        holder.close()
        database.dispose()


@pytest.mark.parametrize("database_url", ["postgresql"], indirect=True)
def test_a_statement_whose_answer_is_stuck_on_the_way_is_cut(
    database_url: str, caplog: pytest.LogCaptureFixture
) -> None:
    """A backend that is active only in sending its answer, which does not get through
    (here, a client that reads none of it; as behind a proxy frozen on that connection
    alone, the server's new connections still answered), is not at work on the
    statement: it is cut at the bound. Counted as at work, it was never cut."""
    from service.store import Database

    database = Database(database_url, answer_within_s=1.0)
    raw = database.engine.raw_connection()
    try:
        pgconn = raw.driver_connection.pgconn  # type: ignore[union-attr]
        with caplog.at_level(logging.WARNING, logger="service.store.answers"):
            # An answer far larger than the sockets' buffers, sent, never read.
            pgconn.send_query(b"SELECT repeat('x', 200000000)")
            for _look in range(300):
                if "gave no answer to a statement within 1 s" in caplog.text:
                    break
                threading.Event().wait(0.1)
        assert "gave no answer to a statement within 1 s" in caplog.text
    finally:
        raw.invalidate()
        database.dispose()


@pytest.mark.parametrize("database_url", ["postgresql"], indirect=True)
def test_a_commit_the_server_is_at_work_on_past_the_bound_is_not_cut(database_url: str) -> None:
    """A COMMIT that takes the server longer than the answer bound (here a deferred
    trigger's 3 s; a synchronous standby's, a slow disk's) is answered, not cut. Before,
    it was cut at the bound, the request failed as on a lost connection, and the commit
    landed all the same: the client told "cannot be reached" of a row stored."""
    import psycopg
    from sqlalchemy import text

    from service.store import Database

    raw = make_url(database_url).set(drivername="postgresql").render_as_string(hide_password=False)
    with psycopg.connect(raw, autocommit=True) as setup:
        setup.execute("CREATE TABLE answer_bound_commit (id int PRIMARY KEY)")
        setup.execute(
            "CREATE FUNCTION answer_bound_slow() RETURNS trigger LANGUAGE plpgsql AS "
            "$$ BEGIN PERFORM pg_sleep(3); RETURN NULL; END $$"
        )
        setup.execute(
            "CREATE CONSTRAINT TRIGGER answer_bound_slow AFTER INSERT ON answer_bound_commit "
            "DEFERRABLE INITIALLY DEFERRED FOR EACH ROW EXECUTE FUNCTION answer_bound_slow()"
        )
    database = Database(database_url, answer_within_s=1.0)
    try:
        with database.session() as session:
            session.execute(text("INSERT INTO answer_bound_commit VALUES (1)"))
        with database.session() as session:
            assert session.execute(text("SELECT id FROM answer_bound_commit")).all() == [(1,)]
    finally:
        database.dispose()


def test_a_long_unknown_id_is_quoted_with_its_cut_marked(api: Api) -> None:
    """A 5,000-character id was quoted as its first 80 characters and nothing more: the
    404 named another id, one that could exist. The cut is marked now, with the length."""
    long_id = "a" * 80 + "b" * 4920
    for route, what in (("/jobs/", "job"), ("/scenarios/", "scenario")):
        response = api.get(route + long_id)
        assert response.status_code == 404, response.text
        assert response.json()["detail"] == f"{what} {'a' * 80!r}… (5000 characters) not found"
    # An id short enough is quoted whole, as before.
    response = api.get("/jobs/" + "c" * 80)
    assert response.json()["detail"] == f"job {'c' * 80!r} not found"


def test_a_long_sent_value_is_quoted_with_its_cut_marked(api: Api) -> None:
    """A header or query value quoted in a refusal was cut at 80 characters without a word
    (routing, idempotency, identify), where an unknown id's 404 said
    "…" and the length: the message named a shorter value, one the client could have
    sent. Every refusal marks the cut now, as the 404's does (deps.quoted)."""
    long = "a" * 80 + "b" * 20
    body = b'{"preset": "paper"}'
    answers = {
        "415 on a JSON route's Content-Type": api.client.post(
            "/scenarios", content=body, headers={**api.auth, "content-type": f"text/{long}"}
        ),
        "415 on a JSON route's Content-Encoding": api.client.post(
            "/scenarios",
            content=body,
            headers={
                **api.auth,
                "content-type": "application/json",
                "content-encoding": long,
            },
        ),
        "415 on /identify's Content-Type": api.client.post(
            "/identify", content=body, headers={**api.auth, "content-type": long}
        ),
        "415 on /identify's Content-Encoding": api.client.post(
            "/identify",
            content=body,
            headers={**api.auth, "content-type": "application/json", "content-encoding": long},
        ),
        "422 on an Idempotency-Key": api.client.post(
            "/scenarios",
            content=body,
            headers={
                **api.auth,
                "content-type": "application/json",
                "idempotency-key": long + ",x",
            },
        ),
    }
    for what, response in answers.items():
        assert response.status_code in (415, 422), (what, response.text)
        detail = response.json()["detail"]
        text = detail if isinstance(detail, str) else detail[0]["msg"]
        assert re.search(r"a{70,80}'… \(1[0-9]{2} characters\)", text), (what, text)


def test_a_list_where_a_number_goes_is_quoted_in_the_422(api: Api) -> None:
    """A list or an object sent for a number was refused without the value ("Input should
    be a valid integer"), where a scalar is quoted; now it is quoted too, cut short."""
    scenario_id = api.create_scenario()["id"]
    response = api.submit("train", scenario_id, params={"sequence": [[[4], 4, 4, 0, 0, 0]]})
    assert response.status_code == 422, response.text
    (error,) = response.json()["detail"]
    assert error["loc"] == ["body", "params", "sequence", 0, 0]
    assert error["msg"] == "Input should be a valid integer, got [4]"
    overrides = {"timing": {"integration_step_s": 0.05, "sample_rate_hz": [1]}}
    response = api.post("/scenarios", json={"preset": "paper", "overrides": overrides})
    assert response.status_code == 422, response.text
    (error,) = response.json()["detail"]
    assert error["loc"] == ["body", "overrides", "timing", "sample_rate_hz"]
    assert error["msg"] == "Input should be a valid number, got [1]"
    # A long one is quoted by its first items, within 120 characters.
    overrides = {"timing": {"integration_step_s": 0.05, "sample_rate_hz": [1.5] * 100_000}}
    response = api.post("/scenarios", json={"preset": "paper", "overrides": overrides})
    (error,) = response.json()["detail"]
    quoted = error["msg"].removeprefix("Input should be a valid number, got ")
    assert quoted == "[1.5, 1.5, 1.5, 1.5, 1.5, 1.5, ...]"
