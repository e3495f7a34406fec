"""The device manager: a simulated leg on its own virtual bus, its status as the truth, a table pushed to it."""

from __future__ import annotations

import pytest

from backend.db import open_engine
from backend.devices.manager import DeviceManager
from backend.devices.specs import parse_device_spec
from backend.errors import NotFoundError
from backend.migrate import migrate
from device_bridge.as_run import as_run
from device_bridge.clock import SteppedClock
from tests.helpers.device import until


@pytest.fixture
def manager(tmp_path):
    path = tmp_path / "q.sqlite"
    migrate(path)
    pool = open_engine(path)
    spec = parse_device_spec("sim")
    m = DeviceManager(pool, [spec], clock=SteppedClock()).start()     # the leg and its link in simulated time
    yield m, spec.device_id
    m.close()
    pool.dispose()


def test_the_leg_comes_online_and_says_it_runs_no_table(manager):
    m, leg = manager
    assert m.ids() == [leg]
    until(lambda: m.online(m.get(leg)), 15.0, clock=m.clock)
    view = m.view(leg)
    assert view["kind"] == "simulated" and view["mode"] == "no_table" and view["active_crc32"] is None
    assert view["patient"] is None and view["bench_state"] is not None
    with pytest.raises(NotFoundError, match="devices: sim-leg-1"):
        m.get("another-leg")


def test_a_pushed_table_is_read_back_by_its_crc_and_then_run(manager, model):
    m, leg = manager
    until(lambda: m.online(m.get(leg)), 15.0, clock=m.clock)
    table = model.propose(1.2, 0.0, 75.0).table
    result = m.push(leg, table, version=1)
    assert result.crc32 == as_run(table).wire_crc32 and result.version == 1
    until(lambda: m.view(leg)["active_crc32"] == f"{result.crc32:08x}", 15.0, clock=m.clock)   # at its next heel strike


def test_a_simulated_leg_is_fitted_to_the_leg_of_the_patient_who_wears_it(manager):
    """The simulated device walks the leg its patient's record describes (and its firmware's thigh, shank and
    forefoot are that leg's, as a real leg is set up for its wearer); worn by nobody, or by a patient whose leg is not
    described, it is the server's bench leg again."""
    from device_bridge.sim.leg_file import load_leg_file
    from device_bridge.sim.leg_model import LegGeometry

    m, leg = manager
    described = load_leg_file("short_person").description()
    short = load_leg_file("short_person").geometry()
    dev = m.get(leg)
    m.worn_by(leg, {"body_mass_kg": 70.0, "leg": described})
    assert dev.walker.geometry == short and dev.node.firmware.config.thigh_length_m == short.thigh_m
    assert dev.node.firmware.config.forefoot_m == short.toe_forward_m != LegGeometry().toe_forward_m
    assert m.view(leg)["bench_leg"] == "short person (1.58 m)"
    m.worn_by(leg, {"body_mass_kg": 70.0, "leg": None})   # a patient whose leg is not described
    assert dev.walker.geometry == LegGeometry() and dev.node.firmware.config.thigh_length_m == LegGeometry().thigh_m
    m.worn_by(leg, {"body_mass_kg": 70.0, "leg": described})
    m.worn_by(leg, None)                              # nobody: the bench leg
    assert dev.walker.geometry == LegGeometry()
