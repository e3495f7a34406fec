"""Every node of an envelope walked at its own task, for the envelope's preview and its bench gate.

What a node walk is: :mod:`device_bridge.bench.node_walks` (the node's table from quiet standing, and reached from
level walking on the envelope's most level node at that speed; the most level nodes themselves walk from standing
only, their level walking being that walk). Each node's walks are judged on the same bounds as
any bench walk (:func:`backend.bench.safety_figures.safety_flags`, without the FSMIC-relative rule: the benchmark is
not walked per node), and every flag gates the envelope.

A walk depends only on its content (the two tables, the task, the body mass, the leg), so walks are kept for the life
of the server by that content: an edit or a refinement that changes three nodes walks those three again, and two
envelopes that share nodes share their walks. Where the machine has cores to spare (``Settings.bench_processes``) a
pool of processes walks the nodes side by side (the standard library's ``ProcessPoolExecutor``: a walk is Python per
simulated tick, so threads would queue on one interpreter); with one process they walk in turn on the caller's thread.
"""

from __future__ import annotations

import hashlib
import multiprocessing
import threading
from collections import OrderedDict
from collections.abc import Hashable
from concurrent.futures import Future, ProcessPoolExecutor, as_completed

from backend.bench.safety_figures import safety_flags
from controller_core.envelope import Envelope
from controller_core.model import QuasiStiffnessModel
from controller_core.table import ImpedanceTable
from device_bridge.bench.node_walks import NODE_STARTS, simulated_s, walk_node
from device_bridge.bench.task_reference import task_reference
from device_bridge.sim import progress
from device_bridge.sim.leg_model import LegGeometry

START_WORDS = {"standing": "from standing", "level": "reached from level walking"}


def content_sha256(item: ImpedanceTable | Envelope) -> str:
    """What a walk of a table or an envelope depends on of it: its content, hashed."""
    return hashlib.sha256(item.model_dump_json().encode()).hexdigest()


def level_index(envelope: Envelope) -> int:
    """The incline index of the envelope's most level nodes (the level walking a node is reached from)."""
    return min(range(len(envelope.inclines_deg)), key=lambda j: (abs(envelope.inclines_deg[j]), envelope.inclines_deg[j]))


def node_flags(walk: dict[str, object]) -> list[dict[str, object]]:
    """One node walk's figures beyond their bounds (absolute bounds: no FSMIC walk per node)."""
    return safety_flags(walk, {})


class NodeWalks:
    """The node walks of envelopes, kept by content (module docstring); ``processes`` > 1 walks them side by side.

    ``maxsize`` bounds the walks kept (about 1 kB each). Thread-safe: previews of two envelopes may ask at once.
    """

    def __init__(self, processes: int = 1, maxsize: int = 20_000) -> None:
        if processes < 1:
            raise ValueError(f"processes must be at least 1, got {processes}")
        self.processes, self.maxsize = processes, maxsize
        self._kept: OrderedDict[Hashable, dict[str, object]] = OrderedDict()
        self._lock = threading.Lock()
        self._pool: ProcessPoolExecutor | None = None

    def close(self) -> None:
        """Stop the pool's processes (a server shutting down)."""
        with self._lock:
            pool, self._pool = self._pool, None
        if pool is not None:
            pool.shutdown(wait=True, cancel_futures=True)

    def _executor(self) -> ProcessPoolExecutor:
        with self._lock:
            if self._pool is None:   # spawned, not forked: the server's threads and sockets stay in the server
                self._pool = ProcessPoolExecutor(self.processes, mp_context=multiprocessing.get_context("spawn"))
            return self._pool

    def walk(self, envelope: Envelope, model: QuasiStiffnessModel | None,
             geometry: LegGeometry | None = None) -> list[dict[str, object]]:
        """Per node (speed-major, as ``envelope.nodes``): its task, its ``walks`` (``standing``, and ``level`` but at
        the most level nodes: the figures of :mod:`device_bridge.bench.node_walks`) and ``flags`` (each with the
        ``start`` it came from).
        Walks it has kept are not walked again. The caller's progress hook hears each walk's simulated seconds."""
        geometry = geometry or LegGeometry()
        j0 = level_index(envelope)
        todo: dict[Hashable, tuple] = {}
        keys: list[dict[str, Hashable]] = []
        for idx, node in enumerate(envelope.nodes):
            i = idx // len(envelope.inclines_deg)
            level = envelope.node(i, j0).table
            mine = {}
            for start in NODE_STARTS:
                if start == "level" and idx % len(envelope.inclines_deg) == j0:
                    continue       # a level node's walk from standing is its level walking: the same rows, floor, speed
                lead = level if start == "level" else None
                key = (content_sha256(node.table), content_sha256(lead) if lead is not None else None,
                       node.speed_mps, node.incline_deg, envelope.mass_kg, geometry, start)
                mine[start] = key
                if key not in self._kept and key not in todo:
                    ref = task_reference(node.speed_mps, node.incline_deg, model, envelope.mass_kg)
                    todo[key] = (node.table, ref, envelope.mass_kg, start, lead, geometry)
            keys.append(mine)
        self._walk_all(todo)
        out = []
        for node, mine in zip(envelope.nodes, keys, strict=True):
            walks = {start: self._kept[key] for start, key in mine.items()}
            flags = [{**f, "start": start, "message": f"{START_WORDS[start]}: {f['message']}"}
                     for start, walk in walks.items() for f in node_flags(walk)]
            out.append({"speed_mps": node.speed_mps, "incline_deg": node.incline_deg, "walks": walks, "flags": flags})
        return out

    def _keep(self, key: Hashable, walk: dict[str, object]) -> None:
        with self._lock:
            self._kept[key] = walk
            self._kept.move_to_end(key)
            while len(self._kept) > self.maxsize:
                self._kept.popitem(last=False)

    def _walk_all(self, todo: dict[Hashable, tuple]) -> None:
        if self.processes == 1 or len(todo) < 2:
            for key, args in todo.items():
                self._keep(key, walk_node(*args).to_dict())     # reports its own seconds as it walks
            return
        pool = self._executor()
        futures: dict[Future, Hashable] = {pool.submit(walk_node, *args): key for key, args in todo.items()}
        try:
            for done in as_completed(futures):
                key = futures[done]
                self._keep(key, done.result().to_dict())
                progress.walked(simulated_s(key[-1]))       # may raise: a cancelled job stops here
        finally:
            for f in futures:
                f.cancel()


def node_label(speed_mps: float, incline_deg: float) -> str:
    """A node's task as the pages write it: ``0.6 m/s, −10°``."""
    return f"{speed_mps:g} m/s, {incline_deg:+g}°".replace("-", "−")


def envelope_flags(stored: dict[str, object]) -> list[dict[str, object]]:
    """Every flag of an envelope's stored preview: the course walk's, then each node's (with ``node_speed_mps``,
    ``node_incline_deg``, ``start``, and the node named in the message). A preview without node walks (stored before
    nodes were walked) has one flag saying so: nothing measured is not safe."""
    runs = stored["controllers"]
    flags = safety_flags(runs["envelope"], runs["fsmic"])
    nodes = stored.get("nodes")
    if nodes is None:
        return [*flags, {"figure": "nodes_walked", "severity": "bad", "value": 0, "fsmic_value": None, "unit": "nodes",
                         "message": "its nodes were not walked alone at their tasks: walk the preview again"}]
    for node in nodes:
        where = node_label(node["speed_mps"], node["incline_deg"])
        flags.extend({**f, "node_speed_mps": node["speed_mps"], "node_incline_deg": node["incline_deg"],
                      "message": f"at {where}, {f['message']}"} for f in node["flags"])
    return flags


def flagged_nodes(stored: dict[str, object]) -> int | None:
    """How many nodes have a figure beyond its bound (None: not walked)."""
    nodes = stored.get("nodes")
    return None if nodes is None else sum(1 for n in nodes if n["flags"])
