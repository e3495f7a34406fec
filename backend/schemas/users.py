"""User accounts (admin)."""

from __future__ import annotations

from pydantic import BaseModel, Field

from backend.schemas.common import StrictIn, Text
from backend.store.users import Role

USERNAME_PATTERN = r"^[A-Za-z0-9][A-Za-z0-9._@-]{0,63}$"


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
