"""The ``quasitune`` command line.

Commands by area: the leg (``leg``: :mod:`device_bridge.osl.cli`, the one command a leg's computer runs), the
server (``serve``, ``users``, ``bridge``: :mod:`backend.cli.server`; ``broker``: :mod:`backend.cli.broker`), the model
(``predict``, ``train``, ``envelope``: :mod:`backend.cli.model`), the simulated bench (``simulate``, ``stumble``,
``sensitivity``: :mod:`backend.cli.simulation`) and the device link (``device soak|drill``: :mod:`backend.cli.device`).
Commands from other installed packages join through the ``quasitune.commands`` entry point: the lab's bench studies
and evaluation (``compare``, ``refine``, ``calibrate``, ``stance-response``, ``plot``, ``evaluate``: :mod:`lab.cli`),
so the product imports nothing from the lab. Bad input exits with code 2 and a one-line reason on stderr. Benchmarks
are not commands of the app: ``python -m benchmarks``.
"""

from __future__ import annotations

import argparse
import sys
from importlib.metadata import entry_points

COMMANDS_ENTRY_POINT = "quasitune.commands"   # each names an add_commands(subparsers) that adds its commands


def build_parser() -> argparse.ArgumentParser:
    from backend.cli import broker, device, model, server, simulation
    from device_bridge.osl.cli import add_arguments

    parser = argparse.ArgumentParser(prog="quasitune", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    for area in (server, broker, device, model, simulation):
        area.add_commands(sub)
    for plugin in entry_points(group=COMMANDS_ENTRY_POINT):
        plugin.load()(sub)
    add_arguments(sub.add_parser("leg", help="the leg side on the leg's computer: an Open Source Leg through its SDK "
                                             "(device_bridge/osl/cli.py; installs with .[leg] alone)"))
    return parser


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if argv[:1] == ["leg"]:      # the leg's computer has none of the server's packages: nothing else is imported
        from device_bridge.osl.cli import main as leg_main

        return leg_main(argv[1:])
    from backend.errors import DomainError
    from controller_core import InvalidTaskError, SafetyLimitError

    args = build_parser().parse_args(argv)
    try:
        return int(args.func(args))
    except (InvalidTaskError, FileNotFoundError, ValueError, SafetyLimitError, DomainError) as exc:
        msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        print(f"quasitune: error: {msg}", file=sys.stderr)
        return 2
