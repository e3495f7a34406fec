"""Commands from other packages join ``quasitune`` through the ``quasitune.commands`` entry point
(``backend/cli/__init__.py``), the lab's among them, and go through the same error handling as the product's."""

from __future__ import annotations

import argparse
from importlib.metadata import entry_points

import backend.cli
from backend.cli import COMMANDS_ENTRY_POINT, build_parser, main


def test_the_lab_is_installed_as_a_plugin_and_its_commands_are_offered():
    assert "lab.cli:add_commands" in {ep.value for ep in entry_points(group=COMMANDS_ENTRY_POINT)}
    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    assert {"compare", "refine", "calibrate", "stance-response", "plot", "evaluate"} <= set(sub.choices)


def test_a_plugin_command_runs_and_its_bad_input_exits_2_with_one_line(monkeypatch, capsys):
    def add_commands(sub: argparse._SubParsersAction) -> None:
        def hello(args: argparse.Namespace) -> int:
            if args.times < 1:
                raise ValueError(f"--times must be at least 1, got {args.times}")
            print("hello " * args.times)
            return 0

        p = sub.add_parser("hello")
        p.add_argument("--times", type=int, default=1)
        p.set_defaults(func=hello)

    class Plugin:
        value = "somewhere:add_commands"

        def load(self):
            return add_commands

    monkeypatch.setattr(backend.cli, "entry_points", lambda group: [Plugin()] if group == COMMANDS_ENTRY_POINT else [])
    assert main(["hello", "--times", "2"]) == 0
    assert capsys.readouterr().out.startswith("hello hello")
    assert main(["hello", "--times", "0"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("quasitune: error: --times must be at least 1") and len(err.strip().splitlines()) == 1
