"""Is this API key accepted? A cheap check a client makes when the key is entered."""

from __future__ import annotations

from fastapi import APIRouter, Response, status

from .deps import UNAUTHORIZED, ApiKeyDep
from .routing import UniqueKeysRoute

__all__ = ["router"]

router = APIRouter(prefix="/auth", tags=["auth"], route_class=UniqueKeysRoute)


@router.get(
    "/check",
    status_code=status.HTTP_204_NO_CONTENT,
    dependencies=[ApiKeyDep],
    responses=UNAUTHORIZED,
)
def check_key() -> Response:
    """204 when the ``X-API-Key`` header holds an accepted key, 401 otherwise. Touches
    nothing: the dashboard asks it before it keeps a key."""
    return Response(status_code=status.HTTP_204_NO_CONTENT)
