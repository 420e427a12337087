"""The dashboard and the API documentation: static files served by the API, offline.

No Node build: ``frontend/`` holds plain HTML, CSS and JavaScript modules, and plotly.js
comes from the installed ``plotly`` Python package; the API documentation at ``/docs``
is Swagger UI from the installed ``swagger-ui-bundle-v2`` package. Nothing is fetched
from a CDN, so both work on a machine without internet.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

from fastapi import FastAPI, HTTPException, status
from fastapi.openapi.docs import get_swagger_ui_html
from fastapi.responses import FileResponse, HTMLResponse
from starlette.responses import Response
from starlette.staticfiles import StaticFiles
from starlette.types import Scope

from service.config import Settings

__all__ = ["mount_dashboard", "mount_docs", "plotly_js_path", "swagger_ui_dir"]

# The pages change with the code: revalidate every time (ETag) rather than cache.
_REVALIDATE = {"Cache-Control": "no-cache"}


def plotly_js_path() -> Path | None:
    """``plotly.min.js`` inside the installed plotly package, found without importing it."""
    spec = importlib.util.find_spec("plotly")
    for folder in (spec.submodule_search_locations or []) if spec else []:
        path = Path(folder) / "package_data" / "plotly.min.js"
        if path.is_file():
            return path
    return None


def swagger_ui_dir() -> Path | None:
    """The Swagger UI distribution inside the installed ``swagger_ui_bundle`` package."""
    spec = importlib.util.find_spec("swagger_ui_bundle")
    for folder in (spec.submodule_search_locations or []) if spec else []:
        for candidate in sorted((Path(folder) / "vendor").glob("swagger-ui-*")):
            if (candidate / "swagger-ui-bundle.js").is_file():
                return candidate
    return None


def mount_docs(app: FastAPI) -> None:
    """Serve Swagger UI at ``/docs`` from the installed package (FastAPI's own ``/docs``
    loads it from a CDN, and is switched off in :func:`app.main.create_app`)."""
    assets = swagger_ui_dir()

    @app.get("/docs", include_in_schema=False)
    def docs() -> HTMLResponse:
        if assets is None:
            raise HTTPException(
                status.HTTP_404_NOT_FOUND,
                detail="the API documentation needs the swagger-ui-bundle-v2 package; "
                "the OpenAPI document itself is at /openapi.json",
            )
        page = get_swagger_ui_html(
            openapi_url=app.openapi_url or "/openapi.json",
            title=f"{app.title}: API documentation",
            swagger_js_url="/docs-assets/swagger-ui-bundle.js",
            swagger_css_url="/docs-assets/swagger-ui.css",
            swagger_favicon_url="/docs-assets/favicon-32x32.png",
        )
        # FastAPI's page states no language, which a screen reader needs (axe's
        # html-has-lang); the rest of Swagger UI's markup is its own.
        html = bytes(page.body).replace(b"<html>", b'<html lang="en">', 1)
        return HTMLResponse(html, status_code=page.status_code)

    if assets is not None:
        app.mount("/docs-assets", StaticFiles(directory=assets), name="docs-assets")


class _Pages(StaticFiles):
    async def get_response(self, path: str, scope: Scope) -> Response:
        response = await super().get_response(path, scope)
        response.headers.update(_REVALIDATE)
        return response


def mount_dashboard(app: FastAPI, settings: Settings) -> None:
    """Serve ``/`` (the dashboard), ``/static/...`` (its files) and plotly.js.

    A deployment without the ``frontend/`` folder still serves the API; ``/`` then says
    where the dashboard was looked for.
    """
    frontend = settings.resolved_frontend_dir
    index = frontend / "index.html"

    @app.get("/static/vendor/plotly.min.js", include_in_schema=False)
    def plotly_js() -> FileResponse:
        path = plotly_js_path()
        if path is None:
            raise HTTPException(status.HTTP_404_NOT_FOUND, detail="plotly is not installed")
        return FileResponse(
            path, media_type="text/javascript", headers={"Cache-Control": "max-age=86400"}
        )

    @app.get("/", include_in_schema=False)
    def dashboard() -> FileResponse:
        if not index.is_file():
            raise HTTPException(
                status.HTTP_404_NOT_FOUND,
                detail=f"the dashboard is not installed: no {index} "
                "(set INERTIA_ID_FRONTEND_DIR to the frontend folder)",
            )
        return FileResponse(index, media_type="text/html", headers=_REVALIDATE)

    if frontend.is_dir():
        app.mount("/static", _Pages(directory=frontend), name="static")
