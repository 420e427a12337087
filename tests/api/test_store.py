"""The job store under concurrency: the database, not luck, keeps submissions apart."""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any

import pytest
from sqlalchemy import func, select
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from inertia_id import Scenario
from service.store import Database, JobRow, ScenarioRow, upgrade
from service.store import jobs as store_jobs
from service.store.jobs import ScenarioGone, cancel, create_job, finish
from service.store.models import utcnow

PARAMS: dict[str, Any] = {"sequence": [[4, 4, 4, 0, 0, 0]] * 4, "metric": "euclidean"}


@pytest.fixture
def db(database_url: str) -> Database:
    upgrade(database_url)
    database = Database(database_url)
    yield database  # type: ignore[misc]
    database.dispose()


@pytest.fixture
def scenario_id(db: Database) -> str:
    """A stored paper scenario, which every submission below refers to."""
    with db.session() as session:
        row = ScenarioRow(name="paper", document=Scenario.paper().model_dump(mode="json"))
        session.add(row)
        session.flush()
        return row.id


def _at_once(count: int, work: Callable[[], Any]) -> list[Any]:
    """Run ``work`` on ``count`` threads released together; results or exceptions."""
    barrier = threading.Barrier(count)
    results: list[Any] = [None] * count

    def run(index: int) -> None:
        barrier.wait()
        try:
            results[index] = work()
        except Exception as exc:
            results[index] = exc

    threads = [threading.Thread(target=run, args=(i,)) for i in range(count)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(60)
    return results


def _job(session: Session, job_id: str) -> JobRow:
    """The job's row, which must exist."""
    job = session.get(JobRow, job_id)
    assert job is not None
    return job


def _succeed(db: Database, job_id: str) -> None:
    """Run the job to success, as a worker would: it stands, finished."""
    with db.session() as session:
        _job(session, job_id).status = "running"
        assert finish(session, job_id, "succeeded", result={})


def _count_jobs(db: Database) -> int:
    with db.session() as session:
        return int(session.scalar(select(func.count()).select_from(JobRow)) or 0)


def _submit(db: Database, scenario_id: str, **options: Any) -> tuple[str, bool]:
    with db.session() as session:
        job, reused = create_job(
            session, job_type="train", scenario_id=scenario_id, params=PARAMS, seed=0, **options
        )
        return job.id, reused


def test_identical_submissions_at_once_make_one_job(db: Database, scenario_id: str) -> None:
    results = _at_once(10, lambda: _submit(db, scenario_id))
    assert not [r for r in results if isinstance(r, Exception)], results
    assert len({job_id for job_id, _ in results}) == 1
    assert sorted(reused for _, reused in results) == [False] + [True] * 9
    with db.session() as session:
        assert session.scalar(select(func.count()).select_from(JobRow)) == 1


def test_reruns_at_once_leave_one_job_standing_for_later_submissions(
    db: Database, scenario_id: str
) -> None:
    first, _ = _submit(db, scenario_id)
    _succeed(db, first)
    results = _at_once(5, lambda: _submit(db, scenario_id, rerun=True))
    assert not [r for r in results if isinstance(r, Exception)], results
    standing, reused = _submit(db, scenario_id)
    assert reused and standing != first
    assert standing in {job_id for job_id, _ in results}


def test_identical_reruns_at_once_make_one_new_job_the_others_reuse(
    db: Database, scenario_id: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    # A rerun asks for a run fresher than the job that stood when it was asked: one new
    # job made while the reruns were in flight answers all of them (before: 6 new jobs
    # and 4 reused of 10, neither one nor ten).
    first, _ = _submit(db, scenario_id)
    _succeed(db, first)
    # All ten asked before any of them writes: each has read the job that stands then.
    asked = threading.Barrier(10)
    read = store_jobs._standing_ids if hasattr(store_jobs, "_standing_ids") else None

    def standing_then_wait(session: Session, digest: str) -> set[str]:
        ids = read(session, digest) if read else set()
        asked.wait(30)
        return ids

    monkeypatch.setattr(store_jobs, "_standing_ids", standing_then_wait, raising=False)
    results = _at_once(10, lambda: _submit(db, scenario_id, rerun=True))
    monkeypatch.undo()
    assert not [r for r in results if isinstance(r, Exception)], results
    assert len({job_id for job_id, _ in results}) == 1, results
    assert sorted(reused for _, reused in results) == [False] + [True] * 9
    (fresh,) = {job_id for job_id, _ in results}
    assert fresh != first
    with db.session() as session:
        assert session.scalar(select(func.count()).select_from(JobRow)) == 2
    # A rerun asked once that job has finished makes a new job again.
    _succeed(db, fresh)
    again, reused = _submit(db, scenario_id, rerun=True)
    assert not reused and again not in (first, fresh)


def test_a_rerun_asked_before_an_identical_reruns_job_was_made_takes_that_job(
    db: Database, scenario_id: str
) -> None:
    # The API's checks of a submission take a while: a rerun received before another's
    # job was made, though it reads what stands after that job was committed (and after
    # that job finished), is answered by it; one received after it makes a new job.
    first, _ = _submit(db, scenario_id)
    _succeed(db, first)
    asked_at = utcnow()
    fresh, reused = _submit(db, scenario_id, rerun=True, asked_at=asked_at)
    assert not reused and fresh != first
    _succeed(db, fresh)
    same, reused = _submit(db, scenario_id, rerun=True, asked_at=asked_at)
    assert (same, reused) == (fresh, True)
    later, reused = _submit(db, scenario_id, rerun=True, asked_at=utcnow())
    assert not reused and later not in (first, fresh)


def test_reruns_naming_the_job_they_replace_make_one_new_job_whenever_taken_up(
    db: Database, scenario_id: str
) -> None:
    # Reruns taken up one after another, each after the one before made its job (a
    # busy API, a double click, a retry): named, they make one job (before: rerun_of
    # unknown), though the job each names has finished.
    first, _ = _submit(db, scenario_id)
    _succeed(db, first)
    answers = [_submit(db, scenario_id, rerun_of=first, asked_at=utcnow()) for _ in range(5)]
    fresh = answers[0][0]
    assert answers == [(fresh, False)] + [(fresh, True)] * 4
    assert fresh != first
    with db.session() as session:
        assert session.scalar(select(func.count()).select_from(JobRow)) == 2
        assert _job(session, first).superseded
    # Naming a job that has not finished replaces it all the same: asked for by name.
    named, reused = _submit(db, scenario_id, rerun_of=fresh, asked_at=utcnow())
    assert not reused and named not in (first, fresh)


def test_plain_reruns_of_a_finished_job_taken_up_over_time_make_one_job(
    db: Database, scenario_id: str
) -> None:
    # Twenty dashboards click rerun on the same finished job at once, and a busy API
    # takes the requests up over hundreds of milliseconds: part after the first one's
    # job was made, part after a worker started it. They asked for one fresh run: one
    # job (before: the later waves made one more each on SQLite, 3 jobs in all, and one
    # more on PostgreSQL).
    first, _ = _submit(db, scenario_id)
    _succeed(db, first)

    def rerun() -> tuple[str, bool]:
        return _submit(db, scenario_id, rerun=True, asked_at=utcnow())

    waves = [_at_once(10, rerun), _at_once(10, rerun)]
    made = {job_id for job_id, reused in waves[0] if not reused}
    assert len(made) == 1, waves[0]
    (fresh,) = made
    with db.session() as session:
        _job(session, fresh).status = "running"
    waves.append(_at_once(5, rerun))
    answers = [answer for wave in waves for answer in wave]
    assert not [a for a in answers if isinstance(a, Exception)], answers
    assert {job_id for job_id, _ in answers} == {fresh}, answers
    assert sorted(reused for _, reused in answers) == [False] + [True] * 24
    assert _count_jobs(db) == 2
    # Asked to stop, the job no longer answers a rerun; finished, neither does it.
    with db.session() as session:
        cancel(session, _job(session, fresh))
    stopping, reused = rerun()
    assert not reused and stopping not in (first, fresh)
    _succeed(db, stopping)
    after, reused = rerun()
    assert not reused and after not in (first, fresh, stopping)
    assert _count_jobs(db) == 4


def test_named_reruns_at_once_make_one_new_job(db: Database, scenario_id: str) -> None:
    first, _ = _submit(db, scenario_id)
    results = _at_once(10, lambda: _submit(db, scenario_id, rerun_of=first))
    assert not [r for r in results if isinstance(r, Exception)], results
    assert len({job_id for job_id, _ in results} | {first}) == 2, results
    assert sorted(reused for _, reused in results) == [False] + [True] * 9


def test_named_reruns_of_a_failed_job_at_once_make_one_new_job(
    db: Database, scenario_id: str
) -> None:
    # Nothing stands to lock: the unique index lets one insert through.
    first, _ = _submit(db, scenario_id)
    with db.session() as session:
        _job(session, first).status = "running"
        assert finish(session, first, "failed", error="boom")
    results = _at_once(10, lambda: _submit(db, scenario_id, rerun_of=first))
    assert not [r for r in results if isinstance(r, Exception)], results
    assert len({job_id for job_id, _ in results} | {first}) == 2, results
    assert sorted(reused for _, reused in results) == [False] + [True] * 9


def test_a_failed_or_cancelled_job_no_longer_stands_in(db: Database, scenario_id: str) -> None:
    first, _ = _submit(db, scenario_id)
    with db.session() as session:
        cancel(session, _job(session, first))
    second, reused = _submit(db, scenario_id)
    assert not reused and second != first
    with db.session() as session:
        _job(session, second).status = "running"
        assert finish(session, second, "failed", error="boom")
    third, reused = _submit(db, scenario_id)
    assert not reused and third not in (first, second)


def test_the_database_refuses_a_second_reusable_row_whoever_writes_it(
    db: Database, scenario_id: str
) -> None:
    job_id, _ = _submit(db, scenario_id)
    with db.session() as session:
        digest = _job(session, job_id).config_hash
    with pytest.raises(IntegrityError), db.session() as session:
        session.add(
            JobRow(type="train", scenario_id=scenario_id, params=PARAMS, config_hash=digest)
        )


def test_a_submission_for_a_deleted_scenario_says_so(db: Database, scenario_id: str) -> None:
    with db.session() as session:
        session.delete(session.get(ScenarioRow, scenario_id))
    with pytest.raises(ScenarioGone):
        _submit(db, scenario_id)
    with db.session() as session:
        assert session.scalar(select(func.count()).select_from(JobRow)) == 0


def test_identical_submissions_at_once_replace_a_job_being_cancelled_with_one(
    db: Database, scenario_id: str
) -> None:
    # A running job asked to stop will end cancelled, with no result: submissions of its
    # configuration at once make one job in its place (before: each was handed the job
    # being cancelled), and the later ones are handed that one.
    first, _ = _submit(db, scenario_id)
    with db.session() as session:
        job = _job(session, first)
        job.status = "running"
        cancel(session, job)
    answers = _at_once(10, lambda: _submit(db, scenario_id))
    assert not [a for a in answers if isinstance(a, Exception)], answers
    made = {job_id for job_id, reused in answers if not reused}
    assert len(made) == 1 and first not in made, answers
    assert {job_id for job_id, _ in answers} == made
    assert _count_jobs(db) == 2
    assert _submit(db, scenario_id) == (made.pop(), True)


def test_a_job_finishes_stopped_by_its_time_limit_or_by_nothing_named(
    db: Database, scenario_id: str
) -> None:
    """``jobs.stopped`` holds what the API's ``JobOut.stopped`` may say: "time_limit", or
    nothing. A word the API would not know ("cancel": a cancel is the status's) is
    refused before it is stored, the job left running."""
    job_id, _ = _submit(db, scenario_id)
    with db.session() as session:
        _job(session, job_id).status = "running"
    with db.session() as session, pytest.raises(ValueError, match="not 'cancel'"):
        finish(session, job_id, "cancelled", stopped="cancel")
    with db.session() as session:
        assert _job(session, job_id).status == "running"
        assert finish(session, job_id, "failed", error="past it", stopped="time_limit")
    with db.session() as session:
        assert _job(session, job_id).stopped == "time_limit"
