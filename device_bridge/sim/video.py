"""A video of the bench: MuJoCo rendered headless (``MUJOCO_GL=egl``) into an MP4 or a folder of PNG frames."""

from __future__ import annotations

import math
from pathlib import Path


class VideoRecorder:
    """Render the bench headless (``MUJOCO_GL=egl``) at 30 frames/s into an MP4 or a folder of PNGs."""

    fps = 30

    def __init__(self, path: Path, width: int = 640, height: int = 480) -> None:
        self.path = path
        self.width, self.height = width, height
        self.every = round(1000 / self.fps)
        self._renderer = None
        self._writer = None
        self._count = 0
        if path.suffix.lower() not in (".mp4", ".png", ""):
            raise ValueError(f"--video takes FILE.mp4 or a folder for PNG frames, got {path}")

    def __call__(self, leg) -> None:
        import mujoco

        if self._renderer is None:
            self._renderer = mujoco.Renderer(leg.model, self.height, self.width)
            self._camera = mujoco.MjvCamera()
            self._camera.distance, self._camera.elevation, self._camera.azimuth = 2.4, -8.0, 90.0
        self._camera.lookat[:] = (leg.data.qpos[0], 0.0, 0.55 + leg.data.qpos[0] * math.tan(math.radians(leg.incline_deg)))
        self._renderer.update_scene(leg.data, self._camera)
        frame = self._renderer.render()
        import imageio.v2 as imageio

        if self.path.suffix.lower() == ".mp4":
            if self._writer is None:
                self._writer = imageio.get_writer(self.path, fps=self.fps, macro_block_size=1)
            self._writer.append_data(frame)
        else:
            folder = self.path.with_suffix("") if self.path.suffix else self.path
            folder.mkdir(parents=True, exist_ok=True)
            imageio.imwrite(folder / f"frame_{self._count:05d}.png", frame)
        self._count += 1

    def close(self) -> None:
        if self._writer is not None:
            self._writer.close()
        if self._renderer is not None:
            self._renderer.close()
