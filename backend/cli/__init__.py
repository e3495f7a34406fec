"""The ``quasitune`` command line.

Commands by area: the server (``serve``, ``users``, ``bridge``: :mod:`backend.cli.server`; ``broker``:
:mod:`backend.cli.broker`), the model (``predict``,
``plot``, ``train``, ``evaluate``, ``envelope``: :mod:`backend.cli.model`), the simulated bench (``simulate``, ``compare``:
:mod:`backend.cli.simulation`) and the device link (``device soak|drill``: :mod:`backend.cli.device`). Bad input
exits with code 2 and a one-line reason on stderr. Benchmarks are not commands of the app: ``python -m benchmarks``.
"""

from __future__ import annotations

import argparse
import sys

from backend.cli import broker, device, model, server, simulation
from backend.errors import DomainError
from controller_core import InvalidTaskError, SafetyLimitError


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="quasitune", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    for area in (server, broker, device, model, simulation):
        area.add_commands(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return int(args.func(args))
    except (InvalidTaskError, FileNotFoundError, ValueError, SafetyLimitError, DomainError) as exc:
        msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        print(f"quasitune: error: {msg}", file=sys.stderr)
        return 2
