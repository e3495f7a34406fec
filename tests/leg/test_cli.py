"""`quasitune leg` itself, on the bench's devices (docs/leg.bench.toml): it runs its loop for the time asked and ends
saying what mode the leg is in and why. A dry run has no clinic on its link: no heartbeat, no table."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

from device_bridge.osl.cli import main

BENCH_FILE = Path(__file__).parents[2] / "docs" / "leg.bench.toml"


def test_a_dry_run_on_the_bench_ends_in_safe_mode_and_says_why(tmp_path, capsys):
    leg_file = tmp_path / "leg.toml"                 # the SDK writes its log beside the leg file: not in the repository
    shutil.copyfile(BENCH_FILE, leg_file)
    assert main(["--config", str(leg_file), "--bench-walk", "1.2", "--seconds", "0.5"]) == 0
    out = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert out["ticks"] == 250 and out["rate_hz"] == 500.0
    assert out["mode"] == "SAFE" and {"HEARTBEAT_LOST", "NO_TABLE"} <= set(out["faults"])
