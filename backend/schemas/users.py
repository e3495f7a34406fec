"""User accounts (admin)."""

from __future__ import annotations

from pydantic import BaseModel, Field

from backend.schemas.common import Password, StrictIn
from backend.store.users import Role

USERNAME_PATTERN = r"^[A-Za-z0-9][A-Za-z0-9._@-]{0,63}$"


class UserCreate(StrictIn):
    username: str = Field(pattern=USERNAME_PATTERN, description="letters, digits, . _ @ -; 1-64 characters")
    role: Role
    password: Password


class UserPatch(StrictIn):
    disabled: bool = Field(description="true: the account can no longer sign in and its tokens stop working")


class PasswordReset(StrictIn):
    password: Password = Field(description="a one-time password the user must change at their next sign-in")


class UserOut(BaseModel):
    id: int
    username: str
    role: Role
    created_at: str
    disabled: bool
    must_change_password: bool = Field(description="the password was chosen by someone else and not yet changed")
    password_changed_at: str | None
