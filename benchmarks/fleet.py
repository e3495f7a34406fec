"""Many legs through one broker to two API instances (``python -m benchmarks fleet``; figures, not a test).

Everything on this machine, on loopback: a Mosquitto of its own with TLS and a throwaway CA (as the tests start it),
two ``quasitune serve`` processes on one SQLite file, each serving every leg (``QUASITUNE_DEVICE=mqtt:leg-1,…``) with
an identity of its own, and ``legs`` leg identities whose telemetry is **replayed**: the simulated leg walked its
learned envelope at 1.2 m/s level (75 kg) for the length of the run, faster than real time, and the frames its
firmware put on its bus, one control tick's frames to a broker message as the bridge sends them (a telemetry sample
every 10 ms, status and health every 100 ms), are published by every leg on the firmware's schedule from
``replayers`` processes (the legs' starts spread over the 10 ms). ``monitors`` live monitors (the WebSocket a
clinician's page opens) watch the first legs, one each, alternating between the instances; the last ``recording``
legs record a session each (started on one instance, stopped on the other; both instances record them).

Measured over ``seconds`` after a warm-up:

* **latency**: from the replayer publishing a sample to a monitor receiving it (one machine, one clock): p50/p99/max.
* **gaps**: per instance and leg, telemetry samples the instance's link did not receive, by their sequence numbers
  (the device's ``telemetry_samples_missing``), and samples a monitor did not receive.
* **recorded**: the sessions' samples and the samples missing from them (their stop summaries).
* **heartbeats at the legs**: the servers' heartbeats arriving at each leg (both instances together): the rate and
  the longest silence (the leg's watchdog acts at 200 ms).
* **CPU**: each process's user + system time over the window (``/proc/PID/stat``), per leg for the instances.

The replayers and the monitors share the machine with what is measured: on a deployment they run at the legs' sites
and in the clinicians' browsers.
"""

from __future__ import annotations

import asyncio
import json
import multiprocessing
import os
import tempfile
import time
from pathlib import Path

import numpy as np

WARMUP_S = 5.0
EARLY_S = 0.002       # a replayed message may leave up to this much before its time (its send time is what counts)
PASSWORD = "fleet benchmark password"


def recorded_walk(seconds: float, mass_kg: float = 75.0, window_s: float | None = None
                  ) -> list[tuple[float, tuple[tuple[int, float], ...], tuple[tuple[float, bytes], ...]]]:
    """The broker messages of the simulated leg's bridge over ``seconds`` of walking its envelope: (when the message
    leaves, from the start s; (sequence number, when the leg made that sample) for each telemetry sample in it; its
    bursts, each (when it left the leg's bus, from the start s; its frames packed as the broker carries them)).
    Grouped as :meth:`Gateway.to_broker` groups them: one control tick's frames (a burst) to a message, telemetry
    waiting up to ``window_s`` (default the bridge's :data:`~device_bridge.gateway.TELEMETRY_WINDOW_S`) for the samples
    after it, anything else leaving at once. The firmware and the bench are stepped directly (no bus, no threads), so
    this takes a few seconds."""
    from controller_core import load_default_model
    from controller_core.walking_reference import sloped_walking_reference
    from device_bridge.device_node import TICK_S
    from device_bridge.envelope_wire import WireEnvelope, envelope_begin_frame, envelope_commit_frame
    from device_bridge.firmware import DeviceFirmware
    from device_bridge.gateway import TELEMETRY_WINDOW_S
    from device_bridge.mqtt_bus import pack_frames
    from device_bridge.protocol import decode, encode, is_telemetry
    from device_bridge.sim.walker import SimWalker

    window = TELEMETRY_WINDOW_S if window_s is None else window_s
    model = load_default_model()
    envelope = model.propose_envelope(np.linspace(0.6, 1.6, 5), np.linspace(-10, 10, 5), mass_kg)
    wire = WireEnvelope.from_envelope(envelope)
    crc = wire.crc32()
    fw = DeviceFirmware(now_s=0.0)
    for frame in [envelope_begin_frame(1, 1, crc, wire.shape), *wire.frames(1),
                  envelope_commit_frame(1, 1, crc, wire.shape)]:
        fw.receive(frame, 0.0)
    walker = SimWalker()
    walker.start(sloped_walking_reference(1.2, 0.0), mass_kg)
    out: list[tuple[float, tuple[tuple[int, float], ...], tuple[tuple[float, bytes], ...]]] = []
    opened: list | None = None      # [opened at s, samples, payload, still waiting]
    for i in range(round(seconds / TICK_S)):
        t = i * TICK_S
        if i % 20 == 0:
            fw.receive(encode("HOST_HEARTBEAT", {"counter": (i // 20) & 0xFFFF}), t)
        knee, ankle, frames = fw.tick(walker.sample(), t)
        walker.step(knee, ankle)
        if not frames:
            continue
        seq = next((raw["seq"] for name, raw in filter(None, map(decode, frames)) if name == "TELEMETRY_GAIT"), None)
        made = () if seq is None else ((seq, t),)
        if opened is not None and t < opened[0] + window - 1e-9:      # still open: these join it
            opened[1] += made
            opened[2] += ((t, pack_frames(frames)),)
            if not all(map(is_telemetry, frames)):     # a status: the message leaves now
                out.append((t, opened[1], opened[2]))
                opened = None
            continue
        if opened is not None:                         # its window closed before this tick
            out.append((opened[0] + window, opened[1], opened[2]))
            opened = None
        if window > 0 and all(map(is_telemetry, frames)):
            opened = [t, made, ((t, pack_frames(frames)),)]
        else:
            out.append((t, made, ((t, pack_frames(frames)),)))
    if opened is not None:
        out.append((opened[0] + window, opened[1], opened[2]))
    return out


def _cpu_s(pid: int) -> float:
    """User + system CPU time of a process so far (s)."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def _replay(legs: list[tuple[int, str, str, str]], n_legs: int, broker: str, ca_file: str,
            walk: list[tuple[float, tuple[tuple[int, float], ...], tuple[tuple[float, bytes], ...]]], start_at: float,
            out_file: str) -> None:
    """One replayer process: its legs (index, id, user name, password) publish the recorded walk on the firmware's
    schedule from ``start_at`` (Unix s), each leg offset by its index over the 10 ms; the publish time of each sample and the
    heartbeats each leg received are written to ``out_file``.

    Each leg is its own MQTT client with its own identity, as at a patient's home, publishing QoS 1 as the bridge
    does; all of a process's clients run in one thread with paho's external-loop calls (``loop_read``/``loop_misc``
    on a ``select`` of their sockets; a publish writes at once): a network thread per client cost the replayers most
    of a core at 50 legs, taken from the instances measured."""
    import select
    import struct

    import paho.mqtt.client as mqtt

    from device_bridge.mqtt_bus import broker_client, pack_late, topic
    from device_bridge.protocol import frame_id

    heartbeat = struct.pack("<H", frame_id("HOST_HEARTBEAT"))
    beats: list[list[float]] = [[] for _ in legs]
    clients = []
    for j, (_, leg_id, username, password) in enumerate(legs):
        c, address = broker_client(broker, username, username, password, ca_file)
        c.on_message = lambda _c, _u, m, j=j: beats[j].append(time.time()) if m.payload[:2] == heartbeat else None
        c.connect(address.host, address.port, keepalive=30)
        c.subscribe(topic(leg_id, "down"), qos=0)
        clients.append(c)
    up = [topic(leg_id, "up") for _, leg_id, _, _ in legs]
    by_socket = {c.socket(): c for c in clients}

    def pump(until: float) -> None:
        """Read what the broker sent (acknowledgements, the servers' heartbeats) until ``until`` (Unix s)."""
        while True:
            wait = until - time.time()
            readable, _, _ = select.select(list(by_socket), [], [], max(0.0, wait))
            for sock in readable:
                by_socket[sock].loop_read()
            if wait <= 0:
                return

    n_samples = 1 + max(seq for _, made, _ in walk for seq, _ in made)
    sent = np.full((len(legs), n_samples), np.nan)
    schedule = sorted((t + index * 0.01 / n_legs, k, j) for j, (index, *_) in enumerate(legs)
                      for k, (t, _, _) in enumerate(walk))
    next_misc = 0.0
    for offset, k, j in schedule:
        due = start_at + offset
        if due - time.time() > EARLY_S:    # events within a couple of ms go out together (fewer wake-ups)
            pump(due - EARLY_S)
        t_message, made, bursts = walk[k]
        now = time.time()       # the records say when each burst left the leg's bus, as the bridge's do
        info = clients[j].publish(up[j], pack_late((now - (t_message - tb), fb) for tb, fb in bursts), qos=1)
        for seq, t_made in made:     # when the leg made the sample: what waited for the message counts
            sent[j, seq] = now - (t_message - t_made) if info.rc == mqtt.MQTT_ERR_SUCCESS else np.nan
        if due >= next_misc:     # keepalive and retries, once a second
            next_misc = due + 1.0
            for c in clients:
                c.loop_misc()
    pump(time.time() + 1.0)
    for c in clients:
        c.disconnect()
    np.savez(out_file, sent=sent, index=np.array([i for i, *_ in legs]),
             beats=np.array([np.array(b) for b in beats], dtype=object))


async def _monitor(url: str, leg: int, until: float, seen: list[tuple[int, int, float]]) -> None:
    import websockets

    async with websockets.connect(url, max_queue=None) as ws:
        while time.time() < until:
            try:
                message = await asyncio.wait_for(ws.recv(), timeout=max(0.01, until - time.time()))
            except TimeoutError:
                break
            now = time.time()
            item = json.loads(message)
            if item.get("type") == "telemetry":
                seen.append((leg, item["seq"], now))


async def _monitors(urls: list[tuple[str, int]], until: float) -> list[tuple[int, int, float]]:
    seen: list[tuple[int, int, float]] = []
    await asyncio.gather(*(_monitor(url, leg, until, seen) for url, leg in urls))
    return seen


def _percentiles_ms(values: np.ndarray) -> dict:
    ms = values * 1e3
    return {"n": int(ms.size), "p50_ms": round(float(np.percentile(ms, 50)), 1),
            "p99_ms": round(float(np.percentile(ms, 99)), 1), "max_ms": round(float(ms.max()), 1)}


def _start_sessions(base: str, headers: dict, leg_ids: list[str]) -> list[int]:
    """A patient per leg, the leg assigned to them, a session recording it (through the first instance)."""
    import httpx

    out = []
    with httpx.Client(base_url=base, headers=headers, timeout=60.0) as c:
        for i, leg in enumerate(leg_ids):
            patient = c.post("/api/patients", json={"code_name": f"FLEET-{i + 1}", "body_mass_kg": 75.0,
                                                    "side": "left"}).json()
            c.put(f"/api/devices/{leg}/assignment", json={"patient_id": patient["id"]}).raise_for_status()
            r = c.post(f"/api/patients/{patient['id']}/sessions", json={"device_id": leg, "speed_mps": 1.2})
            r.raise_for_status()
            out.append(r.json()["id"])
    return out


def _stop_sessions(base: str, headers: dict, sessions: list[int]) -> dict:
    import httpx

    summaries = []
    with httpx.Client(base_url=base, headers=headers, timeout=120.0) as c:
        for sid in sessions:
            r = c.post(f"/api/sessions/{sid}/stop")
            r.raise_for_status()
            summaries.append(r.json()["summary"])
    return {"sessions": len(sessions), "samples": sum(x["samples"] for x in summaries),
            "missing_samples": sum(x["missing_samples"] for x in summaries)}


def run(legs: int = 50, monitors: int = 20, seconds: float = 30.0, replayers: int = 2,
        window_s: float | None = None, recording: int = 10) -> dict:
    import httpx

    from backend.db import connect
    from backend.migrate import migrate
    from backend.store.users import create_user
    from benchmarks.instances import Instance
    from tests.helpers.mosquitto import admin_of, running_broker

    if not (1 <= monitors <= legs and 1 <= replayers <= legs and 0 <= recording <= legs):
        raise ValueError("need 1 <= monitors <= legs, 1 <= replayers <= legs and 0 <= recording <= legs")
    if not 1.0 <= seconds <= 500.0:      # the replay's 16-bit sequence numbers must not wrap (655 s)
        raise ValueError(f"seconds must be in [1, 500], got {seconds!r}")
    walk_s = WARMUP_S + seconds + 30.0     # the instances' start-up and the monitors' connections come first
    t0 = time.monotonic()
    walk = recorded_walk(walk_s, window_s=window_s)
    recorded_in = time.monotonic() - t0
    leg_ids = [f"leg-{i + 1}" for i in range(legs)]
    with running_broker() as broker, tempfile.TemporaryDirectory(prefix="quasitune-fleet-") as tmp:
        folder = Path(tmp)
        with admin_of(broker) as admin:
            identities = [admin.add_device(leg) for leg in leg_ids]
            servers_id = {name: admin.add_server(f"fleet-{name}") for name in ("api1", "api2")}
        migrate(folder / "quasitune.sqlite")
        conn = connect(folder / "quasitune.sqlite")
        try:
            create_user(conn, "bench", "prosthetist", PASSWORD)
        finally:
            conn.close()
        device = ",".join(f"mqtt:{leg}" for leg in leg_ids)
        servers = {name: Instance(folder, None, device, {
            "QUASITUNE_BROKER_URL": broker.url, "QUASITUNE_BROKER_USERNAME": who.username,
            "QUASITUNE_BROKER_PASSWORD": who.password, "QUASITUNE_BROKER_CA_FILE": broker.ca_file,
            "QUASITUNE_INSTANCE_NAME": name}) for name, who in servers_id.items()}
        procs: list[multiprocessing.Process] = []
        try:
            for s in servers.values():
                s.spawn()
            for s in servers.values():
                s.ready()
            start_at = time.time() + 5.0 + 0.2 * legs / replayers    # every replayer connected by then
            ctx = multiprocessing.get_context("spawn")
            groups = [[(i, leg_ids[i], *identities[i]) for i in range(r, legs, replayers)] for r in range(replayers)]
            for r, group in enumerate(groups):
                p = ctx.Process(target=_replay, args=(group, legs, broker.url, broker.ca_file, walk, start_at,
                                                      str(folder / f"replay-{r}.npz")))
                p.start()
                procs.append(p)
            first, second = servers.values()
            with httpx.Client(base_url=first.base, timeout=60.0) as c:
                token = c.post("/api/auth/token", data={"username": "bench", "password": PASSWORD}).json()
            headers = {"Authorization": f"Bearer {token['access_token']}"}
            time.sleep(max(0.0, start_at - time.time()) + 1.0)
            sessions = _start_sessions(first.base, headers, leg_ids[legs - recording:])
            time.sleep(max(0.0, start_at + WARMUP_S - time.time()))
            cpu_pids = {"broker": broker.proc.pid, **{name: s.proc.pid for name, s in servers.items()},
                        **{f"replayer_{r}": p.pid for r, p in enumerate(procs)}, "monitors": os.getpid()}
            cpu0 = {k: _cpu_s(pid) for k, pid in cpu_pids.items()}
            w0 = time.monotonic()
            window = (time.time(), time.time() + seconds)
            urls = [(f"ws://127.0.0.1:{(first, second)[m % 2].port}/api/devices/{leg_ids[m]}/telemetry"
                     f"?token={token['access_token']}", m) for m in range(monitors)]
            seen = asyncio.run(_monitors(urls, window[1]))
            wall = time.monotonic() - w0
            cpu = {k: round((_cpu_s(pid) - cpu0[k]) / wall, 3) for k, pid in cpu_pids.items()}
            views = {}
            for name, s in servers.items():
                with httpx.Client(base_url=s.base, timeout=60.0) as c:
                    views[name] = {d["id"]: d for d in c.get("/api/devices", headers=headers).json()}
            recorded = _stop_sessions(second.base, headers, sessions)
            for p in procs:
                p.join(timeout=walk_s + 60)
        finally:
            for p in procs:
                if p.is_alive():
                    p.terminate()
            for s in servers.values():
                s.stop()
        replays = [np.load(folder / f"replay-{r}.npz", allow_pickle=True) for r in range(replayers)]
    sent = np.full((legs, replays[0]["sent"].shape[1]), np.nan)
    beats: list[np.ndarray] = [np.array([])] * legs
    for rep in replays:
        for j, i in enumerate(rep["index"]):
            sent[i] = rep["sent"][j]
            beats[i] = np.asarray(rep["beats"][j], dtype=float)
    seen_a = np.array(seen, dtype=float) if seen else np.zeros((0, 3))
    lat = seen_a[:, 2] - sent[seen_a[:, 0].astype(int), seen_a[:, 1].astype(int)]
    monitor_missing = 0
    for m in range(monitors):
        seqs = np.unique(seen_a[seen_a[:, 0] == m, 1])
        monitor_missing += int(seqs[-1] - seqs[0] + 1 - seqs.size) if seqs.size else 0
    in_window = [b[(b >= window[0]) & (b <= window[1])] for b in beats]
    beat_gaps = [float(np.diff(b).max()) for b in in_window if b.size > 1]
    return {
        "legs": legs, "monitors": monitors, "seconds": seconds, "replayers": replayers, "tls": True,
        "telemetry": "replayed: the simulated leg's firmware frames, walking its learned envelope at 1.2 m/s level",
        "walk_recorded_in_s": round(recorded_in, 1),
        "monitor_latency": _percentiles_ms(lat[np.isfinite(lat)]),
        "monitor_samples": int(seen_a.shape[0]), "monitor_samples_missing": monitor_missing,
        "recorded": recorded,
        "instances": {name: {
            "samples_received": sum(d["telemetry_samples_received"] for d in v.values()),
            "samples_missing": sum(d["telemetry_samples_missing"] for d in v.values()),
            "legs_online": sum(bool(d["online"]) for d in v.values())} for name, v in views.items()},
        "heartbeats_at_legs": {"per_leg_per_s": round(float(np.mean([b.size for b in in_window])) / seconds, 1),
                               "longest_silence_ms": round(max(beat_gaps) * 1e3, 1) if beat_gaps else None},
        "cpu_cores": cpu, "cpu_per_leg_per_instance": {
            name: round(cpu[name] / legs, 4) for name in servers},
        "machine_cores": os.cpu_count(),
    }
