"""``python -m benchmarks {model,api,commands,device,envelope,fleet,instances,leg-loop,link,redteam,refine,storage,ui}
[options]``:
one benchmark, its figures as JSON."""

from __future__ import annotations

import argparse
import json
import sys


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks", description=__doc__)
    sub = parser.add_subparsers(dest="name", required=True)
    p = sub.add_parser("model", help="fit time, propose() and KMP timings, one state-machine step")
    p.add_argument("--repeats", type=int, default=2000)
    p = sub.add_parser("api", help="proposals from concurrent clients against one server process, telemetry beside")
    p.add_argument("--clients", type=int, default=20)
    p.add_argument("--seconds", type=float, default=10.0, help="measured duration (s) after a warm-up")
    p = sub.add_parser("commands", help="safe mode and the device list while ten bench walks are queued (target: "
                                        "safe mode ≤ 200 ms)")
    p.add_argument("--seconds", type=float, default=15.0, help="commands timed this long, idle and busy (s)")
    sub.add_parser("redteam", help="issue 52's broker attacks end to end with a stolen leg identity: takeovers, "
                                   "impossible times, huge messages, floods; what leg 1 and its session saw")
    p = sub.add_parser("device", help="push latency through the API and telemetry rate with the simulated leg")
    p.add_argument("--seconds", type=float, default=10.0, help="telemetry measured for this long (s)")
    p.add_argument("--pushes", type=int, default=50, help="approved proposals pushed through the API")
    p = sub.add_parser("envelope", help="envelope proposal, per-stride blend, adaptive tick, envelope pushes")
    p.add_argument("--repeats", type=int, default=50, help="envelopes proposed")
    p.add_argument("--pushes", type=int, default=100, help="envelope pushes over a clean virtual bus")
    p.add_argument("--trials", type=int, default=500, help="envelope pushes through a faulty bus")
    p = sub.add_parser("refine", help="a 5 × 5 envelope refined from 120 s of recorded strides (target ≤ 2 s)")
    p.add_argument("--repeats", type=int, default=10)
    p.add_argument("--seconds", type=float, default=120.0, help="walking recorded once, before the timing (s)")
    p = sub.add_parser("instances", help="one and two API instances on PostgreSQL against one on SQLite, then SIGKILLs")
    p.add_argument("--clients", type=int, default=20)
    p.add_argument("--seconds", type=float, default=20.0, help="measured per configuration (s)")
    p.add_argument("--kill-seconds", type=float, default=60.0, help="the run with two SIGKILLs (s)")
    p = sub.add_parser("link", help="the leg's link through a broker over TLS: pushes, a soak with broker restarts, "
                                    "a link loss mid-session in both lost-link modes")
    p.add_argument("--pushes", type=int, default=100, help="pushes of each kind (25-node envelope, table)")
    p.add_argument("--trials", type=int, default=500, help="soak pushes with bus faults and broker restarts")
    p.add_argument("--restart-every", type=int, default=50, help="the broker is restarted every this many trials")
    p.add_argument("--cut-seconds", type=float, default=60.0, help="the link loss in the middle of a session (s)")
    p = sub.add_parser("fleet", help="many legs' replayed telemetry through one broker to two API instances, with live "
                                     "monitors: latency, gaps, heartbeats at the legs, CPU")
    p.add_argument("--legs", type=int, default=50)
    p.add_argument("--monitors", type=int, default=20, help="live monitors (WebSockets), one leg each")
    p.add_argument("--seconds", type=float, default=30.0, help="measured for this long (s) after a warm-up")
    p.add_argument("--replayers", type=int, default=2, help="processes publishing the legs' telemetry")
    p.add_argument("--recording", type=int, default=10, help="legs recording a session each")
    p.add_argument("--window-ms", type=float, default=None,
                   help="the bridge's telemetry window (default the bridge's own; 0: a message per sample)")
    p = sub.add_parser("storage", help="bytes and read-back time of an hour of telemetry on SQLite and PostgreSQL")
    p.add_argument("--record-seconds", type=float, default=60.0, help="walking recorded by a real server (s)")
    p.add_argument("--hours", type=float, default=1.0, help="walking hours written from that recording")
    p = sub.add_parser("leg-loop", help="the leg's control loop at its rate: tick lateness, overruns (run it in the "
                                        "leg's environment, .venv-leg)")
    p.add_argument("--rate", type=float, default=500.0, help="Hz")
    p.add_argument("--seconds", type=float, default=20.0)
    p = sub.add_parser("ui", help="dashboard in Chromium: proposal view time to interactive, live-monitor fps")
    p.add_argument("--repeats", type=int, default=20, help="proposals requested through the page")
    p.add_argument("--monitor-seconds", type=float, default=5.0, help="live monitor measured for this long (s)")
    args = parser.parse_args(argv)
    if args.name == "model":
        from benchmarks.model import run

        result = run(args.repeats)
    elif args.name == "api":
        from benchmarks.api import run

        result = run(args.clients, args.seconds)
    elif args.name == "instances":
        from benchmarks.instances import run

        result = run(args.clients, args.seconds, args.kill_seconds)
    elif args.name == "link":
        from benchmarks.link import run

        result = run(args.pushes, args.trials, args.restart_every, args.cut_seconds)
    elif args.name == "fleet":
        from benchmarks.fleet import run

        result = run(args.legs, args.monitors, args.seconds, args.replayers,
                     None if args.window_ms is None else args.window_ms / 1e3, args.recording)
    elif args.name == "storage":
        from benchmarks.storage import run

        result = run(args.record_seconds, args.hours)
    elif args.name == "refine":
        from benchmarks.refine import run

        result = run(args.repeats, args.seconds)
    elif args.name == "envelope":
        from benchmarks.envelope import run

        result = run(args.repeats, args.pushes, args.trials)
    elif args.name == "commands":
        from benchmarks.commands import run

        result = run(args.seconds)
    elif args.name == "redteam":
        from benchmarks.redteam import run

        result = run()
    elif args.name == "leg-loop":
        from benchmarks.leg_loop import run

        result = run(args.rate, args.seconds)
    elif args.name == "device":
        from benchmarks.device import run

        result = run(args.seconds, args.pushes)
    else:
        from benchmarks.ui import run

        result = run(args.repeats, args.monitor_seconds)
    print(json.dumps(result, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
