"""The lab's commands on the ``quasitune`` command line: bench studies and the model's evaluation, which the product
does not need (``compare``, ``refine``, ``calibrate``, ``stance-response``, ``plot``, ``evaluate``).

They reach ``quasitune`` through the ``quasitune.commands`` entry point (``pyproject.toml``) rather than an import from
the product: the product's code imports nothing from the lab, and the same commands keep their names.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from device_bridge.bench.command_line import LEG_HELP, leg_named, model_named, write_json


def load(args: argparse.Namespace):
    """The model named by ``--model``, or the default one."""
    return model_named(args.model)


def _leg(args: argparse.Namespace):
    """The bench leg of ``--leg FILE`` (or a repository leg's name), None for the nominal bench."""
    return leg_named(getattr(args, "leg", None))


def _course(args: argparse.Namespace):
    from device_bridge.sim.course import load_course

    return load_course(args.course)   # ValueError (unknown name, bad file) is reported by quasitune's main()


def cmd_plot(args: argparse.Namespace) -> int:
    from lab.plotting import plot_proposal

    model = load(args)
    proposal = model.propose(speed_mps=args.speed, incline_deg=args.incline, mass_kg=args.mass)
    print(f"wrote {plot_proposal(model, proposal, args.out)}")
    return 0


def cmd_evaluate(args: argparse.Namespace) -> int:
    from lab.evaluation import evaluate, format_incline_report, format_report
    from lab.um21_envelopes import format_um21_report

    report = evaluate()
    print(format_report(report))
    print()
    print(format_incline_report(report["incline"]))
    print()
    print(format_um21_report(report["um21_envelopes"]))
    if args.out:
        write_json(args.out, report)
    return 0


def cmd_compare(args: argparse.Namespace) -> int:
    if args.course is not None:
        from lab.course_compare import compare_course, format_course_compare

        result = compare_course(load(args), _course(args), args.mass, geometry=_leg(args), start=args.start)
        print(format_course_compare(result))
        if args.out:
            write_json(args.out, result)
        return 0
    from lab.comparison import compare, format_compare, plot_compare

    results = compare(load(args), tuple(args.speeds), tuple(args.inclines), args.seconds, args.mass, _leg(args),
                      start=args.start)
    rows = [score.to_dict() for score, _ in results]
    print(format_compare(rows))
    if args.out:
        write_json(args.out, rows)
    if args.plot:
        args.plot.parent.mkdir(parents=True, exist_ok=True)
        plot_compare(results, args.plot)
        print(f"wrote {args.plot}")
    return 0


def cmd_calibrate(args: argparse.Namespace) -> int:
    from lab.bench_calibration import calibrate, format_calibration

    rows = calibrate(tuple(args.speeds), tuple(args.inclines), args.mass, args.seconds)
    print(format_calibration(rows))
    if args.out is not None:
        write_json(args.out, rows)
    return 0


def cmd_stance_response(args: argparse.Namespace) -> int:
    from device_bridge.bench.stance_response import stance_response
    from lab.stance_response import format_stance_response

    rows = stance_response(load(args), args.mass, args.seconds)
    print(format_stance_response(rows))
    if args.out is not None:
        write_json(args.out, rows)
    return 0


def cmd_refine(args: argparse.Namespace) -> int:
    from controller_core.refine_search import TrustRegionSearch
    from device_bridge.bench.refine_walks import refine_on_bench
    from device_bridge.sim.course import load_course
    from device_bridge.sim.leg_model import LegGeometry
    from lab.refine_report import format_refine

    if not (0.0 < args.seconds_per_round <= 600.0):
        raise ValueError(f"--seconds-per-round must be in (0, 600] s, got {args.seconds_per_round!r}")
    result = refine_on_bench(load(args), _leg(args) or LegGeometry(), load_course(args.train_course),
                             load_course(args.eval_course), args.rounds, args.seconds_per_round, args.mass,
                             settled=load_course(args.settled_course),
                             search=TrustRegionSearch(max_walks=args.search_walks) if args.search_walks else None)
    print(format_refine(result))
    if args.out is not None:
        write_json(args.out, result)
    return 0


def add_commands(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("plot", help="torque-angle loops with KMP bands, via-points and regression lines")
    p.add_argument("--speed", type=float, required=True, help="walking speed (m/s), [0.1, 3]")
    p.add_argument("--incline", type=float, default=0.0, help="incline (deg, + uphill), within ±20")
    p.add_argument("--mass", type=float, default=75.0, help="patient body mass (kg), 20-200")
    p.add_argument("--model", type=Path, default=None, help="model directory from 'quasitune train'")
    p.add_argument("--out", type=Path, required=True, help="output image (.png, .pdf, .svg)")
    p.set_defaults(func=cmd_plot)
    p = sub.add_parser("evaluate", help="leave-one-condition-out evaluation against baselines")
    p.add_argument("--out", type=Path, default=None, help="also write the report as JSON here")
    p.set_defaults(func=cmd_evaluate)
    p = sub.add_parser("compare", help="quasi-stiffness vs FSMIC over a task grid on the simulated bench")
    p.add_argument("--course", default=None, help="compare the adaptive envelope, the nominal table and the FSMIC "
                                                  "over a course (speed, terrain, mixed, frequent or a JSON file)")
    p.add_argument("--speeds", type=float, nargs="+", default=[0.84, 1.2, 1.49, 1.95])
    p.add_argument("--inclines", type=float, nargs="+", default=[0.0])
    p.add_argument("--seconds", type=float, default=20.0)
    p.add_argument("--mass", type=float, default=75.0)
    p.add_argument("--model", type=Path, default=None)
    p.add_argument("--out", type=Path, default=None, help="write the rows as JSON here")
    p.add_argument("--plot", type=Path, default=None, help="write the trajectory figure here")
    p.add_argument("--leg", default=None, help=LEG_HELP)
    p.add_argument("--start", choices=("standing", "level", "swing"), default="standing",
                   help="each walk starts from a second of quiet standing through gait initiation (standing), the "
                        "same and then 6 s of level walking that changes to the task (level: strides scored after "
                        "the change), or in late swing at belt speed (swing: the bench's first start); a course "
                        "takes standing or swing")
    p.set_defaults(func=cmd_compare)
    p = sub.add_parser("refine", help="the refinement loop on the bench: a leg walks a course with the envelope, the "
                                      "envelope is refined from its strides, repeated; then an evaluation course with "
                                      "the original envelope, the refined one and the FSMIC")
    p.add_argument("--leg", default=None, help=LEG_HELP)
    p.add_argument("--train-course", default="mixed", help="course walked each round (name or JSON file)")
    p.add_argument("--eval-course", default="terrain", help="course of the evaluation, not used for training")
    p.add_argument("--settled-course", default="settled",
                   help="tasks where bias and spread are judged (each segment walked alone at its task)")
    p.add_argument("--search-walks", type=int, default=0,
                   help="search each node's rows on the bench in up to this many walks (a study, 2-50); 0: one "
                        "step through the shipped sensitivity, checked on the bench")
    p.add_argument("--rounds", type=int, default=2, help="refinement rounds, 1-10")
    p.add_argument("--seconds-per-round", type=float, default=120.0, help="walking per round (s), (0, 600]")
    p.add_argument("--mass", type=float, default=75.0)
    p.add_argument("--model", type=Path, default=None)
    p.add_argument("--out", type=Path, default=None, help="write the JSON here")
    p.set_defaults(func=cmd_refine)
    p = sub.add_parser("stance-response", help="bench study: how far the loaded knee answers its stance-flexion "
                                               "stiffness (learned table and FSMIC), under the bench's person and "
                                               "weaker ones")
    p.add_argument("--seconds", type=float, default=16.0, help="walking per table (s)")
    p.add_argument("--mass", type=float, default=75.0)
    p.add_argument("--model", type=Path, default=None)
    p.add_argument("--out", type=Path, default=None, help="write the rows as JSON here")
    p.set_defaults(func=cmd_stance_response)
    p = sub.add_parser("calibrate", help="walk the reference's own joint angles on the bench over a task grid: how far "
                                         "the body strays from where people's is")
    p.add_argument("--speeds", type=float, nargs="+", default=[0.84, 1.2, 1.49, 1.95])
    p.add_argument("--inclines", type=float, nargs="+", default=[0.0, 5.0])
    p.add_argument("--seconds", type=float, default=8.0)
    p.add_argument("--mass", type=float, default=75.0)
    p.add_argument("--out", type=Path, default=None, help="write the rows as JSON here")
    p.set_defaults(func=cmd_calibrate)
