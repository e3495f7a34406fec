"""Every grid the API accepts reaches the leg whole, and nothing a transfer does can stop the leg's control.

A 64-node envelope once killed the firmware: node 63 doubled as the axes' check marker, its frames were dropped and
the commit raised inside the thread that also ran the control loop. These tests fail on that layout.
"""

from __future__ import annotations

import numpy as np
import pytest

from backend.schemas.versions import MAX_NODES
from controller_core.fsm import SensorSample
from device_bridge.envelope_wire import EnvelopeReceiver, WireEnvelope
from device_bridge.firmware import DeviceFirmware
from device_bridge.protocol import AckResult, Command, Fault, Mode, ProtocolError, decode, encode
from device_bridge.soak import soak
from tests.device_bridge.test_firmware import feed, install, status
from tests.helpers.device import frames_of, pair, until


def accepted_shapes() -> list[tuple[int, int]]:
    """Every (speeds, inclines) grid the envelope request accepts: 2-15 per axis, at most 64 nodes."""
    return [(a, b) for a in range(2, 16) for b in range(2, 16) if a * b <= MAX_NODES]


def envelope_of(model, shape: tuple[int, int], mass_kg: float = 75.0):
    return model.propose_envelope(np.linspace(0.6, 1.6, shape[0]), np.linspace(-10.0, 10.0, shape[1]), mass_kg)


def test_the_grid_list_covers_the_corners_of_what_the_api_accepts():
    shapes = accepted_shapes()
    assert (8, 8) in shapes and (15, 4) in shapes and (4, 15) in shapes and (2, 2) in shapes
    assert (9, 8) not in shapes and (16, 2) not in shapes


def test_every_accepted_grid_is_staged_whole_by_the_firmware(model):
    for shape in accepted_shapes():
        env = envelope_of(model, shape)
        fw = DeviceFirmware()
        begin, data, commit, crc = frames_of(env, 3, 40)
        [ack] = feed(fw, [begin, *data, commit], 0.0)
        assert ack["result"] == AckResult.STAGED and ack["crc32"] == crc, shape
        fw.tick(None, 0.001)
        assert fw.active_.envelope == WireEnvelope.from_envelope(env).to_device(), shape
        assert Fault.RECEIVE_ERROR not in fw.faults_


def test_node_63_has_a_check_of_its_own_and_the_axes_check_is_told_apart(model):
    env = envelope_of(model, (8, 8))
    _, data, _, _ = frames_of(env, 1, 2)
    checks = [decode(f)[1] for f in data if decode(f)[0] == "ENVELOPE_CHECK"]
    assert sum(c["target"] == 1 for c in checks) == 1                       # the axes
    assert sorted(c["node"] for c in checks if c["target"] == 0) == list(range(64))


def test_a_fault_while_receiving_aborts_that_transfer_and_keeps_the_running_table(model, tables, monkeypatch):
    fw = DeviceFirmware()
    crc = install(fw, tables[0], 5)
    env = envelope_of(model, (3, 3))
    monkeypatch.setattr(EnvelopeReceiver, "wire", lambda self: {}[(63, 0)])   # the old KeyError, on purpose
    begin, data, commit, _ = frames_of(env, 4, 6)
    [ack] = feed(fw, [begin, *data, commit], 0.01)
    assert ack["result"] == AckResult.DEVICE_ERROR and ack["crc32"] == 0
    assert fw.active_.crc32 == crc and fw.staged_ is None and fw.mode_ == Mode.ACTIVE
    out = fw.receive(encode("DEVICE_COMMAND", {"command": Command.REQUEST_STATUS}), 0.02)
    assert status(out)["active_crc32"] == crc
    health = next(decode(m)[1] for m in out if decode(m)[0] == "DEVICE_HEALTH")
    assert health["fault_flags"] & Fault.RECEIVE_ERROR


def test_a_fault_in_the_control_step_puts_the_leg_in_safe_mode_and_the_loop_goes_on(tables, monkeypatch):
    fw = DeviceFirmware()
    install(fw, tables[0], 5)

    def broken(self, x):
        raise ZeroDivisionError("a controller bug")

    monkeypatch.setattr(type(fw.controller_), "step", broken)
    x = SensorSample(time_s=0.0, knee_angle_rad=0.3, knee_velocity_rad_s=1.0, ankle_angle_rad=0.0,
                     ankle_velocity_rad_s=-1.0, load_N=0.0, ankle_moment_Nm=0.0)
    fw.receive(encode("HOST_HEARTBEAT", {}), 0.01)
    knee, ankle, out = fw.tick(x, 0.011)
    assert fw.mode_ == Mode.SAFE and Fault.CONTROL_ERROR in fw.faults_
    assert knee < 0 and ankle > 0            # passive damping against the motion, not a stopped loop
    assert status(out)["mode"] == Mode.SAFE
    knee2, _, _ = fw.tick(x, 0.012)
    assert knee2 == pytest.approx(knee)


def test_the_receiver_never_raises_a_key_error_for_an_incomplete_transfer(model):
    env = envelope_of(model, (2, 2))
    rx = EnvelopeReceiver(1, 1, WireEnvelope.from_envelope(env).crc32(), 2, 2, 0.0)
    with pytest.raises(ProtocolError, match="missing"):
        rx.wire()


def test_an_8_by_8_envelope_pushed_on_a_running_node_keeps_control_alive(model):
    """On the threads and the bus of the simulated leg: the push is acknowledged and the node's control ticks on."""
    from device_bridge.sim.walker import SimWalker

    walker = SimWalker()
    node, link = pair(leg=walker)
    try:
        until(lambda: link.status is not None, clock=link.clock)
        result = link.push(envelope_of(model, (8, 8)), 9, timeout_s=5.0)
        until(lambda: link.status is not None and link.status.active_crc32 == result.crc32, clock=link.clock)
        seen = link.status.received_monotonic_s
        until(lambda: link.status.received_monotonic_s > seen + 0.15, clock=link.clock)    # the device goes on reporting
        assert link.status.mode == Mode.ACTIVE and node.errors == 0
    finally:
        link.close()
        node.close()


@pytest.mark.parametrize("shape", [(8, 8), (15, 4), (4, 15)])
def test_the_largest_grids_survive_a_faulty_bus(model, shape):
    out = soak([envelope_of(model, shape, m) for m in (70.0, 85.0)], trials=4, drop=0.05, corrupt=0.01,
               reorder=0.05, seed=3, push_timeout_s=6.0)
    assert out["mixed"] == 0 and out["crc_mismatch"] == 0
    assert out["committed"] + out["committed_unconfirmed"] >= 2
