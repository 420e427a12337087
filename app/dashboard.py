"""The dashboard: the static pages in ``frontend/`` and plotly.js, served by the API.

No Node build: ``frontend/`` holds plain HTML, CSS and JavaScript modules, and plotly.js
comes from the installed ``plotly`` Python package, so the dashboard works offline and
its plotting library's version is the one the project pins.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

from fastapi import FastAPI, HTTPException, status
from fastapi.responses import FileResponse
from starlette.responses import Response
from starlette.staticfiles import StaticFiles
from starlette.types import Scope

from service.config import Settings

__all__ = ["mount_dashboard", "plotly_js_path"]

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
