"""Refinements from walking: ask for one from sessions, read it."""

from __future__ import annotations

from pydantic import BaseModel, Field

from backend.schemas.common import MAX_ID, StrictIn, Text


class RefinementRequest(StrictIn):
    session_ids: list[int] = Field(min_length=1, max_length=50,
                                   description="stopped sessions of this patient on exactly this version")
    comment: Text = Field(min_length=1, max_length=2000, description="why (audited)")

    def ids(self) -> list[int]:
        bad = [i for i in self.session_ids if not 1 <= i <= MAX_ID]
        if bad:
            raise ValueError(f"walking sessions are named by their numbers (1 or more): {', '.join(map(str, bad))} "
                             f"{'is' if len(bad) == 1 else 'are'} not")
        return list(self.session_ids)


class RefinementOut(BaseModel):
    """A refinement: the draft version it derived, from which sessions, with the evidence per node and the changes.
    Errors are measured − target in each quantity's unit (``quantities``: deg or % of the gait cycle)."""

    id: int
    envelope_id: int | None = Field(description="the refined draft envelope (None for a table)")
    proposal_id: int | None = Field(description="the refined draft table (None for an envelope)")
    parent_id: int = Field(description="the approved version it derives from")
    session_ids: list[int]
    created_by: str
    created_at: str
    strides: int = Field(description="strides in the sessions")
    strides_on_version: int = Field(description="strides the leg ran the version for the whole of")
    strides_used: int = Field(description="strides compared with their targets (on the version, with a task)")
    strides_without_feature: dict[str, int] = Field(description="feature → strides on which it was not found "
                                                               "(counted, not guessed)")
    feature_abs_error: dict[str, float | None] = Field(description="mean absolute error of the strides per quantity")
    quantities: dict[str, dict] = Field(description="each controlled quantity: label, tolerance, unit")
    nodes: list[dict] = Field(description="per node walked: strides, per quantity the evidence (error, 95 % "
                                          "interval, agreement, act and why; held: 'not responding' or 'out of "
                                          "reach'), expected error after the change")
    changes: list[dict] = Field(description="per node and value: before, after, why in clinical words, held_from "
                                            "where the neighbour rule moved it back")
    nodes_changed: list[list[int]]
    change_in_steps: float | None = Field(default=None, description="how far the values moved: the sum over the "
                                                                    "changes of |change| in step limits (5° of θe, 25 % "
                                                                    "of k or b); None for refinements stored before it")
    sensitivity: str
    bench_leg: str | None = Field(default=None, description="the leg the bench walked, in words (None for "
                                                            "refinements stored before it)")
    rules: dict
    version: dict | None = Field(default=None, description="the refined draft as its own endpoint returns it (on "
                                                           "creation)")
