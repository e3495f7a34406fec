"""Login and users."""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, Field

from backend.schemas.common import StrictIn, Text
from backend.store.users import Role

USERNAME_PATTERN = r"^[A-Za-z0-9][A-Za-z0-9._@-]{0,63}$"


class TokenOut(BaseModel):
    access_token: str
    token_type: Literal["bearer"] = "bearer"
    expires_in: int = Field(description="seconds until the token expires")


class UserCreate(StrictIn):
    username: str = Field(pattern=USERNAME_PATTERN, description="letters, digits, . _ @ -; 1-64 characters")
    role: Role
    password: Text = Field(min_length=8, max_length=1024)


class UserOut(BaseModel):
    id: int
    username: str
    role: Role
    created_at: str
    disabled: bool


class Me(BaseModel):
    id: int
    username: str
    role: Role
