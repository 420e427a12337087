"""The FastAPI application factory.

Run with uvicorn's factory mode: ``uvicorn app.main:create_app --factory`` (``inertia-id
serve`` does). Nothing is created at import time.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from typing import Any

from fastapi import Depends, FastAPI
from fastapi.openapi.utils import get_openapi
from sqlalchemy.exc import InterfaceError, OperationalError

import inertia_id
from service.config import Settings, settings_or_exit
from service.queue import make_celery
from service.store.refusals import database_label, driver_said
from service.store.session import Database, DatabaseNewerThanCode, upgrade

from .api import ROUTERS
from .api.deps import numbers_as_written, one_value_each
from .api.errors import install_error_handlers
from .api.identify import openapi_components
from .capacity import ComputeGate
from .classifier_cache import ClassifierCache
from .dashboard import mount_dashboard, mount_docs
from .result_schema import add_result_schemas
from .security import (
    AllowedHosts,
    BodySizeLimit,
    HeadAsGet,
    KeyBeforeBody,
    KeyVerifier,
    SecurityHeaders,
    ensure_api_key,
)
from .shutdown import StopCut
from .verdicts import VerdictProcess

__all__ = ["DATABASE_SILENT_S", "create_app"]

log = logging.getLogger("inertia_id.api")

#: The API's database connections are given up after about this many seconds of a silent
#: network (see service.store.session.Database): a connect (libpq's ``connect_timeout``),
#: or a pooled connection whose server's machine stopped acknowledging what is sent or
#: its keepalive probes (``tcp_user_timeout``, ``keepalives_*``). The request is then the
#: 503 an unreachable database gets. Before, with the database's packets dropped (a
#: partition, a firewall, a dead host), ``GET /jobs`` waited on for the kernel's limits:
#: still waiting 150 s on over a pooled connection, 130 s for a connect (its SYN
#: retries), holding the request and its client. 5 s, not the worker's 10 s: a request
#: may meet it twice (a pooled connection's check, then a new connect), and ``/health``
#: (the compose file's check allows it 5 s) and callers wait on it. A slow server is no
#: silent one (its machine acknowledges at once); a server that takes over 5 s merely to
#: open a session is taken for an unreachable one. A proxy that acknowledges for a
#: server that does not answer (frozen) is bounded by INERTIA_ID_DATABASE_ANSWER_TIMEOUT_S
#: instead (service.store.answers). The start's migration gets the same connect bound.
DATABASE_SILENT_S = 5.0

DESCRIPTION = """\
Identify which known inertia configuration a spacecraft is in from its response to a
chosen thruster sequence.

Store **scenarios**, run **jobs** on workers (search for a sequence, train a classifier,
sweep its accuracy against noise), download **classifiers**, and **identify** telemetry.
Write endpoints (POST, DELETE) need the API key in the `X-API-Key` header.
"""


def _warm_up_core() -> None:
    """Import what requests will need and compile the numba kernels, off the request path.

    The API answers ``/health`` before this is done (the classifier registry alone pulls
    in scikit-learn: a second or two); a request that needs a module still loading waits
    for that import, and the kernels are compiled (or loaded from numba's cache) here,
    never inside a request.

    Compiling calls ``ast.parse`` (numba's array-expression lowering), and CPython
    3.11.0-3.11.7 fails one of two ASTs built at once in two threads (gh-106905). No
    request path of the API parses Python source (checked with ``ast.parse`` traced
    during a cold start under requests), and numba compiles under its own global lock;
    the test suite compiles the kernels before it collects (``tests/conftest.py``), as
    pytest parses every test module it imports.
    """
    started = time.perf_counter()
    try:
        import inertia_id.search  # noqa: F401  (search job validation)
        from inertia_id import warm_up

        warm_up()
    except Exception:
        log.exception("could not warm up the science core; requests will load it")
        return
    log.info("science core loaded and kernels compiled in %.1f s", time.perf_counter() - started)


def _unanswered(url: str, doing: str, exc: Exception) -> str:
    """The start's one line for a database that could not be reached (a traceback
    before): which database, what for, and what the driver said."""
    return (
        f"inertia-id api: cannot reach the database {database_label(url)} {doing}: "
        f"{driver_said(exc)}"
    )


def create_app(settings: Settings | None = None) -> FastAPI:
    """Build the application: migrate the database, make sure an API key exists.

    ``app.state`` holds ``settings``, ``db`` (:class:`Database`), ``celery`` (the app that
    sends jobs by task name), ``classifier_cache``, and ``generated_api_key``: the
    plaintext of a key generated by this call (first run), else None.
    """
    # From the environment (uvicorn's factory mode): a bad setting ends the start with
    # one line naming it, not a traceback.
    settings = settings or settings_or_exit("inertia-id api")
    settings.data_dir.mkdir(parents=True, exist_ok=True)
    url = settings.resolved_database_url
    try:
        # Its connect bounded as the requests' are: a silent database held the start
        # (uvicorn's, serve's) for ever, printing nothing.
        upgrade(url, silent_after_s=DATABASE_SILENT_S)
    except DatabaseNewerThanCode as exc:
        # One line, as for a bad setting: it was Alembic's traceback ending in "Can't
        # locate revision identified by '0012'".
        raise SystemExit(f"inertia-id api: {exc}") from None
    except (OperationalError, InterfaceError) as exc:
        raise SystemExit(_unanswered(url, "to migrate it", exc)) from None
    database = Database(
        url,
        silent_after_s=DATABASE_SILENT_S,
        answer_within_s=settings.database_answer_timeout_s,
    )
    try:
        generated_key = ensure_api_key(database, settings)
    except (OperationalError, InterfaceError) as exc:
        database.dispose()
        raise SystemExit(_unanswered(url, "to check its API key", exc)) from None

    celery = make_celery(settings)
    verdicts = (
        None
        if settings.verdict_process == "off"
        else VerdictProcess(
            url, settings.classifier_cache_size, timeout_s=settings.verdict_timeout_s
        )
    )

    @asynccontextmanager
    async def lifespan(_app: FastAPI) -> AsyncIterator[None]:
        def warm_up() -> None:
            _warm_up_core()
            # The verdict process after the API's own imports: both at once on a small
            # machine pushed the first /health answer towards 3 s.
            if verdicts is not None and settings.verdict_process == "eager":
                verdicts.start()

        threading.Thread(target=warm_up, name="inertia-id warm-up", daemon=True).start()
        yield
        if verdicts is not None:
            verdicts.close()
        celery.close()
        database.dispose()

    app = FastAPI(
        title="inertia-id",
        version=inertia_id.__version__,
        description=DESCRIPTION,
        lifespan=lifespan,
        # /docs is served from the installed Swagger UI package (app.dashboard), not a CDN.
        docs_url=None,
        redoc_url=None,
        dependencies=[Depends(one_value_each), Depends(numbers_as_written)],
    )
    app.state.settings = settings
    app.state.db = database
    app.state.celery = celery
    app.state.classifier_cache = ClassifierCache(settings.classifier_cache_size)
    app.state.compute_gate = ComputeGate(
        threads=settings.compute_threads,
        queue=settings.compute_queue,
        wait_s=settings.compute_wait_s,
    )
    # Verdicts in flight to the verdict process: two, so that the next is on its way
    # while one computes; past them requests queue, and past the queue get a 503.
    app.state.verdicts = verdicts
    app.state.verdict_gate = ComputeGate(
        threads=2, queue=settings.compute_queue, wait_s=settings.compute_wait_s
    )
    app.state.generated_api_key = generated_key
    app.state.verify_key = KeyVerifier.for_store(database, settings)

    for router in ROUTERS:
        app.include_router(router)
    install_error_handlers(app)
    mount_docs(app)
    mount_dashboard(app, settings)
    app.add_middleware(KeyBeforeBody)
    app.add_middleware(BodySizeLimit, max_bytes=settings.max_body_bytes)
    app.add_middleware(AllowedHosts, hosts=settings.resolved_allowed_hosts)
    app.add_middleware(HeadAsGet)
    # A request cut off by the shutdown's grace: a 503, not a traceback and a 500.
    app.add_middleware(StopCut)
    app.add_middleware(SecurityHeaders)  # outermost: on every answer, refusals too
    _extend_openapi(app, settings)
    return app


_HTTP_ERROR: dict[str, Any] = {
    "title": "HTTPError",
    "type": "object",
    "properties": {"detail": {"type": "string"}},
    "required": ["detail"],
}
_BODY_ERRORS = {
    "400": "the body could not be read (e.g. JSON that is not UTF-8, a malformed form)",
    "413": "the body is larger than INERTIA_ID_MAX_BODY_BYTES",
}


def _error_response(description: str) -> dict[str, Any]:
    schema = {"$ref": "#/components/schemas/HTTPError"}
    return {"description": description, "content": {"application/json": {"schema": schema}}}


def _extend_openapi(app: FastAPI, settings: Settings) -> None:
    """Complete the generated document with what depends on the settings or is parsed by hand.

    The page size cap is a setting, so the routers cannot declare it; the identify body
    (JSON or multipart on one path) is parsed by the route, so its schemas are added here.
    """

    def openapi() -> dict[str, Any]:
        if app.openapi_schema is None:
            schema = get_openapi(
                title=app.title,
                version=app.version,
                description=app.description,
                routes=app.routes,
            )
            schemas = schema.setdefault("components", {}).setdefault("schemas", {})
            for name, component in openapi_components().items():
                schemas.setdefault(name, component)
            schemas["HTTPError"] = _HTTP_ERROR
            add_result_schemas(schema)
            for operations in schema.get("paths", {}).values():
                for operation in operations.values():
                    for parameter in operation.get("parameters", []):
                        if parameter.get("in") == "query" and parameter.get("name") == "limit":
                            parameter["schema"]["maximum"] = settings.max_page_size
                    if "requestBody" in operation:
                        responses = operation.setdefault("responses", {})
                        for code, description in _BODY_ERRORS.items():
                            responses.setdefault(code, _error_response(description))
            app.openapi_schema = schema
        return app.openapi_schema

    app.openapi = openapi  # type: ignore[method-assign]
