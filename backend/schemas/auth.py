"""Signing in: the bearer token and who holds it."""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, Field

from backend.store.users import Role


class TokenOut(BaseModel):
    access_token: str
    token_type: Literal["bearer"] = "bearer"
    expires_in: int = Field(description="seconds until the token expires")


class Me(BaseModel):
    id: int
    username: str
    role: Role
