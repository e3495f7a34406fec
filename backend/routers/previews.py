"""The simulated preview of a proposal's table, or of an envelope on the varying-task course, against the FSMIC."""

from __future__ import annotations

from collections.abc import Callable

import anyio
from fastapi import APIRouter, Request
from sqlalchemy import Connection

from backend.bench.node_previews import NodeWalks, envelope_flags
from backend.bench.preview import PREVIEW_COURSE, BenchmarkWalks, preview_envelope, preview_table
from backend.bench.safety_figures import safety_flags
from backend.deps import Conn, CurrentUser, Model
from backend.errors import ConflictError
from backend.schemas.common import IdPath
from backend.schemas.errors import CONFLICT, NOT_FOUND, TOO_MANY, UNAUTHORIZED, UNAVAILABLE
from backend.schemas.previews import EnvelopePreviewOut, PreviewOut
from backend.services import legs
from backend.store import previews, versions
from backend.threads import run_bench, run_waiting
from controller_core.model import QuasiStiffnessModel
from device_bridge.as_run import as_run
from device_bridge.sim.course import COURSES

router = APIRouter(prefix="/api", tags=["previews"], responses=UNAUTHORIZED)

PREVIEW_SECONDS = 10.0
# one walk per version however many pages ask for it at once (a page redrawn while its preview walks asks again, two
# tabs open the same new envelope): the others wait for it here, not in the bench's queue, and read what it stored;
# walks of different versions take their turn on the bench's queue (backend.threads.run_bench: one at a time), so many
# new envelopes queue instead of starving the device loop of CPU
_walks: dict[tuple[str, int], anyio.Lock] = {}


async def _walk_once(key: tuple[str, int], user: str, preview: Callable[..., dict | None], *args: object) -> dict:
    """The stored preview of ``key``; walked first, as a job on the bench's queue, if there is none."""
    lock = _walks.setdefault(key, anyio.Lock())
    try:
        async with lock:
            stored = await run_waiting(preview, *args, walk=False)
            if stored is None:
                words = "table" if key[0] == "proposal" else "envelope"
                job = (f"{words} preview", f"{words} {key[1]}", f"/api/{key[0]}s/{key[1]}")
                stored = await run_bench(user, job, preview, *args)
            return stored
    finally:
        if not lock.locked() and lock.statistics().tasks_waiting == 0:
            _walks.pop(key, None)


@router.get("/proposals/{proposal_id}/preview", response_model=PreviewOut,
            responses={**NOT_FOUND, **CONFLICT, **UNAVAILABLE, **TOO_MANY})
async def get_preview(proposal_id: IdPath, request: Request, conn: Conn, user: CurrentUser, model: Model) -> dict:
    """Walk this proposal's table and the FSMIC benchmark for 10 s each on the simulated bench at the proposal's
    task (computed on first request, about a second, then stored: a proposal never changes; the FSMIC's walk at a task
    and body mass is kept for the server's life, so a later table at that task walks alone). Falls, strides and
    joint RMSE against the able-bodied reference, and the stride-averaged trajectories; ``safety`` flags the
    table's safety figures (falls, toe catches, time on swing settings under load) on their own bounds."""
    return await _walk_once(("proposal", proposal_id), user.username, _table_preview, proposal_id, conn, model,
                            request.app.state.benchmark_walks)


def _table_preview(proposal_id: int, conn: Connection, model: QuasiStiffnessModel, benchmark: BenchmarkWalks,
                   walk: bool = True) -> dict | None:
    """The stored preview, walked first if there is none (``walk=False``: None instead)."""
    row = versions.get_row(conn, "proposal", proposal_id)
    stored = previews.get_preview(conn, "proposal", proposal_id, row["content_sha256"])
    if stored is None and not walk:
        return None
    if stored is None:
        checked = as_run(versions.stored_table(row))   # walked as the device would run it
        _refuse_unsafe(checked.violations, f"proposal {proposal_id}")
        table = checked.item
        result = preview_table(table, row["speed_mps"], row["incline_deg"], row["body_mass_kg"], model,
                               PREVIEW_SECONDS, legs.version_leg(row).geometry(), benchmark)
        stored = previews.store_preview(conn, "proposal", proposal_id, row["content_sha256"], result)
    runs = stored["controllers"]
    return {"proposal_id": proposal_id, "table_sha256": row["content_sha256"], **stored,
            "safety": safety_flags(runs["table"], runs["fsmic"])}


@router.get("/envelopes/{envelope_id}/preview", response_model=EnvelopePreviewOut,
            responses={**NOT_FOUND, **CONFLICT, **UNAVAILABLE, **TOO_MANY})
async def get_envelope_preview(envelope_id: IdPath, request: Request, conn: Conn, user: CurrentUser,
                               model: Model) -> dict:
    """Walk the bench's ``mixed`` course (speed changes, ramps up and down ±8°) with this envelope, the leg estimating
    its task and adapting, and with the FSMIC; and walk every node alone at its own task, from quiet standing and
    reached from level walking (``nodes``; computed on first request, about ten seconds plus half a CPU-second per
    node, then stored; node walks the server has made before are not walked again). Safety figures (``safety``: the
    course walk's flags, then each node's, each on its own bound), errors per segment against the reference at each
    stride's true task, the leg's estimation accuracy, and the envelope's per-stride RMSE minus the FSMIC's with 95 %
    intervals."""
    return await _walk_once(("envelope", envelope_id), user.username, _envelope_preview, envelope_id, conn, model,
                            request.app.state.benchmark_walks, request.app.state.node_walks)


def _envelope_preview(envelope_id: int, conn: Connection, model: QuasiStiffnessModel, benchmark: BenchmarkWalks,
                      nodes: NodeWalks, walk: bool = True) -> dict | None:
    """The stored preview, walked first if there is none (``walk=False``: None instead)."""
    row = versions.get_row(conn, "envelope", envelope_id)
    stored = previews.get_preview(conn, "envelope", envelope_id, row["content_sha256"])
    if stored is None and not walk:
        return None
    if stored is None:
        checked = as_run(versions.stored_envelope(row))
        _refuse_unsafe(checked.violations, f"envelope {envelope_id}")
        result = preview_envelope(checked.item, model, COURSES[PREVIEW_COURSE], legs.version_leg(row).geometry(),
                                  benchmark, nodes)
        stored = previews.store_preview(conn, "envelope", envelope_id, row["content_sha256"], result)
    return {"envelope_id": envelope_id, **stored, "safety": envelope_flags(stored)}


def _refuse_unsafe(violations: list, what: str) -> None:
    """The bench runs only what the device would accept (a stored version from before values were rounded first may
    lie outside a limit by less than a wire step)."""
    if violations:
        raise ConflictError(f"{what} fails the safety limits as the device would run it, so the device would refuse "
                            "it and there is nothing to preview: " + "; ".join(v.message for v in violations[:5]),
                            violations=[v.model_dump() for v in violations])
