"""A video of the bench, rendered headless."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from device_bridge.sim.video import VideoRecorder


def test_only_an_mp4_or_a_folder_is_accepted(tmp_path):
    with pytest.raises(ValueError, match=r"FILE\.mp4 or a folder"):
        VideoRecorder(tmp_path / "walk.gif")
    assert VideoRecorder(tmp_path / "frames").every == round(1000 / 30)


_RENDER = """
import sys
from pathlib import Path
from controller_core.walking_reference import level_walking_reference
from device_bridge.sim.bench_trajectory import plan_bench_trajectory
from device_bridge.sim.plant import SimulatedLeg
from device_bridge.sim.video import VideoRecorder

leg = SimulatedLeg()
leg.reset(plan_bench_trajectory(level_walking_reference(1.2), leg.geometry, 75.0, 0.2, leg.timestep_s), 0.2, 0.0)
video = VideoRecorder(Path(sys.argv[1]), width=64, height=48)
for _ in range(3):
    video(leg)
    leg.step(0.0, 0.0)
video.close()
"""


def test_frames_of_the_bench_are_rendered_headless_as_pngs(tmp_path):
    # MuJoCo picks its GL back end when it is first imported: render in a process of its own with EGL
    env = {**os.environ, "MUJOCO_GL": "egl", "PYOPENGL_PLATFORM": "egl"}
    done = subprocess.run([sys.executable, "-c", _RENDER, str(tmp_path / "frames")], env=env, capture_output=True,
                          text=True, timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]
    frames = sorted((tmp_path / "frames").iterdir())
    assert [p.name for p in frames] == [f"frame_0000{i}.png" for i in range(3)]
    assert all(p.stat().st_size > 100 for p in frames)
