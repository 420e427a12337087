"""Shared fixtures for the inertia_id test suite.

Everything here is deterministic: every random draw comes from a seeded generator, so a
failure is reproducible and no test depends on timing.
"""

from __future__ import annotations

import gc
import os
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from scenario_support import GOOD_SEQUENCE

from inertia_id import InertiaClassifier, Scenario, preset, train
from inertia_id.physics.presets import NOISE_OFF

# Every source of randomness switched off, and the actuation low-pass too.
ZERO_UNCERTAINTY: dict[str, Any] = {**NOISE_OFF, "lowpass_time_constant_s": 0.0}


def pytest_sessionstart(session: pytest.Session) -> None:
    """Import the core and compile its numba kernels here, in the main thread, before
    collection.

    An app's lifespan starts a warm-up thread that does the same (``app.main``), and
    ``tests/api/test_schemathesis.py`` starts one while it is collected. On a fresh clone
    (no numba cache) that thread compiled for tens of seconds while pytest parsed the
    next test modules, and CPython 3.11.0-3.11.7 cannot build two ASTs at once in two
    threads (gh-106905, fixed in 3.11.8): numba's array-expression lowering and
    ``inspect.signature`` of builtins both call ``ast.parse``, and the collection of
    ``tests/search/test_pareto.py`` failed with "SystemError: AST constructor recursion
    depth mismatch" in CI. With the kernels compiled and the modules imported here, an
    app's warm-up thread finds them ready and parses nothing.
    """
    import inertia_id.search  # noqa: F401  (what the app's warm-up imports)
    from inertia_id import warm_up

    warm_up()
    _one_blas_thread()


_BLAS_LIMIT: Any = None


@pytest.hookimpl(trylast=True)
def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Refuse a collection in which two tests share an id.

    pytest-xdist hands tests out by id, so it runs only one of a set that share one,
    and says nothing: under ``-n 2`` schemathesis' 26 operation tests ran as one
    (``tests/api/conftest.py``). This makes such a loss an error in one process too.
    """
    seen: set[str] = set()
    shared = sorted({item.nodeid for item in items if item.nodeid in seen or seen.add(item.nodeid)})
    if shared:
        raise pytest.UsageError(
            f"{len(shared)} test id(s) shared by more than one test (pytest-xdist would run"
            f" only one of each): {', '.join(shared[:5])}"
        )


@pytest.hookimpl(trylast=True)
def pytest_sessionfinish(session: pytest.Session) -> None:
    """In a pytest-xdist worker, once its tests and fixtures are done: collect its
    garbage now and freeze what is left, so that pytest's own collection at unconfigure
    is short.

    pytest-xdist's worker reports its end after this hook; the controller then ends the
    worker's gateway, and execnet gives the rest of the worker's run 5 s before it sends
    the worker SIGINT (``WorkerGateway._terminate_execution``). That rest is pytest's
    unconfigure, whose ``gc.collect()`` over a worker's heap after six API modules took
    over 8 s: the SIGINT landed in a weakref callback (SQLAlchemy's
    ``_collection_gced``), printed as an unraisable KeyboardInterrupt after the summary,
    and a worker slower still would be killed in its exit (``atexit`` cleanups cut).
    Here, before the report, nothing waits on it. Thawed at unconfigure, after pytest's
    collection (:func:`pytest_unconfigure`)."""
    if os.environ.get("PYTEST_XDIST_WORKER"):
        gc.collect()
        gc.freeze()


@pytest.hookimpl(trylast=True)
def pytest_unconfigure(config: pytest.Config) -> None:
    gc.unfreeze()  # the interpreter's exit collects as it would have


def _one_blas_thread() -> None:
    """One BLAS thread in this process (numpy's and scipy's OpenBLAS, both loaded by
    now).

    The suite shares 2 cores with the services, workers and browsers its tests start,
    and OpenBLAS's second thread spins while it waits for work that those processes hold
    up: a test of 5 s alone took 60 s beside other busy processes, and tests/evaluation with
    tests/classifiers ran in 62 s instead of 84 s on an idle machine with one thread.
    Only this process is limited: the environment is untouched, so every service,
    worker and CLI a test starts runs with its threads as shipped.
    """
    global _BLAS_LIMIT
    import scipy.linalg  # noqa: F401  (scipy's own OpenBLAS, loaded before the limit)
    from threadpoolctl import threadpool_limits

    _BLAS_LIMIT = threadpool_limits(limits=1, user_api="blas")


@pytest.fixture(scope="session")
def gzip_bomb(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A gzip file of about 1 MB holding 1 GiB of zeros (written once a session: 3 s)."""
    from gzip_support import write_gzip_bomb

    return write_gzip_bomb(tmp_path_factory.mktemp("bomb") / "pass.csv.gz")


@pytest.fixture(scope="session")
def migrated_sqlite(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A SQLite file migrated to head, made once a session: a test copies it as its
    fresh database (``service_support.migrated_sqlite_template``)."""
    from service_support import migrated_sqlite_template

    return migrated_sqlite_template(tmp_path_factory.mktemp("migrated"))


@pytest.fixture(scope="session")
def migrated_postgres() -> Iterator[str]:
    """The name of a PostgreSQL database migrated to head, made once a session, for
    ``postgres_database(template=...)`` to copy (``migrated_postgres_template``)."""
    from service_support import migrated_postgres_template

    with migrated_postgres_template() as name:
        yield name


@pytest.fixture(scope="session")
def paper() -> Scenario:
    """The paper preset (5 candidates, 6 thrusters, 5 levels) started from rest with an
    unbiased gyro, the paper's premise that most tests' figures rest on. Frozen, so
    shareable."""
    return Scenario.paper()


@pytest.fixture(scope="session")
def drifting_paper() -> Scenario:
    """The paper's spacecraft in orbit (preset ``paper-in-orbit``): initial body rates
    (5e-3 rad/s) and constant gyro biases (2e-3 rad/s) drawn per realisation and axis."""
    return preset("paper-in-orbit")


@pytest.fixture(scope="session")
def good_sequence() -> np.ndarray:
    return np.array(GOOD_SEQUENCE)


@pytest.fixture(scope="session")
def zero_uncertainty() -> dict[str, Any]:
    return dict(ZERO_UNCERTAINTY)


@pytest.fixture(scope="session")
def noise_off() -> dict[str, Any]:
    """Every source of randomness off, the actuation low-pass on."""
    return dict(NOISE_OFF)


@pytest.fixture(scope="session")
def quiet_paper(paper: Scenario) -> Scenario:
    """The paper preset with every noise and the low-pass switched off."""
    return paper.with_uncertainty(**ZERO_UNCERTAINTY)


@pytest.fixture(scope="session")
def scenario_like() -> Callable[..., Scenario]:
    """Build a scenario with the paper's thrusters/timing/uncertainty and given tensors.

    ``scenario_like({"heavy": tensor, ...}, timing=..., uncertainty=...)``.
    """

    def build(candidates: dict[str, Any], **overrides: Any) -> Scenario:
        tensors = [
            {"name": name, "inertia_kg_m2": np.asarray(tensor, float).tolist()}
            for name, tensor in candidates.items()
        ]
        return preset("paper", name="test", inertia_candidates=tensors, **overrides)

    return build


@pytest.fixture(scope="module")
def euclidean_classifier(paper: Scenario) -> InertiaClassifier:
    """Euclidean classifier trained on the paper preset with the good sequence (fast).

    Module-scoped: trained once per test module. Tests must not mutate it.
    """
    return train(paper, GOOD_SEQUENCE, 20, np.random.default_rng(1), metric="euclidean")
