"""Bench jobs: the walks queued and walking on this instance's bench, with their progress and the time left."""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, Field


class JobOut(BaseModel):
    id: int
    kind: str = Field(description="'table preview', 'envelope preview' or 'refinement'")
    target: str = Field(description="what it walks, in the page's words ('envelope 12')")
    path: str = Field(description="… as the API names it ('/api/envelopes/12')")
    user: str = Field(description="who asked for it")
    state: Literal["queued", "walking", "done", "failed", "cancelled"]
    queued_at: str
    started_at: str | None
    ended_at: str | None
    ahead: int = Field(description="walks that go before this one (the one walking and those queued before it)")
    walked_s: float = Field(description="simulated seconds walked so far")
    expected_s: float = Field(description="simulated seconds it is expected to walk in all (the last job of its kind "
                                          "on this instance, or a first guess)")
    estimate_basis: str = Field(description="where expected_s comes from, in words")
    fraction: float = Field(ge=0, le=1, description="how far it has come (1 only once done)")
    seconds_left_s: float = Field(description="wall seconds until it is done, the walks ahead of it included "
                                              "(an estimate: see expected_s)")
    cancelled_by: str | None
    error: str | None
    words: str = Field(description="its state in a sentence for the page")
