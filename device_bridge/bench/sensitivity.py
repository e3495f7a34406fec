"""The refinement's sensitivity, measured on the bench (``quasitune sensitivity``).

At each node of a task grid the model's table is walked with each refined value
(:data:`controller_core.refine.PARAMETERS`) moved a little up and a little down; the central difference of the
controlled quantities' mean errors (:func:`device_bridge.bench.refine_walks.bench_feature_errors`, the leg's own
feature definitions) is that node's sensitivity: quantity units (deg, % of the cycle) per deg of an equilibrium angle
or per unit of ln|value| of a stiffness or damping. The bench is deterministic, so the two walks differ only by the
change; a walk that falls, or measures a quantity on fewer than :data:`MIN_STRIDES` strides, leaves that entry
unresolved (null), and :class:`controller_core.refine_sensitivity.BenchSensitivity` fills it from the grid's other
nodes.

Why measured, not modelled: the sub-phase spring model the refinement used before (a feature moves one for one with its
own row's θe) is wrong on this leg where it matters most. The stance knee peak is set by how the knee lands, the
terminal-swing row (+22° per unit ln b and +0.75° per degree of its θe, grid medians, against +0.19° per degree of the
stance-flexion row's θe), and the swing peak's timing hardly responds to the swing-flexion stiffness the spring model
moved for it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from datetime import UTC, datetime

from controller_core.model import QuasiStiffnessModel
from controller_core.refine import PARAMETERS, Parameter, clamp_value
from controller_core.refine_evidence import QUANTITIES
from controller_core.refine_sensitivity import SENSITIVITY_VERSION
from controller_core.table import DEFAULT_LIMITS, ParameterTable
from controller_core.table_edit import edit_table
from device_bridge.bench.controllers import DEFAULT_ENVELOPE_INCLINES_DEG, DEFAULT_ENVELOPE_SPEEDS_MPS, NOMINAL_TASK
from device_bridge.bench.refine_walks import bench_feature_errors

THETA_STEP_DEG = 3.0            # ± on an equilibrium angle (beyond it, the refinement's bench check: RefineRules)
LOG_STEP = math.log(1.25)       # ± on ln|k| or ln|b| (×1.25, ÷1.25)
MIN_STRIDES = 6


def perturbed(table: ParameterTable, p: Parameter, sign: float) -> tuple[ParameterTable, float]:
    """The table with ``p`` moved one measuring step in the direction ``sign``, held inside the limits (a node at a
    limit is measured one-sidedly), and the value it was given in the stepping unit."""
    old = p.value_in(table)
    new = clamp_value(p, p.moved(old, sign * (LOG_STEP if p.relative else THETA_STEP_DEG)), table, DEFAULT_LIMITS)
    if new == old:
        return table, p.stepping(old)
    return edit_table(table, [{"joint": p.joint, "subphase": p.subphase, p.attr: new}])[0], p.stepping(new)


_WORKER_MODEL: list[QuasiStiffnessModel] = []   # the model in a worker process, sent once (not with every walk)


def _start_worker(model: QuasiStiffnessModel) -> None:
    _WORKER_MODEL[:] = [model]


def _errors(args: tuple[ParameterTable, float, float, float, float]) -> dict | None:
    table, speed, incline, mass, seconds = args
    r = bench_feature_errors(table, speed, incline, mass, _WORKER_MODEL[0], seconds)
    if r["falls"] or r["strides"] < MIN_STRIDES:
        return None
    return r["error"]


def node_sensitivity(results: Sequence[dict | None], values: Sequence[float]) -> list[list[float | None]]:
    """(quantities × parameters) central differences from the walks' errors and the values walked (stepping unit),
    both ordered (+p0, −p0, +p1, −p1, …)."""
    out: list[list[float | None]] = [[None] * len(PARAMETERS) for _ in QUANTITIES]
    for c in range(len(PARAMETERS)):
        up, down = results[2 * c], results[2 * c + 1]
        h = values[2 * c] - values[2 * c + 1]
        if up is None or down is None or h <= 0.0:
            continue
        for r, q in enumerate(QUANTITIES):
            a, b = up.get(q.key), down.get(q.key)
            if a is not None and b is not None:
                out[r][c] = round((a - b) / h, 4)
    return out


def measure_sensitivity(model: QuasiStiffnessModel, speeds_mps: Sequence[float] = DEFAULT_ENVELOPE_SPEEDS_MPS,
                        inclines_deg: Sequence[float] = DEFAULT_ENVELOPE_INCLINES_DEG, mass_kg: float = 75.0,
                        seconds: float = 16.0, workers: int = 2) -> dict:
    """The sensitivity grid as the JSON :class:`controller_core.refine_sensitivity.BenchSensitivity` reads (module
    docstring): the tables of the model's envelope over the grid (the ones a refinement edits), on the nominal leg,
    ``seconds`` per walk."""
    envelope = model.propose_envelope(list(speeds_mps), list(inclines_deg), mass_kg, NOMINAL_TASK)
    tasks = [(node.speed_mps, node.incline_deg, node.table) for node in envelope.nodes]
    walked = [(perturbed(table, p, sign), s, i) for s, i, table in tasks for p in PARAMETERS for sign in (1.0, -1.0)]
    jobs = [(table, s, i, mass_kg, seconds) for (table, _), s, i in walked]
    values = [v for (_, v), _, _ in walked]
    if workers <= 1:                 # in this process (tests, a one-core machine)
        _start_worker(model)
        results = [_errors(job) for job in jobs]
    else:
        with ProcessPoolExecutor(max_workers=workers, initializer=_start_worker, initargs=(model,)) as pool:
            results = list(pool.map(_errors, jobs, chunksize=4))
    per = 2 * len(PARAMETERS)
    return {
        "version": SENSITIVITY_VERSION,
        "parameters": [p.field for p in PARAMETERS], "quantities": [q.key for q in QUANTITIES],
        "speeds_mps": [float(s) for s in speeds_mps], "inclines_deg": [float(i) for i in inclines_deg],
        "jacobians": [node_sensitivity(results[k * per:(k + 1) * per], values[k * per:(k + 1) * per])
                      for k in range(len(tasks))],
        "provenance": {
            "what": "central differences of each controlled quantity's mean error (quantity unit per deg of θe, or "
                    "per unit ln|k| or ln|b|) on the simulated bench, the model's envelope table at each node",
            "leg": "nominal", "mass_kg": mass_kg, "seconds_per_walk": seconds,
            "steps": {"theta_e_deg": THETA_STEP_DEG, "ln_value": round(LOG_STEP, 6)},
            "unresolved_rule": f"a walk that falls or measures a quantity on fewer than {MIN_STRIDES} strides",
            "command": "quasitune sensitivity --out controller_core/data/refine_sensitivity.json",
            "made_utc": datetime.now(UTC).strftime("%Y-%m-%dT%H:%M:%SZ"),
        },
    }
