"""Model commands: ``predict``, ``plot``, ``train``, ``evaluate``."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from backend.cli.formatting import print_proposal
from controller_core import QuasiStiffnessModel
from device_bridge.bench.command_line import LEG_HELP, leg_named, model_named


def load(args: argparse.Namespace) -> QuasiStiffnessModel:
    """The model named by ``--model``, or the default one."""
    return model_named(args.model)


def task_args(p: argparse.ArgumentParser, speed_required: bool = True) -> None:
    """The task and patient options shared by the commands that propose or simulate."""
    p.add_argument("--speed", type=float, required=speed_required, default=None, help="walking speed (m/s), [0.1, 3]")
    p.add_argument("--incline", type=float, default=0.0, help="incline (deg, + uphill), within ±20")
    p.add_argument("--mass", type=float, default=75.0, help="patient body mass (kg), 20-200")
    p.add_argument("--model", type=Path, default=None, help="model directory from 'quasitune train'")


def swing_ratio(args: argparse.Namespace) -> tuple[float, float]:
    """The swing inertia of the leg named by ``--leg`` over the reference leg's: the swing rows are proposed for it."""
    from device_bridge.sim.swing_inertia import swing_inertia_ratio

    return swing_inertia_ratio(leg_named(args.leg))


def cmd_predict(args: argparse.Namespace) -> int:
    d = load(args).propose(speed_mps=args.speed, incline_deg=args.incline, mass_kg=args.mass,
                           swing_inertia_ratio=swing_ratio(args)).to_dict()
    if args.format == "json":
        print(json.dumps(d, allow_nan=False))
    else:
        print_proposal(d)
    return 0


def cmd_train(args: argparse.Namespace) -> int:
    from controller_core.model_io import save_model, train_default, train_from_file

    print(f"training on {args.data or 'the shipped data'} …", file=sys.stderr, flush=True)
    model = train_default() if args.data is None else train_from_file(args.data, use_published=args.with_published)
    out = save_model(model, args.out)
    print(f"model {model.model_version} ({len(model.reference_.records)} conditions) saved to {out}")
    return 0


def cmd_envelope(args: argparse.Namespace) -> int:
    import numpy as np

    from controller_core.content import canonical_json, content_sha256
    from device_bridge.as_run import as_run

    (s0, s1), (g0, g1) = args.speeds, args.inclines
    env = load(args).propose_envelope(np.linspace(s0, s1, args.grid[0]), np.linspace(g0, g1, args.grid[1]), args.mass,
                                      nominal=(args.nominal[0], args.nominal[1]), swing_inertia_ratio=swing_ratio(args))
    checked = as_run(env)
    violations, wire_crc = checked.violations, checked.wire_crc32 if checked.ok else None
    sha256 = content_sha256(canonical_json(checked.item))
    if args.format == "json":
        print(json.dumps({**env.to_json(), "wire_crc32": wire_crc, "envelope_sha256": sha256, "safety": {
            "ok": not violations, "violations": [v.model_dump() for v in violations]}}, allow_nan=False))
        return 0 if not violations else 1
    print(f"Envelope {len(env.speeds_mps)} × {len(env.inclines_deg)}: speeds "
          f"{', '.join(f'{v:g}' for v in env.speeds_mps)} m/s × inclines {', '.join(f'{v:+g}' for v in env.inclines_deg)}"
          f" deg, patient {env.mass_kg:g} kg, nominal {env.nominal_speed_mps:g} m/s {env.nominal_incline_deg:+g} deg")
    print(f"Model {env.model_version}; sha256 {sha256[:16]}… (as the device runs it)"
          + (f"; CRC-32 {wire_crc:08x} (what the device reads back)" if wire_crc is not None else ""))
    print("\nNodes (x: outside the training data; g: values held to the neighbour rule)")
    print("  " + "speed \\ incline".ljust(16) + "".join(f"{v:+8g}" for v in env.inclines_deg))
    for i, speed in enumerate(env.speeds_mps):
        cells = []
        for j in range(len(env.inclines_deg)):
            node = env.node(i, j)
            cells.append(("x" if node.extrapolation else "·") + ("g" if node.neighbour_guarded else " "))
        print(f"  {speed:<16g}" + "".join(f"{c:>8s}" for c in cells))
    for node in env.nodes:
        for name, fitted in node.neighbour_guarded.items():
            print(f"  guard at {node.speed_mps:g} m/s {node.incline_deg:+g} deg: {name} fitted {fitted:.4g}, held to "
                  "its neighbours' step")
    print("\nSafety (every node's limits, the neighbour rule, as the device will run it): "
          + ("all within limits" if not violations else "VIOLATIONS:"))
    for v in violations:
        print(f"  - {v.message}")
    return 0 if not violations else 1


def add_commands(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("envelope", help="propose an envelope: tables over a speed × incline grid, checked")
    p.add_argument("--speeds", type=float, nargs=2, default=[0.6, 1.6], metavar=("LOW", "HIGH"),
                   help="speed range (m/s)")
    p.add_argument("--inclines", type=float, nargs=2, default=[-10.0, 10.0], metavar=("LOW", "HIGH"),
                   help="incline range (deg)")
    p.add_argument("--grid", type=int, nargs=2, default=[5, 5], metavar=("SPEEDS", "INCLINES"),
                   help="nodes per axis (2-15 each)")
    p.add_argument("--nominal", type=float, nargs=2, default=[1.2, 0.0], metavar=("SPEED", "INCLINE"),
                   help="the task the leg returns to when unsure (clamped into the grid)")
    p.add_argument("--mass", type=float, default=75.0, help="patient body mass (kg), 20-200")
    p.add_argument("--model", type=Path, default=None, help="model directory from 'quasitune train'")
    p.add_argument("--leg", default=None, help=LEG_HELP + " (the swing rows are proposed for its inertia)")
    p.add_argument("--format", choices=["text", "json"], default="text")
    p.set_defaults(func=cmd_envelope)
    p = sub.add_parser("predict", help="propose curves and a parameter table for a task")
    task_args(p)
    p.add_argument("--leg", default=None, help=LEG_HELP + " (the swing rows are proposed for its inertia)")
    p.add_argument("--format", choices=["text", "json"], default="text")
    p.set_defaults(func=cmd_predict)
    p = sub.add_parser("train", help="fit a model from a standard-format dataset (CSV/Parquet)")
    p.add_argument("--data", type=Path, default=None, help="dataset file; default: the shipped data")
    p.add_argument("--out", type=Path, required=True, help="model directory to write")
    p.add_argument("--with-published", action="store_true",
                   help="also train on the shipped published incline features")
    p.set_defaults(func=cmd_train)
