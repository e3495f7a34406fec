"""Server settings: where the data lives and how long a login lasts."""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

DB_FILE = "quasitune.sqlite"


def default_frontend_dir() -> Path:
    """The dashboard: ``$QUASITUNE_FRONTEND_DIR``, else the repository's ``frontend/`` (editable install)."""
    if os.environ.get("QUASITUNE_FRONTEND_DIR"):
        return Path(os.environ["QUASITUNE_FRONTEND_DIR"])
    return Path(__file__).resolve().parents[1] / "frontend"


def default_data_dir() -> Path:
    """Per-user data directory: ``$QUASITUNE_DATA_DIR``, else ``$XDG_DATA_HOME/quasitune``, else
    ``~/.local/share/quasitune``."""
    if os.environ.get("QUASITUNE_DATA_DIR"):
        return Path(os.environ["QUASITUNE_DATA_DIR"])
    base = os.environ.get("XDG_DATA_HOME") or str(Path.home() / ".local" / "share")
    return Path(base) / "quasitune"


@dataclass(frozen=True)
class Settings:
    """Args:
        data_dir: holds the SQLite file (created if missing).
        token_ttl_s: bearer-token lifetime (s).
        model_dir: a model from ``quasitune train``; None = the default model (shipped data).
        model_wait_s: how long a request waits for the model while it loads at start-up before a 503.
        device: ``sim`` (the simulated leg on an in-process virtual CAN bus), ``none``, or ``INTERFACE:CHANNEL``
            for a python-can bus to a real leg (``socketcan:can0``). ``quasitune serve`` defaults to ``sim``.
        frontend_dir: the dashboard (``index.html``, ``app/``) and its npm packages (``node_modules/``).
        bench_leg: a leg file (``device_bridge/sim/legs/*.json`` or a path) for the simulated leg and the bench
            previews; None: the nominal bench.
        viewer3d: also serve viser's 3D view of each leg on a loopback port. Off by default: viser has no login,
            so anyone on this machine could watch the live telemetry there; the dashboard's own leg view comes
            through the signed-in telemetry stream instead.
        trusted_proxies: addresses of reverse proxies whose ``X-Forwarded-For`` / ``X-Forwarded-Proto`` are believed
            (uvicorn's ``forwarded_allow_ips``). None by default: every other client could otherwise claim any
            address and dodge, or aim, the sign-in throttle.
        request_threads: request handlers run at once in worker threads. The process is bound by one interpreter
            lock: more threads add no throughput and starve the event loop that streams live telemetry.
    """

    data_dir: Path
    token_ttl_s: int = 8 * 3600
    model_dir: Path | None = None
    model_wait_s: float = 30.0
    device: str = "none"
    frontend_dir: Path = field(default_factory=default_frontend_dir)
    viewer3d: bool = False
    bench_leg: Path | None = None
    trusted_proxies: tuple[str, ...] = ()
    request_threads: int = 2

    @property
    def db_path(self) -> Path:
        return self.data_dir / DB_FILE
