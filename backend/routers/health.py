"""Liveness and readiness (no sign-in needed)."""

from __future__ import annotations

from typing import Literal

from fastapi import APIRouter, Request
from pydantic import BaseModel

from backend import __version__
from backend.deps import Conn
from backend.migrate import schema_version

router = APIRouter(prefix="/api", tags=["health"])


class Health(BaseModel):
    status: Literal["ok"]
    version: str
    schema_version: int
    model: Literal["loading", "ready", "failed"]
    model_version: str | None


@router.get("/health", response_model=Health)
def health(request: Request, conn: Conn) -> Health:
    """The server answers, the database is reachable; ``model`` says whether proposals can be made yet."""
    service = request.app.state.model
    return Health(status="ok", version=__version__, schema_version=schema_version(conn), model=service.status,
                  model_version=service.version)
