"""Helpers shared by the API tests: an in-process app with one user per role on a temporary database."""

from __future__ import annotations

import os
import shutil
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from fastapi.testclient import TestClient
from sqlalchemy import func, select

from backend.app import create_app
from backend.db import connect
from backend.errors import NotFoundError
from backend.settings import Settings
from backend.store.tables import metadata
from backend.store.users import ROLES, create_user, id_of
from device_bridge.clock import WALL_CLOCK, SteppedClock
from tests.helpers.server import PASSWORD

DEVICE = "sim-leg-1"   # the simulated leg of an app made with device="sim"
SECOND = "prosthetist-b"   # a second prosthetist: the gate's override takes two


@dataclass
class Api:
    client: TestClient
    data_dir: Path
    headers: dict[str, dict[str, str]] = field(default_factory=dict)
    database: str | Path | None = None     # what the app stores in: its SQLite file or a PostgreSQL URL
    clock: SteppedClock | None = None      # the device stack's, when the app runs its simulated leg stepped

    def as_(self, role: str) -> dict[str, str]:
        """The bearer header of ``role``'s user, signed in through the API the first time a test asks (most tests act
        as one or two of the four: signing all in up front was a third of an app's set-up)."""
        if role not in self.headers:
            r = self.client.post("/api/auth/token", data={"username": role, "password": PASSWORD})
            assert r.status_code == 200, r.text
            self.headers[role] = {"Authorization": f"Bearer {r.json()['access_token']}"}
        return self.headers[role]

    def db(self):
        """A connection of the test's own to the app's database (SQLAlchemy; close it, or use it in ``with``)."""
        return connect(self.database or self.data_dir / "quasitune.sqlite")

    def count(self, table: str) -> int:
        """Rows in a table of the app's database (to check that a refused request stored nothing); "proposals" and
        "envelopes" count the versions of that kind (one table holds both)."""
        kinds = {"proposals": "table", "envelopes": "envelope"}
        versions = metadata.tables["versions"]
        query = (select(func.count()).select_from(versions).where(versions.c.kind == kinds[table]) if table in kinds
                 else select(func.count()).select_from(metadata.tables[table]))
        with self.db() as conn:
            return conn.execute(query).scalar_one()

    def new_patient(self, code: str = "P-001", mass: float = 80.0) -> dict:
        r = self.client.post("/api/patients", headers=self.as_("prosthetist"),
                             json={"code_name": code, "body_mass_kg": mass, "side": "left", "height_m": 1.78,
                                   "k_level": 3})
        assert r.status_code == 201, r.text
        return r.json()

    def propose(self, patient_id: int, speed: float = 1.2, incline: float = 0.0, **extra) -> dict:
        """A draft proposal (``extra``: more of the request body, e.g. ``extrapolate`` and ``reason``)."""
        r = self.client.post(f"/api/patients/{patient_id}/proposals", headers=self.as_("prosthetist"),
                             json={"speed_mps": speed, "incline_deg": incline, **extra})
        assert r.status_code == 201, r.text
        return r.json()


def make_api(data_dir: Path, model_loader, **settings) -> tuple[Api, TestClient]:
    """App on ``data_dir`` (or on ``database_url``, a migrated PostgreSQL database, when the settings name one) loading
    its model with ``model_loader``, with users prosthetist/viewer/admin and a second prosthetist :data:`SECOND`
    (password :data:`PASSWORD`), each signed in when a test first acts as them (:meth:`Api.as_`).
    ``template``: an SQLite file already at the newest revision, copied in first; ``clock``: the device stack's (a
    :class:`~device_bridge.clock.SteppedClock` runs the simulated leg in simulated time, moved by :func:`wait_for`)."""
    template = settings.pop("template", None)      # a migrated SQLite file to start from (migrating is slow)
    clock = settings.pop("clock", None)
    data_dir.mkdir(parents=True, exist_ok=True)
    database = settings.get("database_url") or data_dir / "quasitune.sqlite"
    copied = template is not None and "database_url" not in settings and not (data_dir / "quasitune.sqlite").exists()
    if copied:
        shutil.copyfile(template_with_users(Path(template)), database)
    app = create_app(Settings(data_dir=data_dir, **settings), model_loader=model_loader,
                     **({} if clock is None else {"clock": clock}))
    if not copied and not has_users(database):
        add_users(database)
    share_bench_walks(app)
    client = TestClient(app)
    return Api(client=client, data_dir=data_dir, database=database, clock=clock), client


def add_users(database: str | Path) -> None:
    """The users of :func:`make_api`: one per role (named after it) and :data:`SECOND`, password :data:`PASSWORD`."""
    with connect(database) as conn:
        for name, role in ({role: role for role in ROLES} | {SECOND: "prosthetist"}).items():
            create_user(conn, name, role, PASSWORD)


def has_users(database: str | Path) -> bool:
    """Whether ``database`` already holds :func:`add_users`'s users (a copy of a template made with them)."""
    with connect(database) as conn:
        try:
            id_of(conn, SECOND)
        except NotFoundError:
            return False
    return True


_WITH_USERS: dict[Path, Path] = {}


def template_with_users(template: Path) -> Path:
    """A copy of the migrated SQLite ``template`` with :func:`add_users`'s users in it, made once per test process
    (checking four passwords' strength and storing them was a fifth of an in-process app's set-up)."""
    if template not in _WITH_USERS:
        with_users = template.with_name(f"users-{os.getpid()}-{template.name}")
        shutil.copyfile(template, with_users)
        add_users(with_users)
        _WITH_USERS[template] = with_users
    return _WITH_USERS[template]


_BENCH_WALKS: list[tuple[object, object]] = []


def share_bench_walks(app) -> None:
    """Give ``app`` this test process's kept bench walks (the FSMIC's, the versions' own, the envelopes' node walks). A
    walk is deterministic by its content, and a server keeps them for its life; the test process is that life for its
    in-process apps, so the SQLite and PostgreSQL runs of a test walk one version once. A test that must see a walk
    happen gives its app a fresh ``BenchmarkWalks`` (``tests/backend/routers/test_jobs.py``)."""
    if not _BENCH_WALKS:
        _BENCH_WALKS.append((app.state.benchmark_walks, app.state.node_walks))
    app.state.benchmark_walks, app.state.node_walks = _BENCH_WALKS[0]


def wait_for(fetch: Callable[[], object], predicate: Callable[[object], bool], timeout_s: float = 10.0,
             clock: SteppedClock | None = None):
    """Call ``fetch`` until ``predicate`` holds for its value (returned); fail with the last value after the timeout.
    Each look is a request the app serves (the samples so far, a device's status), so looks are spaced to what is
    waited for, seconds of walking: with a stepped ``clock`` (an app's simulated leg) each moves it on 100 ms and the
    timeout is simulated time (at 20 ms a step the looks were most of a walking test's time); otherwise every 50 ms."""
    time_of, pause, step_s = (WALL_CLOCK, time.sleep, 0.05) if clock is None else (clock, clock.advance, 0.1)
    deadline = time_of.monotonic() + timeout_s
    while not predicate(value := fetch()):
        assert time_of.monotonic() < deadline, f"condition not reached in {timeout_s:g} s; last value {value}"
        pause(step_s)
    return value


def wait_recorded(api: Api, session_id: int, seconds: float, timeout_s: float = 60.0) -> None:
    """Wait until the session holds ``seconds`` of the device's samples (by its 10 ms period, not the host's clock).
    On a stepped app the simulated leg walks half a second between looks; otherwise they come twice a second of real
    time (a busier poll would take the in-process leg's interpreter time and change what it walks)."""
    wanted = round(seconds * 100 / 100)
    time_of, pause = (WALL_CLOCK, time.sleep) if api.clock is None else (api.clock, api.clock.advance)
    deadline = time_of.monotonic() + timeout_s
    while api.client.get(f"/api/sessions/{session_id}/samples", params={"every": 100},
                         headers=api.as_("viewer")).json()["count"] < wanted:
        assert time_of.monotonic() < deadline, f"{seconds} s of samples not recorded in {timeout_s} s"
        pause(0.5)


# approving an envelope needs a clean bench preview (about ten seconds of the mixed course) or two prosthetists'
# sign-offs; the tests whose subject is not the approval gate (tests/backend/routers/test_bench_gate.py) take the
# override: :func:`cosign`, then the approval or push with this reason
FIXTURE_OVERRIDE = "test fixture: this test is about what follows approval, not the bench gate"


def cosign(api: Api, kind: str, item_id: int, reason: str = FIXTURE_OVERRIDE) -> dict:
    """The second prosthetist's sign-off on a version's bench findings (``kind``: proposal or envelope): with it, the
    prosthetist's approval or push giving its own ``override_reason`` completes the gate's two-person override."""
    r = api.client.post(f"/api/{kind}s/{item_id}/signoffs", headers=api.as_(SECOND), json={"reason": reason})
    assert r.status_code == 201, r.text
    return r.json()


def approve_anyway(api: Api, kind: str, item_id: int, comment: str = "ok", reason: str = FIXTURE_OVERRIDE):
    """Approve a version as the prosthetist whatever its bench preview says (the second prosthetist signs off first
    where the preview is not clean); returns the response."""
    if api.client.get(f"/api/{kind}s/{item_id}", headers=api.as_("viewer")).json()["bench"]["status"] != "clean":
        cosign(api, kind, item_id, reason)
    return api.client.post(f"/api/{kind}s/{item_id}/approve", headers=api.as_("prosthetist"),
                           json={"comment": comment, "override_reason": reason})


def walk_preview(api: Api, proposal_id: int) -> dict:
    """Walk a proposal's bench preview (about a second), as its page does before a prosthetist decides."""
    r = api.client.get(f"/api/proposals/{proposal_id}/preview", headers=api.as_("viewer"))
    assert r.status_code == 200, r.text
    return r.json()


def approved_proposal(api: Api, speed: float = 1.2) -> dict:
    """A new patient's proposal at ``speed``, its bench preview walked, approved by the prosthetist."""
    patient = api.new_patient()
    prop = api.propose(patient["id"], speed=speed)
    walk_preview(api, prop["id"])
    r = api.client.post(f"/api/proposals/{prop['id']}/approve", headers=api.as_("prosthetist"), json={"comment": "ok"})
    assert r.status_code == 200, r.text
    return prop


def assign(api: Api, patient_id: int, device: str = DEVICE) -> dict:
    """Assign the device to the patient (as the prosthetist would on the live monitor)."""
    r = api.client.put(f"/api/devices/{device}/assignment", headers=api.as_("prosthetist"),
                       json={"patient_id": patient_id})
    assert r.status_code == 200, r.text
    return r.json()


def push_body(api: Api, device: str = DEVICE) -> dict:
    """A push request confirming what the leg runs now (read from the device) and that the patient is ready."""
    d = wait_for(lambda: api.client.get(f"/api/devices/{device}", headers=api.as_("prosthetist")).json(),
                 lambda d: d["online"], clock=api.clock)
    current = d["pending_table"] or d["active_table"]
    return {"device_id": device, "replaces_proposal_id": None if current is None else current["proposal_id"],
            "replaces_envelope_id": None if current is None else current["envelope_id"], "patient_ready": True}


def push_to_leg(api: Api, proposal: dict, device: str = DEVICE, override_reason: str | None = None):
    """Assign the device to the proposal's patient and push the proposal, confirmed (with ``override_reason`` where
    its bench preview is not clean); returns the response."""
    assign(api, proposal["patient_id"], device)
    body = push_body(api, device)
    if override_reason is not None:
        body["override_reason"] = override_reason
    return api.client.post(f"/api/proposals/{proposal['id']}/push", headers=api.as_("prosthetist"), json=body)
