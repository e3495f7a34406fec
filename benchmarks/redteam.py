"""The broker red team of issue 52, end to end (``python -m benchmarks redteam``): one API instance serving two
simulated legs, each behind its own bridge, through a real Mosquitto over TLS with the dynamic security plugin (set
up as the tests set it up). Leg 1 runs an approved table, supervised (a lost link puts it in safe mode), recording a
session; the attacker holds leg 2's stolen credentials (and, for one scenario, the admin's API account).

Scenarios, in the issue's order: take over the server's or leg 1's broker session by client id; issue "device"
credentials named like the server or the broker's admin; status records stamped in the future, infinite, not a
number; a late record stamped 1e300; a 10 MB message; 300 late messages of 58 KB. Throughout, leg 1's mode is read
from its firmware every 20 ms and the server's view of both legs every 100 ms. Prints what each scenario did, whether
anything was taken over, how often leg 1 was seen in safe mode or offline, and whether its session lost a sample.
Asserts nothing (the tests assert each item on its own).
"""

from __future__ import annotations

import contextlib
import math
import tempfile
import threading
import time
from pathlib import Path

CHUNK = 58 * 1024


def _stop(c) -> None:
    c.loop_stop()
    c.disconnect()


class _Watch:
    """Leg 1's firmware mode every 20 ms, and the server's view of both legs every 100 ms, on a thread."""

    def __init__(self, api, leg1, legs: tuple[str, str]) -> None:
        self.api, self.leg1, self.legs = api, leg1, legs
        self.safe_seen = 0
        self.offline_seen = {leg: 0 for leg in legs}
        self.offline_at: dict[str, list[float]] = {leg: [] for leg in legs}    # monotonic s of each look offline
        self.looks = 0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def _run(self) -> None:
        from device_bridge.protocol import Mode

        k = 0
        while not self._stop.wait(0.02):
            self.safe_seen += self.leg1.node.snapshot().mode == Mode.SAFE
            k += 1
            if k % 5 == 0:
                for d in self.api.client.get("/api/devices", headers=self.api.as_("viewer")).json():
                    if d["id"] in self.offline_seen and not d["online"]:
                        self.offline_seen[d["id"]] += 1
                        self.offline_at[d["id"]].append(time.monotonic())
                self.looks += 1

    def __enter__(self) -> _Watch:
        self._thread.start()
        return self

    def __exit__(self, *_exc) -> None:
        self._stop.set()
        self._thread.join(5)


def _scenarios(broker, admin, api, leg1, leg2, server_username: str, spans: dict) -> dict:
    import can

    from device_bridge.mqtt_bus import pack_frames, pack_late, topic
    from device_bridge.protocol import encode
    from tests.helpers.mosquitto import connect_as

    thief = leg2.identity
    out: dict[str, dict] = {}
    mark = time.monotonic
    t = mark()
    # 1 session takeover by client id
    taken = {}
    for cid in (server_username, "device-leg-1"):
        accepted, c = connect_as(broker, *thief, cid)
        taken[cid] = accepted
        time.sleep(1.0)
        _stop(c)
    spans["takeover_by_client_id"], t = (t, mark()), mark()
    out["takeover_by_client_id"] = {"accepted": taken,
                                    "server_connected_after": api.client.app.state.broker.connected}
    # 2 credentials named like the server or the admin
    issued = {}
    for name in ("api1", server_username, "quasitune-admin"):
        r = api.client.post(f"/api/devices/{name}/credentials", headers=api.as_("admin"))
        issued[name] = {"status": r.status_code, "username": r.json().get("username")}
    spans["credentials_named_like_others"], t = (t, mark()), mark()
    out["credentials_named_like_others"] = {
        "issued": issued, "server_connected_after": api.client.app.state.broker.connected,
        "admin_still_works": bool(admin.add_device("after-redteam"))}
    # 3-6 the stolen leg's own traffic: records with impossible times, a huge message, a flood of late messages
    accepted, c = connect_as(broker, *thief, thief.username, clean_session=True)
    status = pack_frames([encode("DEVICE_STATUS", {"counter": 1, "mode": 2, "fsm_state": 0, "active_version": 0,
                                                   "active_crc32": 0})])
    now = time.time()
    for at in (now + 2.0, now + 3600.0, math.inf, math.nan, 1e300, -1e300):
        c.publish(topic(leg2.device_id, "late"), pack_late([(at, status)]), qos=1).wait_for_publish(5)
    time.sleep(3.0)
    link2 = api.client.app.state.devices.get(leg2.device_id).link
    spans["impossible_times"], t = (t, mark()), mark()
    out["impossible_times"] = {"sent": 6, "refused": link2.bus.refused_times, "clamped": link2.bus.clamped_times}
    big = c.publish(topic(leg2.device_id, "up"), b"\0" * 10_000_000, qos=1)
    with contextlib.suppress(RuntimeError):      # the broker cuts the sender off (its max_packet_size)
        big.wait_for_publish(5)
    time.sleep(3.0)
    spans["ten_megabytes"], t = (t, mark()), mark()
    out["ten_megabytes"] = {"sender_still_connected": c.is_connected()}
    _stop(c)
    accepted, c = connect_as(broker, *thief, thief.username, clean_session=True)
    record = pack_frames([can.Message(arbitration_id=0x7F0, data=b"\0" * 8, is_extended_id=False)] * 255)
    junk = pack_late([(time.time() - 1.0, record)] * (CHUNK // len(record)))
    t0 = time.monotonic()
    for _ in range(300):
        c.publish(topic(leg2.device_id, "late"), junk, qos=1)
    time.sleep(5.0)
    spans["late_flood_300_x_58_kB"] = (t, mark())
    out["late_flood_300_x_58_kB"] = {"published_in_s": round(time.monotonic() - t0, 2),
                                     "dropped_at_the_server": dict(api.client.app.state.broker.late_dropped)}
    _stop(c)
    return out


def run() -> dict:
    from controller_core import load_default_model
    from tests.helpers.api import approved_proposal, make_api, push_to_leg, wait_for
    from tests.helpers.bridged_leg import bridged_leg
    from tests.helpers.mosquitto import ADMIN, admin_of, running_broker

    model = load_default_model()
    with running_broker() as broker, admin_of(broker) as admin, \
            tempfile.TemporaryDirectory(prefix="quasitune-redteam-") as tmp:
        folder = Path(tmp)
        with bridged_leg(broker, admin, folder, "leg-1") as leg1, bridged_leg(broker, admin, folder, "leg-2") as leg2:
            server = admin.add_server("api1")
            api, client = make_api(folder / "api", lambda: model, device="mqtt:leg-1,mqtt:leg-2",
                                   broker_url=broker.url, broker_username=server.username,
                                   broker_password=server.password, broker_ca_file=broker.ca_file,
                                   instance_name="api1", broker_admin_username=ADMIN,
                                   broker_admin_password=broker.admin_password)
            with client:
                prop = approved_proposal(api)
                r = push_to_leg(api, prop, device="leg-1")
                if r.status_code != 201:
                    raise RuntimeError(f"push refused: {r.text}")
                wait_for(lambda: api.client.get("/api/devices/leg-1", headers=api.as_("viewer")).json(),
                         lambda d: d["mode"] == "active", timeout_s=30.0)
                r = api.client.post(f"/api/patients/{prop['patient_id']}/sessions", headers=api.as_("prosthetist"),
                                    json={"device_id": "leg-1", "speed_mps": 1.2})
                session_id = r.json()["id"]
                time.sleep(1.0)
                with _Watch(api, leg1, ("leg-1", "leg-2")) as watch:
                    spans: dict[str, tuple[float, float]] = {}
                    scenarios = _scenarios(broker, admin, api, leg1, leg2, server.username, spans)
                    time.sleep(1.0)
                r = api.client.post(f"/api/sessions/{session_id}/stop", headers=api.as_("prosthetist"))
                summary = r.json().get("summary", {})
                return {"scenarios": scenarios,
                        "leg_1": {"firmware_looks": watch.looks * 5, "safe_mode_seen": watch.safe_seen,
                                  "server_looks": watch.looks, "offline_seen": watch.offline_seen,
                                  "leg_1_offline_looks_by_scenario": {
                                      name: sum(a <= x <= b for x in watch.offline_at["leg-1"])
                                      for name, (a, b) in spans.items()}},
                        "session_on_leg_1": {"stop_status": r.status_code,
                                             "missing_samples": summary.get("missing_samples"),
                                             "samples": summary.get("samples")}}
