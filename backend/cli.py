"""The ``quasitune`` command line.

Commands: ``serve``, ``bridge``, ``device``, ``users``, ``predict``, ``plot``, ``train``, ``evaluate``, ``bench``,
``bench-api``, ``simulate``, ``compare``. Bad input exits with code 2 and a one-line reason on stderr.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from backend.store.users import ROLES
from controller_core import InvalidTaskError, QuasiStiffnessModel, load_default_model, load_model
from controller_core.gait_metrics import GAIT_CHANNELS, difference_keys
from controller_core.table import SafetyLimitError


def _model(args: argparse.Namespace) -> QuasiStiffnessModel:
    return load_model(args.model) if args.model else load_default_model()


def _task_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--speed", type=float, required=True, help="walking speed (m/s), (0, 3]")
    p.add_argument("--incline", type=float, default=0.0, help="incline (deg, + uphill), within ±20")
    p.add_argument("--mass", type=float, default=75.0, help="patient body mass (kg), 20-200")
    p.add_argument("--model", type=Path, default=None, help="model directory from 'quasitune train'")


def _print_readable(d: dict) -> None:
    t = d["task"]
    print(f"Task: {t['speed_mps']:.2f} m/s, incline {t['incline_deg']:+.1f} deg, patient {t['mass_kg']:.1f} kg")
    print(f"Model: {d['model']['version']}  data sha256 {d['model']['data_sha256'][:16]}…")
    if d["extrapolation"]:
        print("WARNING: task outside the training data for some features (extrapolation); see std.")
    print("\nPredicted features (GPR, mean ± 1 SD)")
    print(f"  {'feature':34s} {'phase %':>9s} {'value':>16s}  unit")
    for f in d["features"]:
        flag = "  (extrapolated)" if f["extrapolation"] else ""
        print(f"  {f['name']:34s} {100 * f['phase']:5.1f}±{100 * f['phase_std']:<3.1f}"
              f" {f['value']:8.3f} ± {f['std']:<6.3f} {f['unit']}{flag}")
    print("\nParameter table (τ = k(θ − θe) − bθ̇; k < 0 is restoring)")
    print(f"  {'joint':6s} {'sub-phase':17s} {'k N·m/rad':>10s} {'k N·m/deg':>10s} {'θe deg':>8s} "
          f"{'b N·m·s/rad':>11s} {'R²':>6s}")
    for r in d["table"]:
        g = f" {r['fit_method'].replace('_', ' ')}" if r["guarded"] else ""
        print(f"  {r['joint']:6s} {r['subphase']:17s} {r['k_Nm_per_rad']:10.1f} {r['k_Nm_per_deg']:10.3f} "
              f"{r['theta_e_deg']:8.2f} {r['b_Nm_s_per_rad']:11.2f} {r['r2']:6.2f}{g}")
    if any(r["fit_method"] == "swing_target" for r in d["table"]):
        print("  swing target: not a fit; θe is the predicted swing target, k the model's swing stiffness")
    th = d["thresholds"]
    print("\nState-machine thresholds")
    for k, v in th.items():
        print(f"  {k:28s} {v:9.2f}")
    s = d["safety"]
    print("\nSafety limits: " + ("all within limits" if s["ok"] else "VIOLATIONS:"))
    for v in s["violations"]:
        print(f"  - {v['message']}")


def cmd_predict(args: argparse.Namespace) -> int:
    d = _model(args).propose(speed_mps=args.speed, incline_deg=args.incline, mass_kg=args.mass).to_dict()
    if args.format == "json":
        print(json.dumps(d, allow_nan=False))
    else:
        _print_readable(d)
    return 0


def cmd_plot(args: argparse.Namespace) -> int:
    from controller_core.plotting import plot_proposal

    model = _model(args)
    proposal = model.propose(speed_mps=args.speed, incline_deg=args.incline, mass_kg=args.mass)
    out = plot_proposal(model, proposal, args.out)
    print(f"wrote {out}")
    return 0


def cmd_train(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from controller_core.features import FEATURES
    from controller_core.model_io import save_model, train_default, train_from_file

    steps = len(FEATURES) + 2
    with tqdm(total=steps, desc="training", unit="part", file=sys.stderr) as bar:
        def tick(name: str) -> None:
            bar.set_postfix_str(name)
            bar.update(1)
        if args.data is None:
            model = train_default(progress=tick)
        else:
            model = train_from_file(args.data, use_published=args.with_published, progress=tick)
    out = save_model(model, args.out)
    print(f"model {model.model_version_} ({len(model.reference_.records)} conditions) saved to {out}")
    return 0


def _emit(d: dict, fmt: str) -> None:
    """Print a flat result as one JSON object or as aligned ``key value`` lines."""
    if fmt == "json":
        print(json.dumps(d))
    else:
        for k, v in d.items():
            print(f"{k:40s} {v}")


def cmd_evaluate(args: argparse.Namespace) -> int:
    from controller_core.evaluation import evaluate, format_report

    report = evaluate()
    print(format_report(report))
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(json.dumps(report, indent=2))
        print(f"\nwrote {args.out}")
    return 0


def cmd_bench(args: argparse.Namespace) -> int:
    from controller_core.bench import run_bench

    result = run_bench(repeats=args.repeats)
    _emit(result, args.format)
    return 0


def cmd_simulate(args: argparse.Namespace) -> int:
    from device_bridge.sim.experiments import simulate

    model = _model(args) if args.controller == "quasi-stiffness" or args.incline != 0.0 else None
    score = simulate(args.controller, args.speed, args.incline, args.seconds, args.mass, model,
                     record=args.record, video=args.video)
    _emit(score.to_dict(), args.format)
    return 0


def _fmt(v: object) -> str:
    return "—" if v is None else f"{v:.2f}" if isinstance(v, float) else str(v)


def format_compare(rows: list[dict]) -> str:
    """Markdown table of a comparison (one row per task and controller)."""
    cols = ["speed_mps", "incline_deg", "controller", "strides", "falls", "toe_catches", "knee_angle_rmse_deg",
            "ankle_angle_rmse_deg", "knee_moment_rmse_Nm_per_kg", "ankle_moment_rmse_Nm_per_kg", "real_time_factor"]
    lines = ["| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    lines += ["| " + " | ".join(_fmt(r.get(c)) for c in cols) + " |" for r in rows]
    verdicts = [r for r in rows if r.get("vs_fsmic")]
    if verdicts:
        keys = [difference_keys(channel) for channel in GAIT_CHANNELS]
        lines += ["", "learned − FSMIC RMSE, 95 % interval over strides (bootstrap), verdict:", "",
                  "| speed_mps | incline_deg | " + " | ".join(k for k, _, _ in keys) + " |",
                  "|" + "---|" * (2 + len(keys))]
        for r in verdicts:
            v = r["vs_fsmic"]
            cells = []
            for key, ci_key, verdict_key in keys:
                d, ci = v.get(key), v.get(ci_key)
                cells.append("—" if d is None else f"{d:+.2f} [{ci[0]:+.2f}, {ci[1]:+.2f}] {v[verdict_key]}")
            lines.append(f"| {_fmt(r.get('speed_mps'))} | {_fmt(r.get('incline_deg'))} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def cmd_compare(args: argparse.Namespace) -> int:
    from device_bridge.sim.experiments import compare, plot_compare

    results = compare(_model(args), tuple(args.speeds), tuple(args.inclines), args.seconds, args.mass)
    rows = [score.to_dict() for score, _ in results]
    print(format_compare(rows))
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(json.dumps(rows, indent=2))
        print(f"\nwrote {args.out}")
    if args.plot:
        args.plot.parent.mkdir(parents=True, exist_ok=True)
        plot_compare(results, args.plot)
        print(f"wrote {args.plot}")
    return 0


def _settings(args: argparse.Namespace):
    from backend.settings import Settings, default_data_dir

    return Settings(data_dir=args.data_dir or default_data_dir(), model_dir=getattr(args, "model", None))


def _port(text: str) -> int:
    try:
        port = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"port must be a whole number 0-65535, got {text!r}") from None
    if not 0 <= port <= 65535:
        raise argparse.ArgumentTypeError(f"port must be 0-65535 (0 = any free port), got {port}")
    return port


def cmd_serve(args: argparse.Namespace) -> int:
    import dataclasses
    import os

    from backend.devices import parse_device_spec
    from backend.serve import serve

    device = args.device or os.environ.get("QUASITUNE_DEVICE") or "sim"
    parse_device_spec(device)   # refuse a bad spec before anything starts
    if args.workers > 1 and device != "none":
        raise ValueError("a device link lives in one server process: use --workers 1 with a device, "
                         "or --device none for a multi-process API server")
    return serve(dataclasses.replace(_settings(args), device=device), host=args.host, port=args.port,
                 bootstrap=not args.no_bootstrap_user, workers=args.workers)


def _read_password() -> str:
    import getpass

    if sys.stdin.isatty():
        first = getpass.getpass("password: ")
        if getpass.getpass("again: ") != first:
            raise ValueError("the two passwords differ")
        return first
    return sys.stdin.readline().rstrip("\r\n")


def cmd_users_add(args: argparse.Namespace) -> int:
    from pydantic import ValidationError

    from backend.db import connect
    from backend.errors import ConflictError
    from backend.migrate import migrate
    from backend.schemas.auth import UserCreate
    from backend.store.users import create_user

    settings = _settings(args)
    try:
        body = UserCreate(username=args.name, role=args.role, password=_read_password())
    except ValidationError as exc:
        err = exc.errors()[0]
        raise ValueError(f"{'.'.join(map(str, err['loc']))}: {err['msg']}") from None
    settings.data_dir.mkdir(parents=True, exist_ok=True)
    migrate(settings.db_path)
    conn = connect(settings.db_path)
    try:
        user = create_user(conn, body.username, body.role, body.password)
    except ConflictError as exc:
        raise ValueError(exc.message) from None
    finally:
        conn.close()
    print(f"user {user['username']} ({user['role']}) added to {settings.db_path}")
    return 0


def cmd_users_list(args: argparse.Namespace) -> int:
    from backend.db import connect
    from backend.migrate import migrate
    from backend.store.users import list_users

    settings = _settings(args)
    settings.data_dir.mkdir(parents=True, exist_ok=True)
    migrate(settings.db_path)
    conn = connect(settings.db_path)
    try:
        for u in list_users(conn):
            print(f"{u['id']:4d}  {u['username']:24s} {u['role']:12s} {'disabled' if u['disabled'] else ''}")
    finally:
        conn.close()
    return 0


def cmd_bench_api(args: argparse.Namespace) -> int:
    from backend.loadbench import run_load_bench

    _emit(run_load_bench(clients=args.clients, seconds=args.seconds, workers=args.workers), args.format)
    return 0


def cmd_device_soak(args: argparse.Namespace) -> int:
    from device_bridge.soak import soak

    out = soak(args.trials, args.drop, args.corrupt, args.reorder, seed=args.seed)
    if args.format == "json":
        print(json.dumps(out))
    else:
        print(f"{out['trials']} pushes through a bus with drop {args.drop:g}, corrupt {args.corrupt:g}, "
              f"reorder {args.reorder:g}")
        for key in ("committed", "kept_old", "committed_unconfirmed", "mixed", "crc_mismatch"):
            print(f"  {key:22s} {out[key]}")
        print(f"  push median {out['median_push_ms']:.2f} ms, p99 {out['p99_push_ms']:.2f} ms")
    return 0 if out["mixed"] == 0 and out["crc_mismatch"] == 0 else 1


def cmd_device_drill(args: argparse.Namespace) -> int:
    from device_bridge.soak import heartbeat_drill

    print(json.dumps(heartbeat_drill(args.repeats, args.timeout_ms / 1000.0)))
    return 0


def cmd_bench_device(args: argparse.Namespace) -> int:
    from backend.devicebench import run_device_bench

    print(json.dumps(run_device_bench(args.seconds, args.pushes)))
    return 0


def cmd_bench_ui(args: argparse.Namespace) -> int:
    try:
        from backend.uibench import run_ui_bench
    except ImportError as exc:   # playwright is a dev dependency
        print(f"quasitune: bench-ui needs the dev dependencies (bash scripts/test.sh installs them): {exc}",
              file=sys.stderr)
        return 2
    print(json.dumps(run_ui_bench(args.repeats, args.monitor_seconds)))
    return 0


def cmd_bridge(args: argparse.Namespace) -> int:
    from device_bridge.buses import open_bus
    from device_bridge.gateway import Gateway

    gateway = Gateway(open_bus(args.can), open_bus(args.to)).start()
    print(f"QuasiTune bridge: {args.can} <-> {args.to}", flush=True)
    try:
        gateway.wait()
    except KeyboardInterrupt:
        pass
    finally:
        gateway.close()
    return 0


def _probability(text: str) -> float:
    value = float(text)
    if not 0.0 <= value < 1.0:
        raise argparse.ArgumentTypeError(f"must be a probability in [0, 1), got {text}")
    return value


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="quasitune", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    data_dir_help = "data directory holding quasitune.sqlite (default: $QUASITUNE_DATA_DIR or ~/.local/share/quasitune)"
    p = sub.add_parser("serve", help="run the API server (loopback by default)")
    p.add_argument("--host", default="127.0.0.1", help="address to bind (default loopback only)")
    p.add_argument("--port", type=_port, default=8000, help="port (0 = any free port; the real one is printed)")
    p.add_argument("--data-dir", type=Path, default=None, help=data_dir_help)
    p.add_argument("--model", type=Path, default=None, help="model directory from 'quasitune train'")
    p.add_argument("--workers", type=int, default=1, choices=range(1, 33), metavar="N",
                   help="server processes (1-32; default 1)")
    p.add_argument("--no-bootstrap-user", action="store_true",
                   help="do not create the first user on an empty database")
    p.add_argument("--device", default=None,
                   help="'sim' (default: the simulated leg on an in-process virtual CAN bus), 'none', or "
                        "INTERFACE:CHANNEL for a real leg on a python-can bus (e.g. socketcan:can0); "
                        "default $QUASITUNE_DEVICE or sim")
    p.set_defaults(func=cmd_serve)
    p = sub.add_parser("device", help="device-link tools: soak test, heartbeat drill")
    device_sub = p.add_subparsers(dest="device_command", required=True)
    p = device_sub.add_parser("soak", help="push tables through a fault-injecting virtual bus and count outcomes")
    p.add_argument("--trials", type=int, default=500)
    p.add_argument("--drop", type=_probability, default=0.1, help="probability a frame is lost")
    p.add_argument("--corrupt", type=_probability, default=0.02, help="probability a frame gets one bit flipped")
    p.add_argument("--reorder", type=_probability, default=0.05, help="probability a frame swaps with the next")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--format", choices=["text", "json"], default="text")
    p.set_defaults(func=cmd_device_soak)
    p = device_sub.add_parser("drill", help="stop the host heartbeat and time the device's safe mode")
    p.add_argument("--repeats", type=int, default=5)
    p.add_argument("--timeout-ms", type=float, default=200.0, help="the device's heartbeat timeout (ms)")
    p.set_defaults(func=cmd_device_drill)
    p = sub.add_parser("bridge", help="forward frames between the leg's CAN bus and the API server's bus")
    p.add_argument("--can", required=True, help="the leg's bus, INTERFACE:CHANNEL (e.g. socketcan:can0)")
    p.add_argument("--to", default="udp_multicast:239.74.163.2",
                   help="the bus 'quasitune serve --device' uses (default udp_multicast:239.74.163.2)")
    p.set_defaults(func=cmd_bridge)
    p = sub.add_parser("users", help="manage users")
    users_sub = p.add_subparsers(dest="users_command", required=True)
    p = users_sub.add_parser("add", help="add a user (password from a prompt, or one line of stdin)")
    p.add_argument("name")
    p.add_argument("--role", required=True, choices=ROLES)
    p.add_argument("--data-dir", type=Path, default=None, help=data_dir_help)
    p.set_defaults(func=cmd_users_add)
    p = users_sub.add_parser("list", help="list users")
    p.add_argument("--data-dir", type=Path, default=None, help=data_dir_help)
    p.set_defaults(func=cmd_users_list)
    p = sub.add_parser("predict", help="propose curves and a parameter table for a task")
    _task_args(p)
    p.add_argument("--format", choices=["text", "json"], default="text")
    p.set_defaults(func=cmd_predict)
    p = sub.add_parser("plot", help="torque-angle loops with KMP bands, via-points and regression lines")
    _task_args(p)
    p.add_argument("--out", type=Path, required=True, help="output image (.png, .pdf, .svg)")
    p.set_defaults(func=cmd_plot)
    p = sub.add_parser("train", help="fit a model from a standard-format dataset (CSV/Parquet)")
    p.add_argument("--data", type=Path, default=None, help="dataset file; default: the shipped data")
    p.add_argument("--out", type=Path, required=True, help="model directory to write")
    p.add_argument("--with-published", action="store_true",
                   help="also train on the shipped published incline features")
    p.set_defaults(func=cmd_train)
    p = sub.add_parser("evaluate", help="leave-one-condition-out evaluation against baselines")
    p.add_argument("--out", type=Path, default=None, help="also write the report as JSON here")
    p.set_defaults(func=cmd_evaluate)
    p = sub.add_parser("bench", help="fit time and propose()/KMP timings")
    p.add_argument("--repeats", type=int, default=2000)
    p.add_argument("--format", choices=["text", "json"], default="text")
    p.set_defaults(func=cmd_bench)
    p = sub.add_parser("bench-api", help="load benchmark: POST proposals with concurrent clients on loopback")
    p.add_argument("--clients", type=int, default=20)
    p.add_argument("--seconds", type=float, default=10.0, help="measured duration (s) after a warm-up")
    p.add_argument("--workers", type=int, default=1, help="server processes")
    p.add_argument("--format", choices=["text", "json"], default="text")
    p.set_defaults(func=cmd_bench_api)
    p = sub.add_parser("bench-device", help="device loop through a real server: API push latency, telemetry rate")
    p.add_argument("--seconds", type=float, default=10.0, help="telemetry measured for this long (s)")
    p.add_argument("--pushes", type=int, default=50, help="approved proposals pushed through the API")
    p.set_defaults(func=cmd_bench_device)
    p = sub.add_parser("bench-ui", help="dashboard in Chromium: proposal view time to interactive, live-monitor fps")
    p.add_argument("--repeats", type=int, default=20, help="proposals requested through the page")
    p.add_argument("--monitor-seconds", type=float, default=5.0, help="live monitor measured for this long (s)")
    p.set_defaults(func=cmd_bench_ui)
    p = sub.add_parser("simulate", help="walk one controller on the simulated MuJoCo bench and score it")
    _task_args(p)
    p.add_argument("--controller", choices=["quasi-stiffness", "fsmic"], default="quasi-stiffness")
    p.add_argument("--seconds", type=float, default=20.0, help="simulated time (s), (0, 600]")
    p.add_argument("--format", choices=["text", "json"], default="text")
    p.add_argument("--record", type=Path, default=None, help="save per-tick trajectories (.csv or .parquet)")
    p.add_argument("--video", type=Path, default=None, help="render headless (MUJOCO_GL=egl): FILE.mp4 or a folder")
    p.set_defaults(func=cmd_simulate)
    p = sub.add_parser("compare", help="quasi-stiffness vs FSMIC over a task grid on the simulated bench")
    p.add_argument("--speeds", type=float, nargs="+", default=[0.84, 1.2, 1.49, 1.95])
    p.add_argument("--inclines", type=float, nargs="+", default=[0.0])
    p.add_argument("--seconds", type=float, default=20.0)
    p.add_argument("--mass", type=float, default=75.0)
    p.add_argument("--model", type=Path, default=None)
    p.add_argument("--out", type=Path, default=None, help="write the rows as JSON here")
    p.add_argument("--plot", type=Path, default=None, help="write the trajectory figure here")
    p.set_defaults(func=cmd_compare)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return int(args.func(args))
    except (InvalidTaskError, FileNotFoundError, ValueError, SafetyLimitError) as exc:
        msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        print(f"quasitune: error: {msg}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
