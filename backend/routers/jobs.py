"""Bench jobs (``backend.jobs``): the walks on this instance's bench, their progress, and cancel."""

from __future__ import annotations

from datetime import UTC, datetime

from fastapi import APIRouter

from backend.db import utc_text
from backend.deps import CurrentUser
from backend.errors import ConflictError, ForbiddenError, NotFoundError
from backend.jobs import BOARD, BenchJob
from backend.schemas.common import IdPath
from backend.schemas.errors import CONFLICT, FORBIDDEN, NOT_FOUND, UNAUTHORIZED
from backend.schemas.jobs import JobOut

router = APIRouter(prefix="/api/jobs", tags=["jobs"], responses=UNAUTHORIZED)


def _at(unix: float | None) -> str | None:
    return None if unix is None else utc_text(datetime.fromtimestamp(unix, UTC))


def _words(job: BenchJob, ahead: int, left_s: float) -> str:
    about = f"about {max(round(left_s), 1)} s left"
    if job.state == "queued":
        return f"queued behind {ahead} walk{'s' if ahead != 1 else ''}: {about}"
    if job.state == "walking":
        return f"walking, {round(100 * job.fraction())} %: {about}"
    if job.state == "cancelled":
        return f"cancelled by {job.cancelled_by}; nothing was stored"
    if job.state == "failed":
        return f"failed: {job.error}"
    return "done"


def _out(job: BenchJob) -> dict:
    before = BOARD.ahead_of(job) if job.state == "queued" else []
    left_s = job.seconds_left() + sum(j.seconds_left() for j in before)
    return {"id": job.id, "kind": job.kind, "target": job.target, "path": job.path, "user": job.user,
            "state": job.state, "queued_at": _at(job.queued_at), "started_at": _at(job.started_at),
            "ended_at": _at(job.ended_at), "ahead": len(before), "walked_s": job.walked_s,
            "expected_s": job.expected_s, "estimate_basis": job.basis, "fraction": job.fraction(), "seconds_left_s": left_s,
            "cancelled_by": job.cancelled_by, "error": job.error, "words": _words(job, len(before), left_s)}


def _job(job_id: int) -> BenchJob:
    job = BOARD.get(job_id)
    if job is None:
        raise NotFoundError(f"no bench job {job_id} on this server (finished jobs are kept 10 minutes)")
    return job


@router.get("", response_model=list[JobOut])
async def list_jobs(_user: CurrentUser) -> list[dict]:
    """The bench's queue on this server (walking first, then in order) and the jobs finished in the last 10 minutes,
    newest first: everyone's, so a prosthetist sees what their walk waits behind."""
    return [_out(j) for j in BOARD.jobs()]


@router.get("/{job_id}", response_model=JobOut, responses=NOT_FOUND)
async def get_job(job_id: IdPath, _user: CurrentUser) -> dict:
    """One bench job: its state, progress and the time left."""
    return _out(_job(job_id))


@router.delete("/{job_id}", response_model=JobOut, responses={**NOT_FOUND, **FORBIDDEN, **CONFLICT})
async def cancel_job(job_id: IdPath, user: CurrentUser) -> dict:
    """Cancel a bench job (its owner, or an admin): queued, it leaves the queue at once; walking, it stops within a
    simulated second. Nothing it would have stored is stored; the request that asked for it answers 409."""
    job = _job(job_id)
    if user.username != job.user and user.role != "admin":
        raise ForbiddenError(f"job {job_id} is {job.user}'s: only they or an admin may cancel it")
    if job.state not in ("queued", "walking"):
        raise ConflictError(f"job {job_id} is {job.state} already; there is nothing to cancel")
    BOARD.cancel(job, user.username)
    return _out(job)
