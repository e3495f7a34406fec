"""Sessions recorded offline for the refinement tests: the bench walks an approved table (faster than real time) and
its samples are stored as a leg's telemetry at the device's 100 Hz, then the session is stopped through the API. Where a
test asks for ``swing_scale``, the recorded knee angle is scaled after toe-off: a synthetic change (a leg whose swing
knee flexes consistently less), said by the test that asks for it."""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np

from backend.db import connect
from backend.store import devices as devices_store
from backend.store import sessions as sessions_store
from backend.store import versions as versions_store
from backend.store.users import User
from controller_core.fsm import ImpedanceSchedule, StateMachineController
from controller_core.table import ParameterTable
from controller_core.units import G_MPS2
from device_bridge.bench.task_reference import task_reference
from device_bridge.protocol import Mode
from device_bridge.sim.simulate import run_walk
from tests.helpers.sql import sql

BENCH_DEVICE = "bench-leg"   # a device row of its own, not one the server's device manager drives


@functools.lru_cache(maxsize=16)
def _walked(table_json: str, speed_mps: float, incline_deg: float, model, mass_kg: float,
            seconds: float) -> dict[str, np.ndarray]:
    """The bench's walk of a table (its log's channels, shared: read them, never change them), kept for the test
    process: the walk is deterministic, and the SQLite and PostgreSQL runs of a test record the same one."""
    table = ParameterTable.model_validate_json(table_json)
    ref = task_reference(speed_mps, incline_deg, model, mass_kg)
    return run_walk(StateMachineController(ImpedanceSchedule.from_table(table)), ref, mass_kg, seconds).channels


def bench_samples(table: ParameterTable, speed_mps: float, incline_deg: float, model, mass_kg: float, seconds: float,
                  swing_scale: float = 1.0, mode: Mode = Mode.ACTIVE) -> list[tuple]:
    """The table walked on the bench, as telemetry rows in :data:`backend.store.sessions.SAMPLE_COLUMNS` order."""
    c = _walked(table.model_dump_json(), speed_mps, incline_deg, model, mass_kg, seconds)
    idx = np.arange(0, c["time_s"].size, 10)             # the device's 10 ms telemetry period
    knee = c["knee_angle_rad"][idx].copy()
    if swing_scale != 1.0:
        knee[c["load_N"][idx] < 0.1 * mass_kg * G_MPS2] *= swing_scale
    return [(k, float(c["time_s"][i]), int(mode), int(c["state"][i]), float(knee[k]),
             float(c["knee_velocity_rad_s"][i]), float(c["knee_torque_Nm"][i]), float(c["ankle_angle_rad"][i]),
             float(c["ankle_velocity_rad_s"][i]), float(c["ankle_torque_Nm"][i]), float(c["load_N"][i]),
             float(c["ankle_moment_Nm"][i]), None, None, None, None, None) for k, i in enumerate(idx)]


def record_offline(db_path: Path | str, model, patient: dict, proposal_id: int, seconds: float = 25.0, **walk) -> int:
    """A session of the patient on the approved table ``proposal_id``, its samples from the bench (not yet stopped);
    returns its id."""
    conn = connect(db_path)
    try:
        if sql(conn, "SELECT 1 FROM devices WHERE id = :id", id=BENCH_DEVICE).first() is None:
            devices_store.register_device(conn, BENCH_DEVICE, "can", "virtual", "bench")
        row = versions_store.get_row(conn, "proposal", proposal_id)
        user_id = sql(conn, "SELECT id FROM users WHERE role = 'prosthetist' ORDER BY id LIMIT 1").scalar_one()
        user = User(id=user_id, username="prosthetist", role="prosthetist")
        task = {"speed_mps": row["speed_mps"], "incline_deg": row["incline_deg"], "body_mass_kg": patient["body_mass_kg"]}
        sid = sessions_store.start_session(conn, patient["id"], BENCH_DEVICE, task,
                                           {"proposal_id": proposal_id, "envelope_id": None, "table_version": 1,
                                            "crc32": 1}, user, simulated=True)
        samples = bench_samples(versions_store.stored_table(row), row["speed_mps"], row["incline_deg"], model,
                                patient["body_mass_kg"], seconds, **walk)
        sessions_store.add_samples(conn, sid, samples)
        return sid
    finally:
        conn.close()
