"""The job runner in-process: every way a job can end, on a real database.

The happy paths run through a real worker in test_worker_jobs.py; here the edges that
need no broker: bad parameters, missing rows, jobs that are not queued, and the
cancel-poll throttle.
"""

from __future__ import annotations

import logging
import os
import threading
from collections.abc import Callable
from dataclasses import replace
from typing import TYPE_CHECKING, Any

import pytest
from scenario_support import GOOD_SEQUENCE
from service_support import POSTGRES_ADMIN_URL, job_clock, writes_refused_while
from sqlalchemy import create_engine, make_url, select, text, update

from inertia_id import Scenario
from inertia_id.pipelines import TrainRequest, train_for_sequence
from service.params import SearchParams
from service.store import ClassifierRow, Database, MetricRow
from service.store.jobs import cancel
from service.store.models import JobRow, utcnow
from worker.context import TIME_LIMIT_GRACE_S
from worker.runner import (
    CANCEL_POLL_S,
    JobContext,
    JobSpec,
    Outcome,
    execute_job,
    json_safe,
    one_line_error,
)

if TYPE_CHECKING:
    from conftest import Store

WORKER = "test@host"


@pytest.mark.parametrize(
    ("job_type", "params", "message"),
    [
        (
            "search",
            {"method": "genetic", "sequence_length": 2, "timesteps": 10, "n_realisations": 2},
            "InputError: the search job's parameters: params.method: Input should be 'ppo'",
        ),
        (
            "train",
            {"sequence": [[9, 4, 4, 0, 0, 0]], "metric": "euclidean", "n_realisations": 2},
            "InputError: sequence step 1, thruster 1: level index 9 is outside 0..4",
        ),
        (
            "sweep",
            {"classifier_id": "nope", "multiples": [1.0], "n_test": 10},
            "InputError: classifier 'nope' does not exist",
        ),
        ("anneal", {}, "job type must be one of"),
    ],
)
def test_a_job_that_raises_fails_with_a_one_line_reason(
    store: Store, job_type: str, params: dict[str, Any], message: str
) -> None:
    job_id = store.add_job(job_type, params)

    assert execute_job(job_id, settings=store.settings, worker_name=WORKER) == "failed"

    job = store.job(job_id)
    assert job.status == "failed" and job.finished_at is not None and job.worker == WORKER
    assert job.error is not None and "\n" not in job.error and message in job.error
    assert job.stopped is None  # no time limit stopped it


def test_a_job_cancelled_while_queued_is_not_run(store: Store) -> None:
    job_id = store.add_job("train", {"sequence": GOOD_SEQUENCE, "n_realisations": 2})
    with store.db.session() as session:
        job = session.get(JobRow, job_id)
        assert job is not None
        cancel(session, job)

    assert execute_job(job_id, settings=store.settings, worker_name=WORKER) == "cancelled"
    job = store.job(job_id)
    assert job.status == "cancelled" and job.started_at is None and job.attempts == 0


def test_a_second_delivery_of_a_finished_job_changes_nothing(store: Store) -> None:
    job_id = store.add_job(
        "train", {"sequence": GOOD_SEQUENCE}, status="succeeded", attempts=1, result={"f1": 1.0}
    )
    assert execute_job(job_id, settings=store.settings, worker_name=WORKER) == "succeeded"
    job = store.job(job_id)
    assert job.attempts == 1 and job.result == {"f1": 1.0} and job.worker is None
    assert execute_job("0" * 32, settings=store.settings, worker_name=WORKER) == "missing"


def test_a_stopping_worker_leaves_a_queued_job_to_another_unsent(store: Store) -> None:
    # Told to stop, its consumer still handed it a message (the job it just handed back,
    # re-sent): it must not run the job until it is killed.
    job_id = store.add_job("train", {"sequence": GOOD_SEQUENCE}, sent_at=utcnow())
    status = execute_job(job_id, settings=store.settings, worker_name=WORKER, stopping=lambda: True)
    assert status == "passed on"
    job = store.job(job_id)
    assert job.status == "queued" and job.attempts == 0 and job.worker is None
    assert job.sent_at is None  # another worker's monitor sends it again


def test_a_job_claimed_as_the_stop_came_is_handed_back_at_no_cost(store: Store) -> None:
    job_id = store.add_job("train", {"sequence": GOOD_SEQUENCE}, sent_at=utcnow())
    # The stop arrives between the check and the claim: the run's first look says no,
    # every later one yes. Only the run's own looks count: its StopCut thread looks every
    # 0.1 s too, and on a loaded CI it had taken the answers meant for the run
    # (StopIteration in the run, PostgreSQL).
    run = threading.get_ident()
    looks: list[bool] = []

    def stopping() -> bool:
        if threading.get_ident() != run:
            return bool(looks) and looks[-1]
        looks.append(bool(looks))
        return looks[-1]

    status = execute_job(job_id, settings=store.settings, worker_name=WORKER, stopping=stopping)
    assert status == "passed on"
    job = store.job(job_id)
    assert job.status == "queued" and job.worker is None and job.sent_at is None
    assert job.attempts == 1 and job.handbacks == 1


def test_a_train_job_stores_its_classifier_and_metrics_in_one_go(store: Store) -> None:
    params = {"sequence": GOOD_SEQUENCE, "metric": "euclidean", "n_realisations": 3}
    job_id = store.add_job("train", params, seed=9)

    assert execute_job(job_id, settings=store.settings, worker_name=WORKER) == "succeeded"

    job = store.job(job_id)
    with store.db.session() as session:
        classifiers = session.scalars(
            select(ClassifierRow).where(ClassifierRow.job_id == job_id)
        ).all()
        metrics = session.execute(
            select(MetricRow.key, MetricRow.step, MetricRow.value).where(MetricRow.job_id == job_id)
        ).all()
    assert [c.id for c in classifiers] == [(job.result or {})["classifier_id"]]
    assert sorted(metrics) == [("accuracy", 0, job.result["accuracy"]), ("f1", 0, job.result["f1"])]


def _spec(store: Store, job_id: str, *, attempt: int) -> JobSpec:
    return JobSpec(
        job_id, "search", SearchParams(), 0, store.scenario_id, Scenario.paper(), attempt=attempt
    )


def test_should_stop_reads_the_cancel_flag_at_most_once_a_second(store: Store) -> None:
    job_id = store.add_job("search", status="running", attempts=1)
    now = [0.0]
    spec = _spec(store, job_id, attempt=1)
    context = JobContext(spec, store.db, store.settings, WORKER, clock=lambda: now[0])
    with store.db.session() as session:
        job = session.get(JobRow, job_id)
        assert job is not None
        cancel(session, job)

    now[0] = CANCEL_POLL_S / 2
    assert not context.should_stop()  # too soon to ask the database
    now[0] = CANCEL_POLL_S
    assert context.should_stop() and context.cancelled and not context.lost


def test_should_stop_notices_a_job_taken_from_this_run(store: Store) -> None:
    # Reaped and claimed again (attempt 2) while this run (attempt 1) was stalled.
    job_id = store.add_job("search", status="running", attempts=2)
    spec = _spec(store, job_id, attempt=1)
    context = JobContext(spec, store.db, store.settings, WORKER)
    assert context.check_now() and context.lost and not context.cancelled


def test_the_outcome_of_a_run_whose_job_was_taken_is_dropped_whole(
    store: Store, monkeypatch: pytest.MonkeyPatch
) -> None:
    from worker import handlers

    job_id = store.add_job("train", {"sequence": GOOD_SEQUENCE})

    def reaped_meanwhile(context: JobContext) -> Outcome:
        # While this run stalled, the reaper re-queued the job and another worker took it.
        with store.db.session() as session:
            job = session.get(JobRow, job_id)
            assert job is not None
            job.attempts, job.worker = 2, "other@host"
        trained = train_for_sequence(
            Scenario.paper(),
            TrainRequest(sequence=GOOD_SEQUENCE, metric="euclidean", n_realisations=3),
            seed=0,
        )
        return Outcome("succeeded", {"f1": 1.0}, metrics=[("f1", 0, 1.0)], classifier=trained)

    monkeypatch.setitem(handlers.HANDLERS, "train", reaped_meanwhile)
    assert execute_job(job_id, settings=store.settings, worker_name=WORKER) == "lost"

    job = store.job(job_id)
    assert job.status == "running" and job.worker == "other@host" and job.result is None
    with store.db.session() as session:
        assert session.scalars(select(ClassifierRow.id)).all() == []
        assert session.scalars(select(MetricRow.id)).all() == []


def test_a_result_that_cannot_be_stored_fails_the_job_with_the_reason(
    store: Store, monkeypatch: pytest.MonkeyPatch
) -> None:
    from worker import handlers

    job_id = store.add_job("train", {"sequence": GOOD_SEQUENCE})

    def unstorable(context: JobContext) -> Outcome:
        return Outcome("succeeded", {"model": object()}, metrics=[("f1", 0, 1.0)])

    monkeypatch.setitem(handlers.HANDLERS, "train", unstorable)
    assert execute_job(job_id, settings=store.settings, worker_name=WORKER) == "failed"

    job = store.job(job_id)
    assert job.status == "failed" and job.result is None
    assert job.error is not None and job.error.startswith("could not store the result: TypeError")
    with store.db.session() as session:
        assert session.scalars(select(MetricRow.id)).all() == []


def test_a_worker_that_cannot_import_the_core_fails_the_job_instead_of_dropping_it(
    store: Store, monkeypatch: pytest.MonkeyPatch
) -> None:
    import worker.runner

    def broken() -> dict[str, Any]:
        raise ImportError("libtorch_cpu.so: cannot open shared object file")

    monkeypatch.setattr(worker.runner, "_import_handlers", broken)
    job_id = store.add_job("search", {"method": "random"})

    assert execute_job(job_id, settings=store.settings, worker_name=WORKER) == "failed"
    job = store.job(job_id)
    assert job.status == "failed" and job.error is not None
    assert "cannot load the science core (ImportError: libtorch_cpu.so" in job.error


def test_a_stop_wrapped_by_compiled_code_hands_the_job_back_not_fails_it(
    store: Store, monkeypatch: pytest.MonkeyPatch
) -> None:
    """SIGTERM raises SystemExit in a task process; raised inside numba's code it comes
    out as a SystemError caused by it (CPython's "returned a result with an exception
    set"). The run raises the stop, so the main process hands the job back; before, the
    job was failed with the SystemError, an attempt spent."""
    import worker.runner

    def stopped_inside_compiled_code(context: JobContext) -> Outcome:
        try:
            raise SystemExit(143)
        except SystemExit as stop:
            raise SystemError("<function _lloyd> returned a result with an exception set") from stop

    monkeypatch.setattr(
        worker.runner, "_import_handlers", lambda: {"search": stopped_inside_compiled_code}
    )
    job_id = store.add_job("search", {"method": "random"})

    with pytest.raises(SystemExit):
        execute_job(job_id, settings=store.settings, worker_name=WORKER)
    job = store.job(job_id)
    assert job.status == "running" and job.error is None  # the main process hands it back


def test_one_line_error_names_the_type_and_flattens_the_message() -> None:
    error = ValueError("first line\n  second line")
    assert one_line_error(error) == "ValueError: first line second line"
    assert one_line_error(KeyError()) == "KeyError"
    assert len(one_line_error(RuntimeError("x" * 10_000))) == 2000


def test_json_safe_turns_nan_and_infinity_into_null() -> None:
    value = {"curve": [float("nan"), 1.5, float("-inf")], "n": 3, "name": "x"}
    assert json_safe(value) == {"curve": [None, 1.5, None], "n": 3, "name": "x"}


def test_the_stop_raised_in_the_worker_is_seen_by_task_processes_it_forked() -> None:
    from worker import process

    read, write = os.pipe()
    child = os.fork()
    if child == 0:  # a task process: forked before the stop, it reads the flag after
        os.read(read, 1)
        os._exit(7 if process.stopping() else 3)
    try:
        assert not process.stopping()
        process.mark_stopping()
        os.write(write, b"x")
        _, code = os.waitpid(child, 0)
        assert os.waitstatus_to_exitcode(code) == 7
    finally:
        process._STOPPING[0] = 0
        os.close(read)
        os.close(write)


# Time limits.


def test_a_search_job_past_its_time_limit_succeeds_with_its_best(store: Store) -> None:
    params = {"method": "random", "sequence_length": 2, "timesteps": 100_000, "n_realisations": 2}
    job_id = store.add_job("search", params)
    # A ceiling spent at once: the search plays one sequence, then stops.
    limited = store.settings.model_copy(update={"job_time_limit_s": 1e-9})
    assert execute_job(job_id, settings=limited, worker_name=WORKER) == "succeeded"
    job = store.job(job_id)
    result = job.result or {}
    assert job.status == "succeeded" and result["stopped"] == "time_limit"
    # The job says it too, as a failed training does: jobs.stopped, for every job alike.
    assert job.stopped == "time_limit"
    # Re-scored while the grace lasts (10 s of the worker's clock): what it reached, it says.
    assert result["best"]["sequence"] and result["fresh"]["draws_asked"] == 5
    assert len(result["fresh"]["f1"]) <= 5
    assert result["settings"]["time_limit_s"] == 1e-9
    assert result["settings"]["time_limit_grace_s"] == 10.0


def test_a_search_job_runs_to_its_own_limit_below_the_ceiling(store: Store) -> None:
    spec = JobSpec(
        "j", "search", SearchParams(time_limit_s=30), 0, store.scenario_id, Scenario.paper(),
        attempt=1,
    )  # fmt: skip
    context = JobContext(spec, store.db, store.settings, WORKER, clock=lambda: 0.0)
    assert context.time_limit_s == 30.0
    roomy = JobContext(
        spec, store.db, store.settings.model_copy(update={"job_time_limit_s": 10.0}), WORKER
    )
    assert roomy.time_limit_s == 10.0  # the ceiling wins
    # The heartbeat's backstop counts the grace the job asked for, else the default.
    assert context.rescore_grace_s == 10.0
    strict = replace(spec, params=SearchParams(time_limit_s=30, time_limit_grace_s=0))
    assert JobContext(strict, store.db, store.settings, WORKER).rescore_grace_s == 0.0
    # A job at the 6 h ceiling: the default grace's cap (300 s), not a tenth (36 min).
    at_ceiling = replace(spec, params=SearchParams())
    six_hours = store.settings.model_copy(update={"job_time_limit_s": 6 * 3600.0})
    assert JobContext(at_ceiling, store.db, six_hours, WORKER).rescore_grace_s == 300.0


def _sweep_job(store: Store, **params: Any) -> str:
    """A sweep job (2 noises x 2 multiples) of a quick classifier trained by a job."""
    train = store.add_job(
        "train",
        {
            "sequence": GOOD_SEQUENCE,
            "kind": "nearest-centroid",
            "metric": "euclidean",
            "n_realisations": 3,
        },
    )
    assert execute_job(train, settings=store.settings, worker_name=WORKER) == "succeeded"
    classifier_id = (store.job(train).result or {})["classifier_id"]
    sweep = {
        "classifier_id": classifier_id,
        "multiples": [1.0, 2.0],
        "n_test": 10,
        "others": [],
        "ceiling_realisations": 0,
    }
    return store.add_job("sweep", {**sweep, **params})


def test_a_sweep_job_past_its_time_limit_keeps_the_points_done(
    store: Store, monkeypatch: pytest.MonkeyPatch
) -> None:
    job_id = _sweep_job(store, time_limit_s=1.0)
    # The job's clock stands at its claim until the first point is reported, then at
    # its limit: spent after exactly one point, on any machine.
    now = job_clock(monkeypatch, after_claim=0.0)
    report = JobContext.report

    def report_then_spend(self: JobContext, **kwargs: Any) -> None:
        report(self, **kwargs)
        now[0] = 1.0

    monkeypatch.setattr(JobContext, "report", report_then_spend)
    assert execute_job(job_id, settings=store.settings, worker_name=WORKER) == "succeeded"
    job = store.job(job_id)
    result = job.result or {}
    assert result["stopped"] == "time_limit" and result["time_limit_s"] == 1.0
    assert len(result["points"]) == 1  # of 2 noises x 2 multiples
    assert job.stopped == "time_limit"


@pytest.mark.parametrize("whose", ["the service's ceiling", "the job's own"])
def test_a_sweep_job_whose_limit_ran_out_before_its_first_point_fails_naming_it(
    store: Store, monkeypatch: pytest.MonkeyPatch, whose: str
) -> None:
    """It "succeeded" with no point at all, ``stopped: time_limit``: a job that stored
    nothing read as done. Now it fails as a training past its limit does."""
    settings = store.settings
    if whose == "the job's own":
        job_id = _sweep_job(store, time_limit_s=1.0)
        job_clock(monkeypatch, after_claim=1.0)  # spent at the first check
        limit = "1 s"
    else:
        job_id = _sweep_job(store)
        settings = settings.model_copy(update={"job_time_limit_s": 1e-9})
        limit = "1e-09 s"
    assert execute_job(job_id, settings=settings, worker_name=WORKER) == "failed"
    job = store.job(job_id)
    assert job.result is None and job.stopped == "time_limit"
    assert job.error == (
        f"JobTimeLimitExceeded: the job exceeded its time limit of {limit} before the first "
        "sweep point"
    )
    with store.db.session() as session:
        assert session.scalars(select(MetricRow).where(MetricRow.job_id == job_id)).all() == []


@pytest.mark.parametrize("whose", ["the service's ceiling", "the job's own"])
def test_a_train_job_past_its_time_limit_fails_naming_it(
    store: Store, monkeypatch: pytest.MonkeyPatch, whose: str
) -> None:
    params: dict[str, Any] = {
        "sequence": GOOD_SEQUENCE,
        "kind": "nearest-centroid",
        "metric": "euclidean",
        "n_realisations": 3,
    }
    settings = store.settings
    if whose == "the job's own":
        # Under the service's ceiling (6 h), as a search or sweep may ask; the job's
        # clock reads its limit from the claim on: spent at the first checkpoint.
        params["time_limit_s"] = 1.0
        job_clock(monkeypatch, after_claim=1.0)
        limit = "1 s"
    else:
        settings = settings.model_copy(update={"job_time_limit_s": 1e-9})
        limit = "1e-09 s"
    job_id = store.add_job("train", params)
    assert execute_job(job_id, settings=settings, worker_name=WORKER) == "failed"
    job = store.job(job_id)
    assert job.error == f"JobTimeLimitExceeded: the job exceeded its time limit of {limit}"
    # A field says it, so that a client need not match the error's words.
    assert job.stopped == "time_limit"
    with store.db.session() as session:
        assert session.scalars(select(ClassifierRow.id)).all() == []


def _count_training(
    monkeypatch: pytest.MonkeyPatch, first_run: Callable[[], None]
) -> dict[str, int]:
    """Count the simulations and calibrations of the trainings that follow, calling
    ``first_run`` after the first simulation."""
    from inertia_id.evaluation import calibration
    from inertia_id.physics.simulate import Simulator

    counts = {"simulations": 0, "calibrations": 0}
    run, calibrate = Simulator.run, calibration.calibrate

    def counted_run(self: Simulator, *args: Any, **kwargs: Any) -> Any:
        result = run(self, *args, **kwargs)
        counts["simulations"] += 1
        if counts["simulations"] == 1:
            first_run()
        return result

    def counted_calibrate(*args: Any, **kwargs: Any) -> Any:
        counts["calibrations"] += 1
        return calibrate(*args, **kwargs)

    monkeypatch.setattr(Simulator, "run", counted_run)
    monkeypatch.setattr(calibration, "calibrate", counted_calibrate)
    return counts


def test_a_train_job_cancelled_while_it_trains_stops_part_way(
    store: Store, monkeypatch: pytest.MonkeyPatch
) -> None:
    # Before, the training ran to its end (calibrated) and only then read the cancel.
    import worker.context

    # The cancel flag read at every checkpoint: the training is caught at the one after
    # the cancel, however fast this machine trains.
    monkeypatch.setattr(worker.context, "CANCEL_POLL_S", 0.0)
    job_id = store.add_job("train", {"sequence": GOOD_SEQUENCE, "n_realisations": 20})

    def cancel_it() -> None:
        with store.db.session() as session:
            job = session.get(JobRow, job_id)
            assert job is not None
            cancel(session, job)

    counts = _count_training(monkeypatch, cancel_it)
    assert execute_job(job_id, settings=store.settings, worker_name=WORKER) == "cancelled"
    # The nominal run (the gyro range's check), then the default kind's three noise runs,
    # the inertia sensitivity and the calibration's draws: cancelled at the nominal run,
    # the training stops at the checkpoint after its first noise run.
    assert counts == {"simulations": 2, "calibrations": 0}
    job = store.job(job_id)
    assert job.status == "cancelled" and job.result is None and job.error is None
    assert job.stopped is None  # a cancel is the status's to say
    with store.db.session() as session:
        assert session.scalars(select(ClassifierRow.id)).all() == []


def test_a_train_job_handed_back_by_its_stopping_worker_stops_part_way(
    store: Store, monkeypatch: pytest.MonkeyPatch
) -> None:
    # A graceful stop (SIGTERM) hands the running job back; before, its training ran on
    # to its end (and the stop waited for it), the result then dropped.
    import worker.context
    from service.store.jobs import hand_back

    monkeypatch.setattr(worker.context, "CANCEL_POLL_S", 0.0)
    job_id = store.add_job("train", {"sequence": GOOD_SEQUENCE, "n_realisations": 20})

    def stop_the_worker() -> None:
        with store.db.session() as session:
            assert hand_back(session, WORKER, f"worker {WORKER} was asked to stop") == [job_id]

    counts = _count_training(monkeypatch, stop_the_worker)
    assert execute_job(job_id, settings=store.settings, worker_name=WORKER) == "lost"
    assert counts == {"simulations": 2, "calibrations": 0}
    job = store.job(job_id)
    assert job.status == "queued" and job.handbacks == 1 and job.result is None
    with store.db.session() as session:
        assert session.scalars(select(ClassifierRow.id)).all() == []


def test_a_train_job_past_its_time_limit_stops_part_way_and_fails_naming_it(
    store: Store, monkeypatch: pytest.MonkeyPatch
) -> None:
    # Before, the training ran to its end and only then failed on the limit.
    job_id = store.add_job("train", {"sequence": GOOD_SEQUENCE, "n_realisations": 20})
    counts = _count_training(monkeypatch, lambda: None)
    limited = store.settings.model_copy(update={"job_time_limit_s": 1e-9})
    assert execute_job(job_id, settings=limited, worker_name=WORKER) == "failed"
    # The nominal run, then the first noise run's checkpoint: past the limit already.
    assert counts == {"simulations": 2, "calibrations": 0}
    job = store.job(job_id)
    assert job.error == "JobTimeLimitExceeded: the job exceeded its time limit of 1e-09 s"
    assert job.stopped == "time_limit"
    with store.db.session() as session:
        assert session.scalars(select(ClassifierRow.id)).all() == []


def test_the_heartbeat_ends_a_job_long_past_its_time_limit(store: Store) -> None:
    job_id = store.add_job("search", status="running", attempts=1)
    now = [0.0]
    settings = store.settings.model_copy(update={"job_time_limit_s": 100.0})
    context = JobContext(
        _spec(store, job_id, attempt=1), store.db, settings, WORKER, clock=lambda: now[0]
    )
    # Past the limit, the search's re-score grace (10 s) and the backstop's: beats on.
    now[0] = 100.0 + 10.0 + TIME_LIMIT_GRACE_S
    context.beat()
    job = store.job(job_id)
    assert job.status == "running" and job.heartbeat_at is not None and not context.lost
    now[0] += 1.0
    context.beat()
    job = store.job(job_id)
    assert job.status == "failed" and context.lost and context.should_stop()
    assert job.error is not None and "exceeded its time limit of 100 s" in job.error
    assert job.stopped == "time_limit"
    assert f"still running {10.0 + TIME_LIMIT_GRACE_S:g} s after it" in job.error


def test_a_result_refused_by_a_full_or_read_only_database_is_kept_and_stored_once_it_can(
    store: Store, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    # Before: the run's result was dropped and the job failed ("could not store the
    # result: ... database or disk is full") once the database took writes again, the
    # work thrown away for a passing condition (a search under inertia-id serve, its
    # SQLite file on a 40 MiB tmpfs filled during the run: failed, where an unreachable
    # database's outcome was kept); before that, the end's write was refused too and the
    # reaper re-ran the job as "heartbeat missed".
    from worker import handlers

    refusing = threading.Event()
    job_id = store.add_job("train", {"sequence": GOOD_SEQUENCE})

    def refused(context: JobContext) -> Outcome:
        refusing.set()
        context.tick()
        context.tick()
        # Writable again a while after the run ends.
        threading.Timer(1.0, refusing.clear).start()
        return Outcome("succeeded", {"f1": 1.0}, metrics=[("f1", 0, 1.0)])

    monkeypatch.setitem(handlers.HANDLERS, "train", refused)
    settings = store.settings.model_copy(update={"heartbeat_interval_s": 0.2})
    with writes_refused_while(refusing), caplog.at_level(logging.WARNING):
        status = execute_job(job_id, settings=settings, worker_name=WORKER)
    assert status == "succeeded"
    job = store.job(job_id)
    assert (job.status, job.result, job.error, job.attempts) == ("succeeded", {"f1": 1.0}, None, 1)
    assert not job.attempt_history
    with store.db.session() as session:
        assert session.scalars(select(MetricRow.value)).all() == [1.0]
    assert caplog.text.count("heartbeat not stored: the database refuses writes (read-only)") == 1
    assert caplog.text.count("could not store its outcome: the database refuses writes") == 1
    assert "its outcome is stored (the database takes writes again)" in caplog.text
    assert "tick failed" not in caplog.text


def test_a_result_refused_past_the_wait_fails_the_job_naming_the_refusal(
    store: Store, monkeypatch: pytest.MonkeyPatch
) -> None:
    # The wait is bounded (INERTIA_ID_OUTCOME_REFUSED_WAIT_S): a result refused past it
    # (say, larger than the room a full disk has left) fails the job, the refusal named,
    # once its end can be stored.
    from worker import handlers

    refusing = threading.Event()
    job_id = store.add_job("train", {"sequence": GOOD_SEQUENCE})

    def refused(context: JobContext) -> Outcome:
        refusing.set()
        threading.Timer(1.0, refusing.clear).start()
        return Outcome("succeeded", {"f1": 1.0})

    monkeypatch.setitem(handlers.HANDLERS, "train", refused)
    settings = store.settings.model_copy(
        update={"heartbeat_interval_s": 0.2, "outcome_refused_wait_s": 0.0}
    )
    with writes_refused_while(refusing):
        status = execute_job(job_id, settings=settings, worker_name=WORKER)
    assert status == "failed"
    job = store.job(job_id)
    assert (job.status, job.result, job.attempts) == ("failed", None, 1)
    assert job.error is not None
    assert job.error.startswith(
        "could not store the result: the database refuses writes (read-only) for 0 s "
        "(INERTIA_ID_OUTCOME_REFUSED_WAIT_S): "
    ), job.error


def test_a_cancel_stored_while_the_result_is_refused_ends_the_job_cancelled(
    store: Store, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    # A result the database refuses (a full disk, read-only) is held and retried; a
    # cancel stored meanwhile (a one-row write a full disk can still take where the
    # result cannot) was never read again: the job stayed "running", its worker's slot
    # held, until the result was stored as "succeeded" (or, refused past
    # INERTIA_ID_OUTCOME_REFUSED_WAIT_S, the job failed). Now the cancel is honoured and
    # the held outcome dropped, the end stored once the database takes it.
    from worker import handlers

    refusing = threading.Event()
    job_id = store.add_job("train", {"sequence": GOOD_SEQUENCE})

    def cancelled_at_its_end(context: JobContext) -> Outcome:
        with store.db.session() as session:
            job = session.get(JobRow, job_id)
            assert job is not None
            cancel(session, job)  # asked for after the run's last look at its flag
        refusing.set()
        threading.Timer(1.0, refusing.clear).start()
        return Outcome("succeeded", {"f1": 1.0}, metrics=[("f1", 0, 1.0)])

    monkeypatch.setitem(handlers.HANDLERS, "train", cancelled_at_its_end)
    settings = store.settings.model_copy(update={"heartbeat_interval_s": 0.2})
    with writes_refused_while(refusing), caplog.at_level(logging.WARNING):
        status = execute_job(job_id, settings=settings, worker_name=WORKER)
    assert status == "cancelled"
    job = store.job(job_id)
    assert (job.status, job.result, job.error, job.attempts) == ("cancelled", None, None, 1)
    with store.db.session() as session:
        assert session.scalars(select(MetricRow.value)).all() == []
    assert "cancelled while its outcome was refused (the database refuses writes" in caplog.text


def test_a_result_refused_past_the_jobs_time_limit_is_stored_not_failed_as_overdue(
    store: Store, monkeypatch: pytest.MonkeyPatch
) -> None:
    # The run ended within its time limit; its result was refused (larger than the room
    # a full disk had left, while the one-row heartbeats still fitted) past the limit and
    # its grace. Before: the beat ended the job "failed: ... time limit ... (still
    # running ...; ended)" and the result, stored once the disk had room, was dropped
    # as taken from the run. The hold has its own bound (outcome_refused_wait_s).
    import sqlite3

    from sqlalchemy.exc import OperationalError

    from worker import context as context_module
    from worker import handlers, runner

    # No grace after the limit (600 s, and a search's re-score grace, in service).
    monkeypatch.setattr(context_module, "TIME_LIMIT_GRACE_S", 0.0)
    monkeypatch.setattr(JobContext, "rescore_grace_s", property(lambda _self: 0.0))
    room = threading.Event()
    job_id = store.add_job("train", {"sequence": GOOD_SEQUENCE})

    def quick(_context: JobContext) -> Outcome:
        threading.Timer(2.0, room.set).start()  # well past the 0.5 s limit
        return Outcome("succeeded", {"f1": 1.0})

    store_outcome = runner._store_outcome

    def too_large_until_room(context: JobContext, db: Database, outcome: Outcome) -> bool:
        if not room.is_set():
            full = sqlite3.OperationalError("database or disk is full")
            full.sqlite_errorcode = sqlite3.SQLITE_FULL
            raise OperationalError("UPDATE jobs ...", {}, full)
        return store_outcome(context, db, outcome)

    monkeypatch.setitem(handlers.HANDLERS, "train", quick)
    monkeypatch.setattr(runner, "_store_outcome", too_large_until_room)
    settings = store.settings.model_copy(
        update={"heartbeat_interval_s": 0.1, "job_time_limit_s": 0.5}
    )
    status = execute_job(job_id, settings=settings, worker_name=WORKER)
    job = store.job(job_id)
    assert (status, job.status, job.error, job.result) == (
        "succeeded",
        "succeeded",
        None,
        {"f1": 1.0},
    )


def _take_the_database_down(store: Store, context: JobContext) -> Callable[[], None]:
    """The run's database wholly down (SQLite: a folder where its file goes; PostgreSQL:
    the test's own database refusing connections, its sessions ended); returns what
    brings it back."""
    url = make_url(store.settings.resolved_database_url)
    if url.drivername.startswith("sqlite"):
        path = str(url.database)
        os.rename(path, f"{path}.away")
        os.mkdir(path)
        context._db.engine.dispose()  # a pooled connection holds the file open

        def back() -> None:
            os.rmdir(path)
            os.rename(f"{path}.away", path)

        return back
    admin = create_engine(POSTGRES_ADMIN_URL, isolation_level="AUTOCOMMIT")
    with admin.connect() as connection:
        connection.execute(text(f'ALTER DATABASE "{url.database}" ALLOW_CONNECTIONS false'))
        connection.execute(
            text(
                "SELECT pg_terminate_backend(pid, 10000) FROM pg_stat_activity"
                " WHERE datname = :name AND pid <> pg_backend_pid()"
            ),
            {"name": url.database},
        )

    def allow() -> None:
        with admin.connect() as connection:
            connection.execute(text(f'ALTER DATABASE "{url.database}" ALLOW_CONNECTIONS true'))
        admin.dispose()

    return allow


def test_an_outcome_the_database_could_not_be_reached_for_is_stored_once_it_answers(
    store: Store, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    # Before: the outcome's write failed, so did the end's, the run raised out of the task
    # with the job left running, and once the database answered the reaper re-ran it as
    # "heartbeat missed ... task process died or hung", the result computed thrown away;
    # each beat of the outage logged a failed tick's traceback (150 KB a worker in 2 min).
    from worker import handlers

    job_id = store.add_job("train", {"sequence": GOOD_SEQUENCE})
    restored = threading.Event()

    def outage(context: JobContext) -> Outcome:
        back = _take_the_database_down(store, context)
        for _ in range(3):
            context.tick()

        def bring_back() -> None:
            back()
            restored.set()

        threading.Timer(1.0, bring_back).start()
        return Outcome("succeeded", {"f1": 1.0}, metrics=[("f1", 0, 1.0)])

    monkeypatch.setitem(handlers.HANDLERS, "train", outage)
    settings = store.settings.model_copy(update={"heartbeat_interval_s": 0.2})
    with caplog.at_level(logging.WARNING):
        status = execute_job(job_id, settings=settings, worker_name=WORKER)
    assert restored.wait(10)
    assert status == "succeeded"
    job = store.job(job_id)
    assert (job.status, job.result, job.attempts) == ("succeeded", {"f1": 1.0}, 1)
    assert caplog.text.count("heartbeat not stored: the database cannot be reached") == 1
    assert caplog.text.count("could not store its outcome: the database cannot be reached") == 1
    assert "tick failed" not in caplog.text
    assert "Traceback" not in caplog.text


def test_a_cancel_flag_or_progress_the_database_cannot_take_is_logged_once_an_episode(
    store: Store, caplog: pytest.LogCaptureFixture
) -> None:
    # Before: check_now (every second of a search) and report (each progress point)
    # logged a full traceback at every call of an outage: 175 lines of log in a 27 s full
    # disk under inertia-id serve, 8 tracebacks. Now one line an episode, and one as it ends.
    job_id = store.add_job(status="running", worker=WORKER, attempts=1)
    context = JobContext(_spec(store, job_id, attempt=1), store.db, store.settings, WORKER)
    with caplog.at_level(logging.INFO, logger="worker"):
        for _episode in (1, 2):
            back = _take_the_database_down(store, context)
            try:
                for _ in range(5):
                    assert not context.check_now()
                    context.report(progress=0.5)
            finally:
                back()
            assert not context.check_now()
            context.report(progress=0.6)
    lines = [r for r in caplog.records if r.name.startswith("worker.")]
    messages = [r.getMessage() for r in lines]
    assert not [r for r in lines if r.exc_info], messages
    assert (
        sum("could not read its cancel flag (the database cannot be reached" in m for m in messages)
        == 2
    ), messages
    assert (
        sum("could not store progress (the database cannot be reached" in m for m in messages) == 2
    ), messages
    assert sum("its cancel flag is read again" in m for m in messages) == 2, messages
    assert sum("progress is stored again" in m for m in messages) == 2, messages
    assert store.job(job_id).progress == 0.6


def test_a_session_opened_while_postgresql_was_read_only_writes_once_it_is_writable_again(
    store: Store, caplog: pytest.LogCaptureFixture
) -> None:
    # A PostgreSQL session keeps the default_transaction_read_only it started with
    # (ALTER DATABASE ... SET): before, a run whose pooled connection was opened while the
    # database was read-only had every heartbeat refused after the setting was reset,
    # while the sessions opened before wrote on, so another worker's reaper re-queued the
    # live run as "heartbeat missed" (and its outcome was refused too).
    url = make_url(store.settings.resolved_database_url)
    if not url.drivername.startswith("postgresql"):
        pytest.skip("a PostgreSQL session's own read-only default")
    job_id = store.add_job(status="running", worker=WORKER, attempts=1)
    run_db = Database(store.settings.resolved_database_url)  # the run's own, as a worker's
    context = JobContext(_spec(store, job_id, attempt=1), run_db, store.settings, WORKER)
    admin = create_engine(POSTGRES_ADMIN_URL, isolation_level="AUTOCOMMIT")

    def beat_stored() -> bool:
        # Through the test's own session, opened before: writable throughout.
        with store.db.session() as session:
            session.execute(update(JobRow).where(JobRow.id == job_id).values(heartbeat_at=None))
        context.tick()
        return store.job(job_id).heartbeat_at is not None

    try:
        with admin.connect() as connection:
            connection.execute(
                text(f'ALTER DATABASE "{url.database}" SET default_transaction_read_only = on')
            )
        run_db.engine.dispose()  # the run's next connection starts read-only
        with caplog.at_level(logging.WARNING):
            assert not beat_stored()
            assert "heartbeat not stored: the database refuses writes (read-only)" in caplog.text
    finally:
        with admin.connect() as connection:
            connection.execute(
                text(f'ALTER DATABASE "{url.database}" RESET default_transaction_read_only')
            )
        admin.dispose()
    try:
        assert beat_stored()  # before: refused for the life of the pooled session
    finally:
        run_db.dispose()
