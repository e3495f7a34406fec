"""The leg's link through the broker (``python -m benchmarks link``; figures, not a test). A Mosquitto of its own on
loopback with TLS and a throwaway CA (as the tests start it), the leg's identity and the server's.

1. **pushes**: a 25-node (5 × 5) envelope and a table pushed ``pushes`` times each through the broker (server → broker
   → the leg's bridge → the leg's virtual CAN bus and back), CRC read-back included: p50/p95/p99 (ms).
2. **soak**: ``trials`` pushes, envelopes and tables in turn, with ``quasitune device soak``'s bus faults on the leg's
   CAN side (drop 10 %, corrupt 2 %, reorder 5 % of frames, both ways) and the broker stopped and restarted every
   ``restart_every`` trials: the soak's outcome classes (``mixed`` and ``crc_mismatch`` must be 0).
3. **link loss**: a walking session through the broker on an API instance, the broker stopped for ``cut_seconds`` in
   the middle, once with the leg supervised and once autonomous: samples stored against the sequence's span, how many
   came late from the bridge's buffer, the leg's modes during the cut (from the device, 50 Hz), how long it took to be
   in safe mode (supervised) and that it runs its table again after the host said so.

Many legs to two instances: ``python -m benchmarks fleet``.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np


def _percentiles(values: list[float]) -> dict:
    a = np.asarray(values)
    return {"n": int(a.size), "p50_ms": round(float(np.percentile(a, 50)), 1),
            "p95_ms": round(float(np.percentile(a, 95)), 1), "p99_ms": round(float(np.percentile(a, 99)), 1),
            "max_ms": round(float(a.max()), 1)}


def _topology(broker, admin, faults: tuple[float, float, float] | None = None, seed: int = 0):
    """The leg (no walker: a push lands at once) behind its bridge, and the server's link, all through ``broker``."""
    import can

    from device_bridge.device_node import DeviceNode
    from device_bridge.faults import FaultInjectingBus
    from device_bridge.gateway import Gateway
    from device_bridge.host import DeviceLink
    from device_bridge.mqtt_bus import MqttBus

    device_id = f"bench-leg-{next(_legs)}"
    identity = admin.add_device(device_id)
    channel = f"bench-link-{time.monotonic_ns()}"

    def leg_bus(offset: int):
        bus = can.Bus(interface="virtual", channel=channel)
        return bus if faults is None else FaultInjectingBus(bus, *faults, seed=seed + offset)

    node = DeviceNode(leg_bus(0)).start()
    far = MqttBus(device_id, broker.url, *identity, role="device", ca_file=broker.ca_file,
                  connect_timeout_s=30.0)
    gateway = Gateway.to_broker(leg_bus(1), far).start()
    link = DeviceLink(MqttBus(device_id, broker.url, *admin.add_server(f"bench-{next(_legs)}"), role="server",
                              ca_file=broker.ca_file, connect_timeout_s=30.0)).start()
    return node, gateway, link


_legs = iter(range(1, 1_000_000))


def _items(model):
    from controller_core.fsmic import fsmic_table

    envelopes = [model.propose_envelope(np.linspace(0.6, 1.6, 5), np.linspace(-10, 10, 5), m) for m in (70.0, 85.0)]
    tables = [model.propose_table(1.2, 0.0, 75.0)[0], fsmic_table(75.0)]
    return envelopes, tables


def pushes(broker, admin, model, n: int) -> dict:
    node, gateway, link = _topology(broker, admin)
    envelopes, tables = _items(model)
    out: dict = {}
    try:
        for kind, items, push in (("envelope_5x5", envelopes, link.push), ("table", tables, link.push)):
            times = []
            for i in range(n):
                result = push(items[i % 2], version=i % 0xFFFF + 1)
                times.append(result.elapsed_ms)
            out[kind] = _percentiles(times)
    finally:
        link.close()
        gateway.close()
        node.close()
    return out


def soak(broker, admin, model, trials: int, restart_every: int) -> dict:
    from device_bridge.soak import soak_link

    envelopes, tables = _items(model)
    node, gateway, link = _topology(broker, admin, faults=(0.10, 0.02, 0.05), seed=7)
    restarts = 0

    def between(i: int) -> None:
        nonlocal restarts
        if i and i % restart_every == 0:
            broker.stop()
            time.sleep(1.0)
            broker.start()
            restarts += 1
            deadline = time.monotonic() + 30
            while not (gateway.b.connected and link.bus.connected) and time.monotonic() < deadline:
                time.sleep(0.05)

    try:
        counts = soak_link(link, node, [envelopes[0], tables[0], envelopes[1], tables[1]], trials, 3.0, between)
    finally:
        link.close()
        gateway.close()
        node.close()
    return {**counts, "broker_restarts": restarts, "faults": {"drop": 0.10, "corrupt": 0.02, "reorder": 0.05}}


def link_loss(broker, admin, model, cut_seconds: float, mode: str) -> dict:
    from backend.migrate import migrate
    from backend.store import sessions as sessions_store
    from device_bridge.protocol import Mode
    from tests.helpers.api import approved_proposal, push_to_leg, wait_for
    from tests.helpers.bridged_leg import bridged_leg, broker_app

    leg_id = f"bench-home-{next(_legs)}"
    with tempfile.TemporaryDirectory(prefix="quasitune-link-bench-") as tmp:
        folder = Path(tmp)
        template = folder / "template.sqlite"
        migrate(template)
        with bridged_leg(broker, admin, folder, leg_id) as leg, \
                broker_app(broker, admin, folder, model, template, leg_id) as api:
            pro = api.as_("prosthetist")
            device = lambda: api.client.get(f"/api/devices/{leg_id}", headers=pro).json()   # noqa: E731
            if mode == "autonomous":
                api.client.put(f"/api/devices/{leg_id}/link-mode", headers=pro,
                               json={"link_mode": "autonomous", "reason": "link benchmark: the autonomous leg"})
                wait_for(device, lambda d: d["link_mode_on_device"] == "autonomous")
            prop = approved_proposal(api)
            assert push_to_leg(api, prop, device=leg_id).status_code == 201
            wait_for(device, lambda d: d["mode"] == "active")
            session = api.client.post(f"/api/patients/{prop['patient_id']}/sessions", headers=pro,
                                      json={"device_id": leg_id, "speed_mps": 1.2}).json()
            time.sleep(5.0)
            cut_at = time.monotonic()
            broker.stop()
            modes, safe_after = [], None
            while time.monotonic() - cut_at < cut_seconds:
                m = leg.node.snapshot().mode
                modes.append(m)
                if m == Mode.SAFE and safe_after is None:
                    safe_after = time.monotonic() - cut_at
                time.sleep(0.02)
            broker.start()
            back_at = time.monotonic()
            wait_for(device, lambda d: d["online"], timeout_s=60.0)
            online_after = time.monotonic() - back_at
            if mode == "supervised":
                api.client.post(f"/api/devices/{leg_id}/commands", headers=pro, json={"command": "leave_safe_mode"})
                wait_for(device, lambda d: d["mode"] == "active")
            table_again = device()["mode"] == "active"
            wait_for(lambda: len(leg.far._late_buffer), lambda n: n == 0, timeout_s=120.0)
            drained_after = time.monotonic() - back_at
            time.sleep(3.0)
            summary = api.client.post(f"/api/sessions/{session['id']}/stop", headers=pro).json()["summary"]
            with api.db() as conn:
                seqs = sessions_store.samples(conn, session["id"])["seq"]
    return {"mode": mode, "cut_s": cut_seconds, "samples_stored": len(seqs),
            "samples_expected": int(seqs[-1] - seqs[0] + 1) if seqs else 0,
            "missing_samples": summary["missing_samples"], "late_samples": summary["late_samples"],
            "leg_modes_during_cut": sorted({m.name.lower() for m in modes}),
            "safe_mode_after_cut_s": None if safe_after is None else round(safe_after, 3),
            "server_sees_leg_after_s": round(online_after, 2), "buffer_delivered_after_s": round(drained_after, 2),
            "runs_its_table_afterwards": table_again}


def run(pushes_n: int = 100, trials: int = 500, restart_every: int = 50, cut_seconds: float = 60.0) -> dict:
    from controller_core import load_default_model
    from tests.helpers.mosquitto import admin_of, running_broker

    model = load_default_model()
    with running_broker() as broker:
        t0 = time.monotonic()
        with admin_of(broker) as admin:
            out = {"tls": True, "broker": "Debian's Mosquitto on loopback",
                   "pushes": pushes(broker, admin, model, pushes_n)}
            out["soak"] = soak(broker, admin, model, trials, restart_every)
        with admin_of(broker) as admin:   # a fresh admin connection after the soak's broker restarts
            out["link_loss"] = [link_loss(broker, admin, model, cut_seconds, m) for m in ("supervised", "autonomous")]
        out["wall_s"] = round(time.monotonic() - t0, 1)
        return out
