"""Device-link commands: ``device soak`` (pushes through a faulty bus) and ``device drill`` (heartbeat loss)."""

from __future__ import annotations

import argparse
import json

import numpy as np

from backend.cli.model import load
from controller_core.envelope import Envelope
from controller_core.table import ParameterTable


def soak_tables(args: argparse.Namespace, n: int = 12) -> list[ParameterTable]:
    """The tables the soak pushes in turn: the model's proposals from 0.8 to 1.9 m/s (75 kg, level)."""
    model = load(args)
    return [model.propose(float(s), 0.0, 75.0).table for s in np.linspace(0.8, 1.9, n)]


def soak_envelopes(args: argparse.Namespace, shape: tuple[int, int] = (5, 5), n: int = 4) -> list[Envelope]:
    """The envelopes the soak pushes in turn: ``shape`` nodes over 0.6–1.6 m/s × ±10° for patients of 60 to 90 kg."""
    model = load(args)
    return [model.propose_envelope(np.linspace(0.6, 1.6, shape[0]), np.linspace(-10, 10, shape[1]), float(m))
            for m in np.linspace(60.0, 90.0, n)]


def accepted_grids() -> list[tuple[int, int]]:
    """Every envelope grid the API accepts (2–15 nodes per axis, at most 64): what one transfer must carry."""
    from backend.schemas.versions import MAX_NODES

    return [(a, b) for a in range(2, 16) for b in range(2, 16) if a * b <= MAX_NODES]


def _grids(text: str) -> list[tuple[int, int]]:
    """``every`` or a comma-separated list of ``NSxNI`` shapes."""
    if text == "every":
        return accepted_grids()
    try:
        shapes = [tuple(int(v) for v in part.lower().split("x")) for part in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected 'every' or shapes like 5x5,8x8, got {text!r}") from None
    bad = [s for s in shapes if len(s) != 2 or s not in accepted_grids()]
    if bad:
        raise argparse.ArgumentTypeError(f"not a grid the API accepts (2-15 nodes per axis, at most 64): {bad}")
    return shapes   # type: ignore[return-value]


_OUTCOMES = ("committed", "kept_old", "committed_unconfirmed", "mixed", "crc_mismatch")


def cmd_device_soak(args: argparse.Namespace) -> int:
    from device_bridge.soak import soak

    timeout = 6.0 if args.envelopes else 2.0
    if not args.envelopes:
        out = soak(soak_tables(args), args.trials, args.drop, args.corrupt, args.reorder, seed=args.seed,
                   push_timeout_s=timeout)
        runs = {"table": out}
    else:
        runs = {f"{a}x{b}": soak(soak_envelopes(args, (a, b), n=2), args.trials, args.drop, args.corrupt, args.reorder,
                                 seed=args.seed, push_timeout_s=timeout) for a, b in args.grids}
    total = {k: sum(r[k] for r in runs.values()) for k in ("trials", *_OUTCOMES)}
    if args.format == "json":
        print(json.dumps({**total, "runs": runs} if args.envelopes else runs["table"]))
    else:
        what = "table" if not args.envelopes else f"envelope ({len(runs)} grid size(s))"
        print(f"{total['trials']} {what} pushes through a bus with drop {args.drop:g}, corrupt {args.corrupt:g}, "
              f"reorder {args.reorder:g}")
        for key in _OUTCOMES:
            print(f"  {key:22s} {total[key]}")
        for name, r in runs.items():
            print(f"  {name:>6s}: {r['committed']} committed, {r['mixed']} mixed, push median "
                  f"{r['median_push_ms']:.2f} ms, p99 {r['p99_push_ms']:.2f} ms")
    return 0 if total["mixed"] == 0 and total["crc_mismatch"] == 0 else 1


def cmd_device_drill(args: argparse.Namespace) -> int:
    from device_bridge.soak import heartbeat_drill

    print(json.dumps(heartbeat_drill(args.repeats, args.timeout_ms / 1000.0)))
    return 0


def _probability(text: str) -> float:
    value = float(text)
    if not 0.0 <= value < 1.0:
        raise argparse.ArgumentTypeError(f"must be a probability in [0, 1), got {text}")
    return value


def add_commands(sub: argparse._SubParsersAction) -> None:
    from pathlib import Path

    p = sub.add_parser("device", help="device-link tools: soak test, heartbeat drill")
    device_sub = p.add_subparsers(dest="device_command", required=True)
    p = device_sub.add_parser("soak", help="push tables through a fault-injecting virtual bus and count outcomes")
    p.add_argument("--trials", type=int, default=500)
    p.add_argument("--drop", type=_probability, default=0.1, help="probability a frame is lost")
    p.add_argument("--corrupt", type=_probability, default=0.02, help="probability a frame gets one bit flipped")
    p.add_argument("--reorder", type=_probability, default=0.05, help="probability a frame swaps with the next")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--envelopes", action="store_true", help="push whole envelopes instead of single tables")
    p.add_argument("--grids", type=_grids, default=[(5, 5)],
                   help="with --envelopes: grid shapes, e.g. 5x5,8x8,15x4, or 'every' grid the API accepts "
                        "(--trials pushes each)")
    p.add_argument("--model", type=Path, default=None, help="model directory whose proposals are pushed")
    p.add_argument("--format", choices=["text", "json"], default="text")
    p.set_defaults(func=cmd_device_soak)
    p = device_sub.add_parser("drill", help="stop the host heartbeat and time the device's safe mode")
    p.add_argument("--repeats", type=int, default=5)
    p.add_argument("--timeout-ms", type=float, default=200.0, help="the device's heartbeat timeout (ms)")
    p.set_defaults(func=cmd_device_drill)
