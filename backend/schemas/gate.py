"""Sign-offs on a version's bench findings, and withdrawals: what the gate's two-person override and a take-back
send and answer."""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, Field

from backend.schemas.common import StrictIn, Text


class SignoffRequest(StrictIn):
    reason: Text = Field(min_length=20, max_length=2000,
                         description="why this version goes ahead although the bench did not find it clean (at least "
                                     "20 characters; audited, and shown wherever the version is shown)")


class Signoff(BaseModel):
    by: str
    reason: str
    at: str


class SignoffsOut(BaseModel):
    signoffs: list[Signoff] = Field(description="the prosthetists' sign-offs on exactly this version's content")
    needed: int = Field(description="how many sign-offs, by distinct prosthetists, override the bench's gate")
    complete: bool


class WithdrawRequest(StrictIn):
    reason: Text = Field(min_length=10, max_length=2000,
                         description="why the version is taken back (audited; shown on the version and the monitor)")


class Withdrawal(BaseModel):
    by: str
    at: str
    reason: str


class LegSentBack(BaseModel):
    device_id: str
    action: Literal["sent_back", "safe_mode", "offline"] = Field(
        description="sent_back: the leg now holds the last version it ran that was not withdrawn; safe_mode: there "
                    "was none (or it could not be sent), the leg was put in safe mode; offline: the leg will be put in "
                    "safe mode when it next reports")
    to_label: str | None = Field(description="the version it was sent back to")
    detail: str


class WithdrawOut(BaseModel):
    withdrawal: Withdrawal
    legs: list[LegSentBack] = Field(description="every leg that ran or held the version, and what was done to it")
