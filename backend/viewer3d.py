"""The live 3D view of a device's leg, served by viser on loopback and embedded in the dashboard.

One viser server per device, started on first request, bound to 127.0.0.1 on a port the OS assigns (``port=0``)
and read back from viser, so it never collides with another process. A thread redraws the leg at 30 Hz from the
device's latest telemetry sample: knee and ankle angles as measured (flexion and dorsiflexion positive), the foot
coloured by the pylon load, the FSM state and torques as a label. The device measures no hip angle, so the thigh
is drawn upright; the view shows what the prosthesis itself senses.
"""

from __future__ import annotations

import importlib.util
import logging
import math
import threading

from backend.devices import DeviceManager
from controller_core.units import body_weight_N
from device_bridge.sim.leg_model import LegGeometry

log = logging.getLogger(__name__)
FRAME_PERIOD_S = 1.0 / 30.0
STATE_NAMES = ("stance flexion", "stance extension", "swing flexion", "swing extension")


def _about_y(angle_rad: float) -> tuple[float, float, float, float]:
    """Quaternion (w, x, y, z) of a rotation by ``angle_rad`` about +y (x forward, z up: + turns z towards x)."""
    return (math.cos(angle_rad / 2), 0.0, math.sin(angle_rad / 2), 0.0)


def _load_colour(load_N: float, weight_N: float) -> tuple[int, int, int]:
    """Grey when unloaded to orange at body weight."""
    f = min(max(load_N / weight_N, 0.0), 1.0)
    return (int(150 + 100 * f), int(150 - 30 * f), int(150 - 120 * f))


class LegViewer:
    """A viser scene mirroring one device's telemetry (see the module docstring)."""

    def __init__(self, devices: DeviceManager, device_id: str, geometry: LegGeometry | None = None,
                 body_mass_kg: float = 75.0) -> None:
        devices.get(device_id)   # unknown devices are refused before any server starts
        self.devices = devices
        self.device_id = device_id
        self.geometry = geometry or LegGeometry()
        self.weight_N = body_weight_N(body_mass_kg)
        self._server = None
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self.frames_drawn = 0

    @property
    def port(self) -> int:
        """The TCP port viser actually bound (read back from viser)."""
        if self._server is None:
            raise RuntimeError("the viewer is not started")
        return int(self._server.get_port())

    @property
    def host(self) -> str:
        return "127.0.0.1"

    def start(self) -> LegViewer:
        import viser

        g = self.geometry
        server = viser.ViserServer(host=self.host, port=0, label=f"QuasiTune — {self.device_id}", verbose=False)
        scene = server.scene
        scene.set_up_direction("+z")
        scene.add_grid("/floor", width=2.0, height=2.0, cell_size=0.1, section_size=0.5)
        hip_z = g.thigh_m + g.shank_m + g.ankle_height_m
        scene.add_frame("/hip", show_axes=False, position=(0.0, 0.0, hip_z))
        scene.add_box("/hip/thigh", color=(120, 130, 150), dimensions=(0.09, 0.09, g.thigh_m),
                      position=(0.0, 0.0, -g.thigh_m / 2))
        self._knee = scene.add_frame("/hip/knee", show_axes=False, position=(0.0, 0.0, -g.thigh_m))
        scene.add_box("/hip/knee/shank", color=(60, 110, 180), dimensions=(0.06, 0.06, g.shank_m),
                      position=(0.0, 0.0, -g.shank_m / 2))
        self._ankle = scene.add_frame("/hip/knee/ankle", show_axes=False, position=(0.0, 0.0, -g.shank_m))
        foot_len = g.heel_back_m + g.toe_forward_m
        self._foot = scene.add_box("/hip/knee/ankle/foot", color=_load_colour(0.0, self.weight_N),
                                   dimensions=(foot_len, 0.09, 0.04),
                                   position=(g.toe_forward_m - foot_len / 2, 0.0, -g.ankle_height_m + 0.02))
        self._label = scene.add_label("/hip/label", "waiting for telemetry", position=(0.0, 0.0, 0.15))
        server.initial_camera.position = (0.3, -2.2, 0.8)
        server.initial_camera.look_at = (0.0, 0.0, hip_z / 2)
        self._server = server
        self._thread = threading.Thread(target=self._run, name=f"viewer3d-{self.device_id}", daemon=True)
        self._thread.start()
        return self

    def _draw(self) -> None:
        x = self.devices.get(self.device_id).last_sample
        if x is None:
            return
        self._knee.wxyz = _about_y(x.knee_angle_rad)            # flexion swings the shank back
        self._ankle.wxyz = _about_y(-x.ankle_angle_rad)         # dorsiflexion lifts the toe
        self._foot.color = _load_colour(x.load_N, self.weight_N)
        state = STATE_NAMES[x.fsm_state] if x.fsm_state is not None and 0 <= x.fsm_state < 4 else "no FSM state"
        self._label.text = (f"{state} · knee {math.degrees(x.knee_angle_rad):.0f}° {x.knee_torque_Nm:+.0f} N·m · "
                            f"ankle {math.degrees(x.ankle_angle_rad):+.0f}° {x.ankle_torque_Nm:+.0f} N·m · "
                            f"load {x.load_N:.0f} N · {x.mode.name.lower()}")
        self.frames_drawn += 1

    def _run(self) -> None:
        while not self._stop.wait(FRAME_PERIOD_S):
            try:
                self._draw()
            except Exception as exc:   # loud, but a bad frame must not end the view; the next one retries
                if self._stop.is_set():
                    return
                log.warning("3D view of %s: frame not drawn: %r", self.device_id, exc)

    def close(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=1.0)
        if self._server is not None:
            self._server.stop()
            self._server = None


class ViewerRegistry:
    """Lazily started viewers, one per device, closed with the app."""

    def __init__(self, devices: DeviceManager) -> None:
        if importlib.util.find_spec("viser") is None:   # an optional extra: asked for, its absence stops the start
            raise RuntimeError("--viewer3d needs viser, which is not installed: pip install 'quasitune[view3d]' "
                               "(scripts/setup_venv.sh installs it)")
        self.devices = devices
        self._viewers: dict[str, LegViewer] = {}
        self._lock = threading.Lock()

    def get(self, device_id: str) -> LegViewer:
        with self._lock:
            viewer = self._viewers.get(device_id)
            if viewer is None:
                viewer = LegViewer(self.devices, device_id).start()
                self._viewers[device_id] = viewer
            return viewer

    def close(self) -> None:
        with self._lock:
            for viewer in self._viewers.values():
                viewer.close()
            self._viewers.clear()



