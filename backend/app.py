"""The FastAPI application: routers per resource, error bodies people can read, start-up work.

``create_app(settings)`` migrates the database, starts loading the model in the background and returns the
app; ``quasitune serve`` runs it with uvicorn. Error bodies are ``{"detail": "<sentence>", ...}``: request
validation errors name the field, the value's problem and the allowed range; domain errors carry extra keys
(``violations``) for scripts.
"""

from __future__ import annotations

import re
from collections.abc import AsyncIterator, Callable
from contextlib import asynccontextmanager

import anyio.to_thread
from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from starlette.exceptions import HTTPException as StarletteHTTPException

from backend import __version__
from backend.bench.node_previews import NodeWalks
from backend.bench.preview import BenchmarkWalks
from backend.body_limit import GateBodies, body_rules
from backend.db import open_engine
from backend.devices import DeviceManager, parse_device_specs
from backend.errors import DomainError, MovedError
from backend.frontend import mount_frontend
from backend.headers import RefuseAnonymousWrites, add_security_headers, mount_docs
from backend.instance_beat import InstanceBeat
from backend.migrate import migrate, require_current
from backend.model_service import ModelService
from backend.refusal_words import sentence
from backend.routers import (
    audit,
    auth,
    device_credentials,
    devices,
    gate,
    health,
    jobs,
    patients,
    previews,
    pushes,
    reference,
    refinements,
    sessions,
    users,
    versions,
)
from backend.schemas.errors import FieldError
from backend.security import set_hash_cost
from backend.settings import Settings
from backend.throttle import LoginThrottle
from backend.unhandled import AnswerFaults
from backend.viewer3d import ViewerRegistry
from controller_core import QuasiStiffnessModel, load_default_model, load_model
from device_bridge.clock import WALL_CLOCK, Clock, PacedClock
from device_bridge.mqtt_connection import MqttConnection
from device_bridge.sim.leg_file import LegFile, load_leg_file


def _field(loc: tuple) -> str:
    parts = [str(p) for p in loc if p not in ("body", "query", "path", "header", "form")]
    return ".".join(parts) or "request"


def _validation_body(exc: RequestValidationError) -> dict:
    """The refusal in clinical words (``detail``); per error the field's code and type for scripts (``errors``)."""
    errors = [{"field": _field(tuple(e.get("loc", ()))), "message": sentence(e), "type": e.get("type")}
              for e in exc.errors()]
    summary = "; ".join(dict.fromkeys(e["message"] for e in errors[:5]))
    return {"detail": f"Not accepted: {summary}.", "errors": errors}


def _allowed_methods(app: FastAPI, request: Request) -> list[str]:
    """Methods the OpenAPI schema documents for the request's path."""
    methods: set[str] = set()
    for template, operations in app.openapi()["paths"].items():
        pattern = "^" + re.sub(r"\\{[^}]+\\}", "[^/]+", re.escape(template)) + "$"
        if re.match(pattern, request.url.path):
            methods |= {m.upper() for m in operations}
    return sorted(methods)


def _default_loader(settings: Settings) -> Callable[[], QuasiStiffnessModel]:
    if settings.model_dir is not None:
        return lambda: load_model(settings.model_dir)
    return load_default_model


def broker_connection(settings: Settings) -> MqttConnection | None:
    """This instance's one connection to the broker of the settings, shared by every leg ``mqtt:DEVICE_ID`` it serves
    (its own client id, so several instances each read every leg's frames); None without a broker identity."""
    if settings.broker_url is None or not settings.broker_username or settings.broker_password is None:
        return None
    return MqttConnection(settings.broker_url, settings.broker_username, settings.broker_password.get_secret_value(),
                          ca_file=None if settings.broker_ca_file is None else str(settings.broker_ca_file),
                          instance=settings.instance_name)


def prepare_storage(settings: Settings) -> None:
    """The embedded SQLite file: create the data directory and bring the database up to date. A server database:
    refuse to start unless it is already at this QuasiTune's revision (``quasitune db upgrade`` migrates it, once,
    before the instances start)."""
    if settings.database_url is not None:
        require_current(settings.database_url, settings.migrations_dir)
        return
    settings.data_dir.mkdir(parents=True, exist_ok=True)
    migrate(settings.db_path, settings.migrations_dir)


def create_app(settings: Settings, model_loader: Callable[[], QuasiStiffnessModel] | None = None,
               clock: Clock | None = None) -> FastAPI:
    """Build the app for ``settings`` (migrates the database now; the model loads in the background). ``clock``: what
    the device stack runs on. None: simulated legs only run on a :class:`~device_bridge.clock.PacedClock` (the leg and
    its link on one clock kept with the wall clock: a busy machine slows the simulated patient, it cannot make the
    leg miss its host's heartbeat), anything else on the wall clock; a stepped one (tests) runs a simulated leg and its
    link in simulated time, moved by whoever waits on it."""
    set_hash_cost(settings.password_hash_cost)
    prepare_storage(settings)

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        # at most this many request handlers in worker threads at once (anyio's default is 40): on a GIL-bound
        # process every extra thread is one more to queue behind for the interpreter, and the event loop that
        # streams live telemetry queued behind all of them (gaps of 0.8 s under 20 reading clients)
        anyio.to_thread.current_default_thread_limiter().total_tokens = settings.request_threads
        yield
        if app.state.viewers is not None:
            app.state.viewers.close()
        if isinstance(app.state.clock, PacedClock):
            app.state.clock.close()
        app.state.instance_beat.close()
        app.state.devices.close()
        app.state.node_walks.close()
        if app.state.broker is not None:
            app.state.broker.close()
        app.state.db.dispose()

    app = FastAPI(title="QuasiTune", version=__version__, lifespan=lifespan, docs_url=None, redoc_url=None,
                  description="Learning quasi-stiffness tuning for a powered knee-ankle prosthesis: patients, "
                              "proposals with uncertainty, approval, audit. Angles in deg, moments in N·m or "
                              "N·m/kg, stiffness in N·m/rad — the unit is in every field name.")
    app.state.settings = settings
    app.state.login_throttle = LoginThrottle(settings.login_per_user_per_minute, settings.login_per_address_per_minute,
                                             settings.login_per_user_anywhere_per_minute)
    app.state.db = open_engine(settings.database)
    app.state.model = ModelService(model_loader or _default_loader(settings)).start()
    specs = parse_device_specs(settings.device)
    # the simulated leg's, and the leg a patient's versions are made for and walked on where theirs is not described
    app.state.bench_leg_file = load_leg_file(settings.bench_leg) if settings.bench_leg is not None else LegFile()
    app.state.benchmark_walks = BenchmarkWalks()   # previews' walks (the FSMIC's, the versions'), kept by content
    app.state.node_walks = NodeWalks(settings.bench_processes)   # envelope nodes walked alone, kept by content
    app.state.broker = None
    if any(spec.interface == "mqtt" for spec in specs):
        app.state.broker = broker_connection(settings)
        if app.state.broker is None:
            raise ValueError(f"device {settings.device} is reached through the broker: set QUASITUNE_BROKER_URL, "
                             "QUASITUNE_BROKER_USERNAME and QUASITUNE_BROKER_PASSWORD (this instance's identity there)")
    bus_options = {} if app.state.broker is None else {"mqtt": {"role": "server", "connection": app.state.broker}}
    paced = None
    if clock is None:
        simulated_only = bool(specs) and all(spec.kind == "simulated" for spec in specs)
        paced = PacedClock() if simulated_only else None
        clock = paced or WALL_CLOCK
    try:
        app.state.devices = DeviceManager(app.state.db, specs, app.state.bench_leg_file.geometry(), bus_options=bus_options,
                                          clock=clock).start()
    except BaseException:     # a leg refused at the broker: the connection's threads must not outlive the failed start
        if app.state.broker is not None:
            app.state.broker.close()
        raise
    app.state.clock = paced.start() if paced is not None else clock
    app.state.devices.instance_name = settings.instance_name
    app.state.instance_beat = InstanceBeat(app.state.db, settings.instance_name).start()
    app.state.viewers = ViewerRegistry(app.state.devices) if settings.viewer3d else None

    @app.exception_handler(RequestValidationError)
    async def _on_validation(_request: Request, exc: RequestValidationError) -> JSONResponse:
        return JSONResponse(_validation_body(exc), status_code=422)

    @app.exception_handler(StarletteHTTPException)
    async def _on_http(request: Request, exc: StarletteHTTPException) -> JSONResponse:
        headers = dict(exc.headers or {})
        if exc.status_code == 405:   # Starlette names only the first matching route's methods; name them all
            headers["Allow"] = ", ".join(_allowed_methods(app, request))
        if exc.status_code == 400 and "parsing the body" in str(exc.detail):
            return JSONResponse({"detail": "the request body could not be parsed: send UTF-8 JSON (or a form where "
                                           "the operation takes one)"}, status_code=422)
        return JSONResponse({"detail": exc.detail}, status_code=exc.status_code, headers=headers)

    @app.exception_handler(DomainError)
    async def _on_domain(request: Request, exc: DomainError) -> JSONResponse:
        headers = {"Retry-After": str(exc.extra["retry_after_s"])} if "retry_after_s" in exc.extra else None
        if isinstance(exc, MovedError):   # the same path under the envelope's version id
            path = request.url.path.replace(f"/envelopes/{exc.moved_from}", f"/envelopes/{exc.extra['moved_to']}", 1)
            headers = {"Location": str(request.url.replace(path=path))}
        return JSONResponse({"detail": exc.message, **exc.extra}, status_code=exc.status, headers=headers)

    for router in (health.router, auth.router, users.router, patients.router, versions.router,
                   previews.router, reference.router, pushes.router, sessions.router, devices.router, audit.router,
                   refinements.router, device_credentials.router, gate.router, jobs.router):
        app.include_router(router)
    mount_frontend(app, settings.frontend_dir)
    mount_docs(app)
    app.add_middleware(RefuseAnonymousWrites)   # its 401 carries the security headers itself
    app.add_middleware(GateBodies, rules=body_rules(app), db=lambda: app.state.db)   # bound and role, body unread
    app.add_middleware(AnswerFaults)            # a 500 that keeps the connection open (inside the security headers)
    add_security_headers(app)
    app.openapi = lambda: _openapi(app)
    return app


def app_from_environment() -> FastAPI:
    """The app configured from the environment (:class:`backend.settings.Settings`, ``QUASITUNE_*``), for running under
    uvicorn directly (``--factory``), e.g. as several workers behind a reverse proxy; its device defaults to ``none``:
    a device lives in exactly one process."""
    return create_app(Settings())


def _openapi(app: FastAPI) -> dict:
    """FastAPI's schema with its default 422 body replaced by the one this app actually sends."""
    if app.openapi_schema is None:
        from fastapi.openapi.utils import get_openapi

        schema = get_openapi(title=app.title, version=app.version, description=app.description, routes=app.routes)
        components = schema.setdefault("components", {}).setdefault("schemas", {})
        if "HTTPValidationError" in components:
            components["HTTPValidationError"] = {
                "title": "HTTPValidationError", "type": "object", "required": ["detail"],
                "properties": {
                    "detail": {"type": "string", "description": "which fields are wrong and why"},
                    "errors": {"type": "array", "items": {"$ref": "#/components/schemas/FieldError"}},
                }}
            components.pop("ValidationError", None)
            components["FieldError"] = FieldError.model_json_schema()
        app.openapi_schema = schema
    return app.openapi_schema
