"""Simulated-bench commands: ``simulate`` (one walk or a course), ``stumble`` (an obstacle in the walk) and
``sensitivity`` (how the refined rows move the features). The bench studies that report through the lab (``compare``,
``refine``, ``calibrate``, ``stance-response``) are the lab's commands: :mod:`lab.cli`."""

from __future__ import annotations

import argparse
from pathlib import Path

from backend.cli.formatting import emit
from backend.cli.model import load, task_args
from device_bridge.bench.command_line import LEG_HELP, leg_named, write_json


def _course(args: argparse.Namespace):
    from device_bridge.sim.course import load_course

    return load_course(args.course)   # ValueError (unknown name, bad file) is reported by main()


def _leg(args: argparse.Namespace):
    """The bench leg of ``--leg FILE`` (or a repository leg's name), None for the nominal bench."""
    return leg_named(getattr(args, "leg", None))


def cmd_simulate(args: argparse.Namespace) -> int:
    geometry = _leg(args)
    if args.course is not None:
        from device_bridge.bench.controllers import NOMINAL_TASK
        from device_bridge.bench.walks import walk_course

        course = _course(args)
        task = (args.speed if args.speed is not None else NOMINAL_TASK[0],
                args.incline if args.speed is not None else NOMINAL_TASK[1])
        model = load(args) if args.controller != "fsmic" else None
        score = walk_course(args.controller, course, model, args.mass, task=task, video=args.video, geometry=geometry)
        emit(score.to_dict(), args.format)
        return 0
    if args.table is not None:
        return _simulate_table(args)
    if args.skip_limits:
        raise ValueError("--skip-limits applies to a table from a file: add --table FILE.json")
    if args.speed is None:
        raise ValueError("simulate needs --speed (a fixed task), --table FILE.json or --course NAME|FILE")
    if args.controller == "adaptive":
        raise ValueError("the adaptive controller walks a course: add --course NAME|FILE")
    from device_bridge.bench.walks import simulate

    model = load(args) if args.controller == "quasi-stiffness" or args.incline != 0.0 else None
    score = simulate(args.controller, args.speed, args.incline, args.seconds, args.mass, model,
                     record=args.record, video=args.video, geometry=geometry)
    emit(score.to_dict(), args.format)
    return 0


def cmd_stumble(args: argparse.Namespace) -> int:
    """Each controller through each obstacle at each task on the leg (``device_bridge/sim/stumble.py``)."""
    from device_bridge.bench.controllers import make_controller
    from device_bridge.bench.task_reference import task_reference
    from device_bridge.sim.leg_model import LegGeometry
    from device_bridge.sim.stumble import run_stumble

    if len(args.speeds) != len(args.inclines):
        raise ValueError(f"stumble walks paired tasks: give one --inclines value per --speeds value "
                         f"({len(args.speeds)} speeds, {len(args.inclines)} inclines)")
    model, geometry = load(args), _leg(args) or LegGeometry()
    rows = []
    for controller in args.controllers:
        for kind in args.kinds:
            for speed, incline in zip(args.speeds, args.inclines, strict=True):
                ref = task_reference(speed, incline, model, args.mass)
                rows.append({"controller": controller, **run_stumble(
                    lambda c=controller, t=(speed, incline): make_controller(c, args.mass, model, t, geometry=geometry),
                    ref, args.mass, kind, geometry=geometry)})
    for r in rows:
        print(f"{r['controller']:16s} {r['kind']:13s} {r['speed_mps']:.2f} m/s {r['incline_deg']:+.0f}°  falls "
              f"{r['falls']}  recovery steps {len(r['recovery_steps'])}  "
              f"back to clean strides after {r['strides_to_recover']}  "
              + "".join("✓" if c else "✗" for c in r["clean"]))
    if args.out is not None:
        write_json(args.out, rows)
    return 0


def cmd_sensitivity(args: argparse.Namespace) -> int:
    import numpy as np

    from controller_core.refine_sensitivity import BenchSensitivity
    from device_bridge.bench.sensitivity import measure_sensitivity

    body = measure_sensitivity(load(args), args.speeds, args.inclines, args.mass, args.seconds, args.workers)
    grid = BenchSensitivity.from_json(body)
    mean = grid.grid_median()
    unresolved = int(np.isnan(grid.jacobians).sum())
    print(f"sensitivity on the bench: {len(grid.speeds_mps)} × {len(grid.inclines_deg)} tasks, {args.seconds:g} s per "
          f"walk, {unresolved} entries unresolved, {grid.outliers()} set aside as outliers; median over the grid "
          "(quantity unit per deg or per unit ln|value|):")
    short = ("stance knee °", "swing knee °", "swing pk %", "push-off °", "push-off %")
    print("refined value".ljust(38) + "".join(h.rjust(14) for h in short[:len(grid.quantities)]))
    for c, name in enumerate(grid.parameters):
        print(name.ljust(38) + "".join(f"{v:14.2f}" for v in mean[:, c]))
    if args.out is not None:
        write_json(args.out, body)
    return 0


UNCHECKED = "UNCHECKED TABLE, bench study only: limits skipped, never for a device"


def _simulate_table(args: argparse.Namespace) -> int:
    """Walk a table read from a file at its own task (or --speed/--incline), limits checked as on the device unless
    --skip-limits, which says so on every line it prints."""
    from controller_core.table import check_table
    from device_bridge.bench.table_file import read_table_file
    from device_bridge.bench.walks import simulate

    table = read_table_file(args.table)
    task = table.provenance
    speed = args.speed if args.speed is not None else task.speed_mps
    incline = args.incline if args.speed is not None else task.incline_deg
    model = load(args) if incline != 0.0 else None
    score = simulate("table", speed, incline, args.seconds, table.body_mass_kg, model, record=args.record,
                     video=args.video, table=table, skip_limits=args.skip_limits, geometry=_leg(args))
    out = {"table_file": str(args.table), **score.to_dict(), "controller": "table"}
    if args.skip_limits:
        out = {"limits": UNCHECKED, **out, "limit_violations": [v.message for v in check_table(table)]}
        if args.format == "json":
            emit(out, "json")
        else:
            for k, v in out.items():
                print(f"[{UNCHECKED}] {k:40s} {v}")
        return 0
    emit(out, args.format)
    return 0




def add_commands(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("simulate", help="walk one controller on the simulated MuJoCo bench and score it")
    task_args(p, speed_required=False)
    p.add_argument("--course", default=None, help="walk a varying-task course instead of one task: "
                                                  "speed, terrain, mixed, frequent, or a course JSON file")
    p.add_argument("--controller", choices=["quasi-stiffness", "fsmic", "adaptive"], default="quasi-stiffness",
                   help="adaptive (courses only): the envelope blended at the leg's own task estimate; "
                        "quasi-stiffness on a course: the table at --speed/--incline (default 1.2 m/s level)")
    p.add_argument("--seconds", type=float, default=20.0, help="simulated time (s), (0, 600]")
    p.add_argument("--format", choices=["text", "json"], default="text")
    p.add_argument("--record", type=Path, default=None, help="save per-tick trajectories (.csv or .parquet)")
    p.add_argument("--video", type=Path, default=None, help="render headless (MUJOCO_GL=egl): FILE.mp4 or a folder")
    p.add_argument("--table", type=Path, default=None,
                   help="walk the table in FILE.json (the JSON of 'quasitune predict --format json' or of GET "
                        "/api/proposals/{id}) at its own task; its patient mass is the walk's")
    p.add_argument("--skip-limits", action="store_true",
                   help="with --table: walk it even where it breaks the safety limits (bench studies only; every "
                        "line of output says so, and nothing from it reaches a device)")
    p.add_argument("--leg", default=None, help=LEG_HELP)
    p.set_defaults(func=cmd_simulate)
    p = sub.add_parser("sensitivity", help="measure on the bench how the refined table values move the controlled "
                                           "features (the refinement's sensitivity, shipped in controller_core/data)")
    p.add_argument("--speeds", type=float, nargs="+", default=[0.6, 0.85, 1.1, 1.35, 1.6])
    p.add_argument("--inclines", type=float, nargs="+", default=[-10.0, -5.0, 0.0, 5.0, 10.0])
    p.add_argument("--seconds", type=float, default=16.0, help="walking per perturbed table (s)")
    p.add_argument("--mass", type=float, default=75.0)
    p.add_argument("--workers", type=int, default=2, help="walks in parallel")
    p.add_argument("--model", type=Path, default=None)
    p.add_argument("--out", type=Path, default=None, help="write the grid as JSON here")
    p.set_defaults(func=cmd_sensitivity)
    p = sub.add_parser("stumble", help="bench study: a block that catches the toe in mid-swing and a platform the foot "
                                       "lands on early, at paired tasks; falls and strides until clean again")
    p.add_argument("--speeds", type=float, nargs="+", default=[1.2, 1.0])
    p.add_argument("--inclines", type=float, nargs="+", default=[0.0, -6.0], help="one per speed")
    p.add_argument("--kinds", nargs="+", choices=("toe_catch", "early_landing"), default=["toe_catch", "early_landing"])
    p.add_argument("--controllers", nargs="+", choices=("quasi-stiffness", "fsmic"),
                   default=["quasi-stiffness", "fsmic"])
    p.add_argument("--mass", type=float, default=75.0)
    p.add_argument("--model", type=Path, default=None)
    p.add_argument("--leg", default=None, help=LEG_HELP)
    p.add_argument("--out", type=Path, default=None, help="write the rows as JSON here")
    p.set_defaults(func=cmd_stumble)
