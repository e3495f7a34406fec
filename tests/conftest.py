"""Shared fixtures. The default-model cache goes to a per-session temporary directory."""

from __future__ import annotations

import os
import shutil
import tempfile

import pytest

# tests/leg run in the leg's own environment (the Open Source Leg SDK pins numpy<2): scripts/test_leg.sh
collect_ignore = ["leg"]

os.environ.setdefault("QUASITUNE_CACHE_DIR", tempfile.mkdtemp(prefix="quasitune-test-cache-"))
# cheap password hashes for the run (servers the tests start read the same variable through their Settings): the
# suite makes hundreds; the production cost is tested on its own (tests/backend/test_security.py)
TEST_HASH_COST = 16
os.environ["QUASITUNE_PASSWORD_HASH_COST"] = str(TEST_HASH_COST)


def pytest_configure(config: pytest.Config) -> None:
    from backend.security import set_hash_cost

    set_hash_cost(TEST_HASH_COST)


# what a fixture needs, as markers (pyproject.toml): `-m "not browser and not postgres and not broker and not wallclock"`
# is the fast subset (scripts/test.sh --fast); `-m live` the tests whose subject is timing on the wall clock
_MARKS_BY_FIXTURE = {
    "page": ("browser", "wallclock"), "browser": ("browser", "wallclock"),
    "server": ("wallclock", "live"),        # the browser tests' server process, with its simulated leg in real time
    "postgres": ("postgres",), "migrated_postgres": ("postgres",), "migrated_postgres_with_users": ("postgres",),
    "broker": ("broker", "wallclock", "live"), "broker_admin": ("broker", "wallclock", "live"),
}


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    for item in items:
        names = set(getattr(item, "fixturenames", ()))
        marks = {m for name in names & _MARKS_BY_FIXTURE.keys() for m in _MARKS_BY_FIXTURE[name]}
        callspec = getattr(item, "callspec", None)
        if callspec is not None and callspec.params.get("database") == "postgresql":
            marks.add("postgres")
        for m in sorted(marks):
            item.add_marker(m)
    # `--dist loadfile` hands out whole files, in this order: the files that start servers, browsers, brokers or
    # PostgreSQL (the longest) first, so that the short ones fill in at the end instead of one long file running alone
    slow = {item.path for item in items if item.get_closest_marker("wallclock") or item.get_closest_marker("postgres")}
    items.sort(key=lambda item: item.path not in slow)


@pytest.fixture(scope="session")
def reference():
    from controller_core.reference import load_shipped_reference

    return load_shipped_reference()


@pytest.fixture(scope="session")
def model():
    from controller_core import load_default_model

    return load_default_model()


@pytest.fixture(scope="session")
def postgres():
    """A PostgreSQL server of the test run's own (tests/helpers/postgres.py), started when a test first needs it."""
    from tests.helpers.postgres import PostgresServer

    server = PostgresServer()
    try:
        server.start()
        yield server
    finally:
        server.stop()


@pytest.fixture(scope="session")
def broker():
    """A Mosquitto broker of the test run's own (tests/helpers/mosquitto.py): TLS on loopback, a throwaway CA, the
    dynamic security plugin; started when a test first needs it."""
    from tests.helpers.mosquitto import running_broker

    with running_broker() as server:
        yield server


@pytest.fixture
def broker_admin(broker):
    """The broker's admin (device identities), connected for one test."""
    from tests.helpers.mosquitto import admin_of

    with admin_of(broker) as admin:
        yield admin


@pytest.fixture(scope="session")
def migrated_sqlite(tmp_path_factory):
    """An SQLite file brought to the newest revision once per run (each test copies it: migrating is the slow part)."""
    from backend.migrate import migrate

    path = tmp_path_factory.mktemp("template") / "template.sqlite"
    migrate(path)
    return path


@pytest.fixture(scope="session")
def migrated_postgres(postgres):
    """The name of a PostgreSQL database at the newest revision, made once per run as the template of each test's."""
    from backend.migrate import migrate

    name = postgres.create_database("quasitune_template")
    migrate(postgres.url(name))
    return name


@pytest.fixture(scope="session")
def migrated_postgres_with_users(postgres, migrated_postgres):
    """A copy of the migrated PostgreSQL template with :func:`tests.helpers.api.add_users`'s users in it, made once per
    run as the template of each in-process app's database (as the SQLite runs copy one: tests/helpers/api.py)."""
    from tests.helpers.api import add_users

    name = postgres.create_database("quasitune_template_users", template=migrated_postgres)
    add_users(postgres.url(name))
    return name


@pytest.fixture(params=["sqlite", "postgresql"])
def api_storage(request):
    """Where an in-process app stores, once on each database (``make_api``'s keyword arguments): the run's migrated
    SQLite file as the template it copies, or a PostgreSQL database of this test's own, copied from the run's migrated
    template with the test users in it, dropped afterwards."""
    if request.param == "sqlite":
        yield {"template": request.getfixturevalue("migrated_sqlite")}
        return
    template = request.getfixturevalue("migrated_postgres_with_users")
    with request.getfixturevalue("postgres").new_database(template=template) as url:
        yield {"database_url": url}


@pytest.fixture(params=["sqlite", "postgresql"])
def database(request, tmp_path):
    """An empty database at the newest revision, once on each database QuasiTune runs on: an SQLite file's path (a copy
    of the run's migrated file), or a PostgreSQL URL (a database of this test's own, made from the run's migrated
    template, dropped afterwards)."""
    if request.param == "sqlite":
        path = tmp_path / "store.sqlite"
        shutil.copyfile(request.getfixturevalue("migrated_sqlite"), path)
        yield path
        return
    template = request.getfixturevalue("migrated_postgres")
    with request.getfixturevalue("postgres").new_database(template=template) as url:
        yield url


@pytest.fixture
def sim_api(request, tmp_path, model, migrated_sqlite):
    """In-process API with the simulated leg (device ``sim-leg-1``) stepped with its link in simulated time: it walks
    only while something waits on ``api.clock`` (a push, :func:`tests.helpers.api.wait_for` with ``clock=api.clock``,
    ``api.clock.advance``). One signed-in user per role. Parametrized indirectly with ``"wall"`` (marked ``live``), the
    app chooses its clock as ``quasitune serve`` does (the simulated leg paced by the wall clock on a thread of its
    own), and ``api.clock`` is None."""
    from device_bridge.clock import SteppedClock
    from tests.helpers.api import make_api

    clock = None if getattr(request, "param", "stepped") == "wall" else SteppedClock()
    api, _client = make_api(tmp_path, lambda: model, device="sim", viewer3d=True, template=migrated_sqlite,
                            clock=clock)
    yield api
    api.client.app.state.viewers.close()
    api.client.app.state.devices.close()


@pytest.fixture
def api(tmp_path, model, migrated_sqlite):
    """In-process API on a temporary database, one signed-in user per role (see tests/helpers/api.py)."""
    from tests.helpers.api import make_api

    api, client = make_api(tmp_path, lambda: model, template=migrated_sqlite)
    with client:
        yield api


def _walk_at_1_2_mps(table):
    from controller_core.fsm import ImpedanceSchedule, StateMachineController
    from controller_core.walking_reference import level_walking_reference
    from device_bridge.sim.simulate import run_walk, score_walk

    ref = level_walking_reference(1.2)
    log = run_walk(StateMachineController(ImpedanceSchedule.from_table(table)), ref, 75.0, seconds=7.0)
    return log, score_walk(log, ref)


@pytest.fixture(scope="session")
def fsmic_walk():
    """(log, score) of the FSMIC table walked 7 s on the bench at 1.2 m/s, 75 kg."""
    from controller_core.fsmic import fsmic_table

    return _walk_at_1_2_mps(fsmic_table(75.0))


@pytest.fixture(scope="session")
def quasi_stiffness_walk(model):
    """(log, score) of the default model's table walked 7 s on the bench at 1.2 m/s, 75 kg."""
    return _walk_at_1_2_mps(model.propose(1.2, 0.0, 75.0).table)
