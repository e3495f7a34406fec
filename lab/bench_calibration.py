"""The bench's calibration over a task grid (``quasitune calibrate``): the reference's own joint angles walked on the
bench, and how far the body then strays from where people's is (:mod:`device_bridge.sim.calibration`)."""

from __future__ import annotations

from device_bridge.bench.task_reference import task_reference
from device_bridge.sim.calibration import (
    DEFICIT_MEAN_TOLERANCE_BW,
    DEFICIT_TOLERANCE_BW,
    HIP_TOLERANCE_MM,
    calibration_walk,
)

GRID_SPEEDS_MPS: tuple[float, ...] = (0.84, 1.2, 1.49, 1.95)
GRID_INCLINES_DEG: tuple[float, ...] = (0.0, 5.0)


def calibrate(speeds_mps: tuple[float, ...] = GRID_SPEEDS_MPS, inclines_deg: tuple[float, ...] = GRID_INCLINES_DEG,
              mass_kg: float = 75.0, seconds: float = 8.0) -> list[dict[str, object]]:
    """One calibration walk per task of the grid, each with ``within`` (all three tolerances hold)."""
    rows = []
    for incline in inclines_deg:
        for speed in speeds_mps:
            r = calibration_walk(task_reference(speed, incline, None, mass_kg), mass_kg, seconds)
            r["within"] = (r["hip_error_stance_min_mm"] >= -HIP_TOLERANCE_MM
                           and r["hip_error_stance_max_mm"] <= HIP_TOLERANCE_MM
                           and r["support_deficit_max_bw"] <= DEFICIT_TOLERANCE_BW
                           and r["support_deficit_mean_bw"] <= DEFICIT_MEAN_TOLERANCE_BW)
            rows.append(r)
    return rows


def format_calibration(rows: list[dict[str, object]]) -> str:
    """The grid as a Markdown table, with the tolerances it is held to."""
    out = [f"Reference angles walked on the bench: hip within ±{HIP_TOLERANCE_MM:.0f} mm of its path over the stance; "
           f"the person's push beyond their other leg's share at most {DEFICIT_TOLERANCE_BW:.1f} body weights "
           f"(50 ms mean), {DEFICIT_MEAN_TOLERANCE_BW:.2f} on average over the stance.", "",
           "| speed m/s | incline ° | hip error in stance, mm (lowest, highest) | hip error RMS mm | "
           "push beyond share, largest BW | mean over stance BW | within |", "|---|---|---|---|---|---|---|"]
    for r in rows:
        out.append(f"| {r['speed_mps']:.2f} | {r['incline_deg']:+.0f} | {r['hip_error_stance_min_mm']:+.1f}, "
                   f"{r['hip_error_stance_max_mm']:+.1f} | {r['hip_error_rms_mm']:.1f} | "
                   f"{r['support_deficit_max_bw']:.2f} | {r['support_deficit_mean_bw']:.3f} | "
                   f"{'yes' if r['within'] else 'NO'} |")
    return "\n".join(out)
