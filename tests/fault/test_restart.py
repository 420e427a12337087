"""A graceful restart (SIGTERM of ``serve``, as systemd or ``docker stop`` sends it) while
a job runs: the job goes back to the queue at once, without spending an attempt, and
the next ``serve`` runs it; two restarts in a row do not fail it."""

from __future__ import annotations

import signal

from faults import Deployment, assert_settled, random_search

#: Each run's time limit, s (see the submit below).
RUN_LIMIT_S = 20.0


def test_graceful_restarts_hand_the_running_job_back_without_spending_attempts(
    deployment: Deployment,
) -> None:
    job_id = ""
    for restart in (1, 2):
        serve = deployment.serve(workers=1)
        if not job_id:
            with serve.client() as client:
                scenario = deployment.scenario(client)
                # Long enough to be caught running at each restart whatever the load
                # (30,000 steps: 40-60 s of work), ended by its time limit on its last
                # run: that run took 40-60 s of each CI's two parameters, for nothing the
                # test checks. Each claim counts the limit afresh, and a restart catches
                # the job within a few seconds of its claim, far inside the 20 s.
                params = random_search(30000, time_limit_s=RUN_LIMIT_S)
                job_id = deployment.submit(client, scenario, "search", params)
        job = deployment.wait_job(job_id, ("running",), timeout_s=120)
        assert job.attempts == restart, (job.attempts, job.handbacks)

        code = serve.terminate()
        assert code == 128 + signal.SIGTERM, serve.log()
        # Serve has ended its workers and joined its verdict process; multiprocessing's
        # resource tracker ends as soon as serve's end closes its pipe.
        deployment.wait_gone(10, "processes of the stopped serve are still running")
        # Back in the queue the moment serve is gone, not a heartbeat timeout later, and
        # the interrupted run is not counted against the job's attempts.
        job = deployment.job(job_id)
        assert job.status == "queued", (job.status, job.error, serve.log())
        assert job.handbacks == restart and job.attempts - job.handbacks == 0, (
            job.attempts,
            job.handbacks,
            serve.log(),
        )

    deployment.serve(workers=1)
    job = deployment.wait_job(job_id, timeout_s=180)
    assert job.status == "succeeded", (job.status, job.error, deployment.logs())
    assert job.attempts == 3 and job.handbacks == 2 and job.error is None
    # Its last run went on to its limit: no restart's hand-back was taken for an end.
    assert job.result is not None and job.result.get("stopped") == "time_limit", job.result
    assert_settled(deployment)
