"""Signing in: the bearer token and who holds it."""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, Field

from backend.schemas.common import Password, StrictIn
from backend.store.users import Role


class TokenOut(BaseModel):
    access_token: str
    token_type: Literal["bearer"] = "bearer"
    expires_in: int = Field(description="seconds until the token expires")


class Me(BaseModel):
    id: int
    username: str
    role: Role
    must_change_password: bool = Field(description="true: a password someone else chose; every other request is "
                                                   "refused (403) until POST /api/auth/password")


class PasswordChange(StrictIn):
    current_password: str = Field(max_length=1024)
    new_password: Password
