"""The server's settings, in one place: every knob, read from ``QUASITUNE_*`` environment variables (pydantic-settings)
and overridden by the command line, which passes its flags as keyword arguments (they win over the environment).

``QUASITUNE_CACHE_DIR`` (where the trained default model is cached) is read by ``controller_core.model_io`` itself:
the model layer sits below the backend and is used without a server.
"""

from __future__ import annotations

import json
import os
import socket
from pathlib import Path
from typing import Annotated

from pydantic import Field, SecretStr, field_validator, model_validator
from pydantic_settings import BaseSettings, NoDecode, SettingsConfigDict

DB_FILE = "quasitune.sqlite"
REPOSITORY = Path(__file__).resolve().parents[1]


def default_frontend_dir() -> Path:
    """The repository's ``frontend/`` (an editable install; another copy is named with ``QUASITUNE_FRONTEND_DIR``)."""
    return REPOSITORY / "frontend"


def default_migrations_dir() -> Path:
    """The repository's ``migrations/`` (another copy is named with ``QUASITUNE_MIGRATIONS_DIR``)."""
    return REPOSITORY / "migrations"


def default_data_dir() -> Path:
    """The per-user data directory when ``QUASITUNE_DATA_DIR`` names none: ``$XDG_DATA_HOME/quasitune``, else
    ``~/.local/share/quasitune``."""
    base = os.environ.get("XDG_DATA_HOME") or str(Path.home() / ".local" / "share")
    return Path(base) / "quasitune"


class Settings(BaseSettings):
    """Every field is also ``QUASITUNE_<FIELD>`` in the environment (``QUASITUNE_DATA_DIR``, ``QUASITUNE_DEVICE`` …).

    Args:
        data_dir: holds the SQLite file (created if missing), the embedded default database.
        database_url: a server database instead of the SQLite file: ``postgresql://USER:PASSWORD@HOST:PORT/NAME``
            (psycopg 3 whatever driver is named). For several API instances on more than one machine; migrated once
            by ``quasitune db upgrade`` before they start. None (default): the SQLite file in ``data_dir``.
        token_ttl_s: bearer-token lifetime (s).
        model_dir: a model from ``quasitune train``; None = the default model (shipped data).
        model_wait_s: how long a request waits for the model while it loads at start-up before a 503.
        device: ``sim`` (the simulated leg on an in-process virtual CAN bus), ``none``, or ``INTERFACE:CHANNEL``
            for a python-can bus to a real leg (``socketcan:can0``, ``mqtt:LEG_ID`` through the broker); several
            comma-separated (``mqtt:leg-1,mqtt:leg-2``). ``quasitune serve`` uses ``sim`` when neither its flag nor
            the environment names one; the app factory (several workers) ``none``.
        frontend_dir: the dashboard (``index.html``, ``app/``) and its npm packages (``node_modules/``).
        migrations_dir: the schema migrations applied at start-up.
        broker_url: the MQTT broker the legs connect to (``mqtts://HOST:8883``); a device ``mqtt:DEVICE_ID`` is reached
            through it. None: no broker (the embedded default).
        broker_username, broker_password: this API instance's identity at the broker (``quasitune broker add-server``).
        broker_ca_file: the CA that signed the broker's certificate (QuasiTune's own, made at the broker's first start).
        broker_credentials: a credentials file (JSON ``username``, ``password``, ``ca_file``, as ``quasitune broker
            add-server --out`` writes it) standing in for the three above, so the password is in no environment.
        broker_admin_username, broker_admin_password: the broker's admin identity, with which an admin's request
            registers, replaces or revokes a leg's credentials (Mosquitto's dynamic security); None: not from the API.
        instance_name: this API instance's name at the broker (its MQTT client ids); default ``HOSTNAME-PID``.
        bench_leg: a leg file (``device_bridge/sim/legs/*.json`` or a path) for the simulated leg and the bench
            previews; None: the nominal bench.
        viewer3d: also serve viser's 3D view of each leg on a loopback port. Off by default: viser has no login,
            so anyone on this machine could watch the live telemetry there; the dashboard's own leg view comes
            through the signed-in telemetry stream instead.
        trusted_proxies: addresses of reverse proxies whose ``X-Forwarded-For`` / ``X-Forwarded-Proto`` are believed
            (uvicorn's ``forwarded_allow_ips``; in the environment comma- or space-separated). None by default: every
            other client could otherwise claim any address and dodge, or aim, the sign-in throttle.
        bench_processes: processes that walk an envelope's nodes side by side (``backend.bench.node_previews``);
            default one fewer than the machine's cores, at most 8; 1: in turn on the bench's own thread.
        request_threads: request handlers run at once in worker threads. The process is bound by one interpreter
            lock: more threads add no throughput and starve the event loop that streams live telemetry.
        login_per_user_per_minute, login_per_address_per_minute, login_per_user_anywhere_per_minute: failed
            sign-ins allowed per minute for one user name from one address, from one address, and for one user name
            from anywhere (:class:`backend.throttle.LoginThrottle`).
        password_hash_cost: scrypt's n for the password hashes this process makes (2¹⁴, 16 MiB each, in production;
            a power of two). Lower it only for a test run, which makes hundreds of hashes.
    """

    model_config = SettingsConfigDict(env_prefix="QUASITUNE_", frozen=True, extra="forbid")

    data_dir: Path = Field(default_factory=default_data_dir)
    database_url: str | None = None
    token_ttl_s: int = Field(default=8 * 3600, gt=0)
    model_dir: Path | None = None
    model_wait_s: float = Field(default=30.0, gt=0)
    device: str = "none"
    frontend_dir: Path = Field(default_factory=default_frontend_dir)
    migrations_dir: Path = Field(default_factory=default_migrations_dir)
    bench_leg: Path | None = None
    broker_url: str | None = None
    broker_username: str | None = None
    broker_password: SecretStr | None = None
    broker_ca_file: Path | None = None
    broker_credentials: Path | None = None
    broker_admin_username: str | None = None
    broker_admin_password: SecretStr | None = None
    instance_name: str = Field(default_factory=lambda: f"{socket.gethostname()}-{os.getpid()}", min_length=1,
                               max_length=40, pattern=r"^[A-Za-z0-9._-]+$")
    viewer3d: bool = False
    trusted_proxies: Annotated[tuple[str, ...], NoDecode] = ()
    request_threads: int = Field(default=2, ge=1, le=64)
    bench_processes: int = Field(default_factory=lambda: max(min((os.cpu_count() or 1) - 1, 8), 1), ge=1, le=64)
    login_per_user_per_minute: int = Field(default=5, ge=1)
    login_per_address_per_minute: int = Field(default=20, ge=1)
    login_per_user_anywhere_per_minute: int = Field(default=100, ge=1)
    password_hash_cost: int = Field(default=2**14, ge=2, le=2**20)

    @field_validator("password_hash_cost")
    @classmethod
    def _power_of_two(cls, value: int) -> int:
        if value & (value - 1):
            raise ValueError(f"password_hash_cost must be a power of two (scrypt's n), got {value}")
        return value

    @field_validator("trusted_proxies", mode="before")
    @classmethod
    def _split_addresses(cls, value: object) -> object:
        """``"10.0.0.2, 10.0.0.3"`` from the environment becomes ``("10.0.0.2", "10.0.0.3")``."""
        return tuple(value.replace(",", " ").split()) if isinstance(value, str) else value

    @model_validator(mode="before")
    @classmethod
    def _credentials_file(cls, data: object) -> object:
        """The broker identity from ``broker_credentials`` where the fields themselves are not given."""
        if not isinstance(data, dict) or not data.get("broker_credentials"):
            return data
        path = Path(data["broker_credentials"])
        try:
            found = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, ValueError) as exc:
            raise ValueError(f"broker_credentials {path}: not a readable JSON file ({exc})") from None
        if not isinstance(found, dict) or not all(isinstance(found.get(k), str) and found[k]
                                                  for k in ("username", "password")):
            raise ValueError(f"broker_credentials {path}: username and password are needed")
        return {"broker_username": found["username"], "broker_password": found["password"],
                **({"broker_ca_file": found["ca_file"]} if found.get("ca_file") else {}), **data}

    @field_validator("database_url")
    @classmethod
    def _known_database(cls, value: str | None) -> str | None:
        """Only SQLite and PostgreSQL URLs (ValueError naming the database otherwise)."""
        if value is None or not value.strip():
            return None
        from backend.db import database_url

        if "://" not in value:
            raise ValueError("database_url must be a URL such as postgresql://USER:PASSWORD@HOST:5432/quasitune")
        return database_url(value)

    @property
    def db_path(self) -> Path:
        """The embedded SQLite file (used when :attr:`database_url` names no server database)."""
        return self.data_dir / DB_FILE

    @property
    def database(self) -> str | Path:
        """What the store opens: :attr:`database_url`, else the SQLite file."""
        return self.database_url or self.db_path

    @property
    def database_shown(self) -> str:
        """The database as logs and messages name it (a URL's password hidden)."""
        if self.database_url is None:
            return str(self.db_path)
        from sqlalchemy.engine import make_url

        return make_url(self.database_url).render_as_string(hide_password=True)

    def given(self, name: str) -> bool:
        """Whether ``name`` was set by the environment or the command line rather than left at its default."""
        return name in self.model_fields_set
