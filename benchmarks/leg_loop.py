"""The leg's control loop at its rate on this machine: the firmware ticking an Open Source Leg over the bench's SDK
objects (the bench's physics inside the tick, as a real leg's bus reads would be), the simulated patient walking;
how late the ticks begin (percentiles), overruns, and the tick's own time. Run in the leg's environment:
``.venv-leg/bin/python -m benchmarks leg-loop`` (scripts/test_leg.sh makes it)."""

from __future__ import annotations

import time

import numpy as np


def run(rate_hz: float, seconds: float) -> dict[str, object]:
    from device_bridge.firmware import DeviceFirmware
    from device_bridge.osl.bench_sdk import BenchLeg
    from device_bridge.osl.config import parse_config
    from device_bridge.osl.leg import OSLLeg
    from device_bridge.osl.loop import ControlLoop

    config = parse_config({"rate_hz": rate_hz, "thigh": "thigh", "knee": {"actuator": "knee", "gear_ratio": 41.5},
                           "ankle": {"actuator": "ankle", "gear_ratio": 41.5}})
    bench = BenchLeg(period_s=config.period_s)
    parts = {"knee": "knee_actuator", "ankle": "ankle_actuator", "loadcell": "loadcell", "thigh": "thigh"}
    devices = {tag: bench.device(tag, part) for tag, part in parts.items()}
    leg = OSLLeg(config, {t: devices[t] for t in ("knee", "ankle")},
                 {t: devices[t] for t in ("loadcell", "thigh")}, clock=time.monotonic, require_calibration=False)
    leg.start()
    bench.walk(1.2)
    fw = DeviceFirmware(now_s=time.monotonic())
    work: list[float] = []

    def tick(now: float) -> None:
        t0 = time.perf_counter()
        fw.last_heartbeat_s_ = now                     # the loop, not the link, is measured
        x = leg.sample()
        knee, ankle, _ = fw.tick(x, now)
        leg.step(knee, ankle)
        work.append(time.perf_counter() - t0)

    loop = ControlLoop(config.period_s, tick, overruns_to_safe=10**6, keep_lateness=True)
    stats = loop.run(max_ticks=round(seconds * rate_hz))
    late = np.array(stats.late_s) * 1e3
    spent = np.array(work) * 1e3
    return {"rate_hz": rate_hz, "seconds": seconds, "ticks": stats.ticks, "overruns": stats.overruns,
            "late_ms": {"p50": round(float(np.percentile(late, 50)), 3), "p99": round(float(np.percentile(late, 99)), 3),
                        "max": round(float(late.max()), 3)},
            "tick_ms": {"p50": round(float(np.percentile(spent, 50)), 3), "p99": round(float(np.percentile(spent, 99)), 3),
                        "max": round(float(spent.max()), 3)},
            "note": "each tick includes the bench's two 1 ms physics steps, which a real leg does not compute"}
