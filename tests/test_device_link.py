"""Host and device on a python-can virtual bus, each in its own thread, as they run in the app."""

from __future__ import annotations

import threading
import time

import can
import pytest

from controller_core.table import ParameterTable
from controller_core.walking_reference import level_walking_reference
from device_bridge.device_node import DeviceNode
from device_bridge.firmware import FirmwareConfig
from device_bridge.host import DeviceLink, PushError, TelemetrySample
from device_bridge.protocol import Command, Mode, WireTable
from device_bridge.sim.walker import SimWalker
from device_bridge.soak import soak

_n = iter(range(10**6))


def pair(config: FirmwareConfig | None = None, leg=None, **link_kwargs) -> tuple[DeviceNode, DeviceLink]:
    channel = f"test-link-{next(_n)}"
    node = DeviceNode(can.Bus(interface="virtual", channel=channel), leg=leg, config=config).start()
    link = DeviceLink(can.Bus(interface="virtual", channel=channel), **link_kwargs).start()
    return node, link


def wait_for(predicate, timeout_s: float = 5.0) -> None:
    deadline = time.monotonic() + timeout_s
    while not predicate():
        assert time.monotonic() < deadline, "condition not reached in time"
        time.sleep(0.002)


@pytest.fixture(scope="module")
def tables(model) -> list[ParameterTable]:
    return [model.propose(s, 0.0, 75.0).table for s in (1.0, 1.5)]


def test_a_push_returns_the_crc_the_device_then_reports_active(tables):
    node, link = pair()
    try:
        result = link.push(tables[0], version=42)
        assert result.crc32 == WireTable.from_table(tables[0]).crc32() and result.version == 42
        wait_for(lambda: link.status is not None and link.status.active_crc32 == result.crc32)
        assert link.status.mode == Mode.ACTIVE and link.status.active_version == 42
        assert node.snapshot().active.crc32 == result.crc32
    finally:
        link.close()
        node.close()


def test_pushes_through_a_faulty_bus_never_leave_a_mixed_table(tables):
    out = soak(40, drop=0.1, corrupt=0.05, reorder=0.05, seed=7, tables=tables)
    assert out["mixed"] == 0 and out["crc_mismatch"] == 0
    assert out["committed"] + out["kept_old"] + out["committed_unconfirmed"] == 40
    assert out["committed"] >= 30   # retries get nearly all of them through
    assert out["frames"]["host"]["dropped"] > 0 and out["frames"]["host"]["corrupted"] > 0


def test_a_table_the_device_finds_unsafe_is_refused_and_the_old_one_stays(tables):
    node, link = pair()
    try:
        old = link.push(tables[0], version=1).crc32
        row = tables[1].rows[0]
        unsafe = tables[1].model_copy(update={"rows": [row.model_copy(update={"b_Nm_s_per_rad": 60.0}),
                                                       *tables[1].rows[1:]]})
        with pytest.raises(PushError, match="outside its own safety limits") as err:
            link.push(unsafe, version=2)
        assert err.value.reason == "safety_limit"
        assert node.snapshot().active.crc32 == old and node.snapshot().staged is None
    finally:
        link.close()
        node.close()


def test_a_push_to_a_silent_bus_times_out_with_a_reason(tables):
    link = DeviceLink(can.Bus(interface="virtual", channel=f"test-link-{next(_n)}")).start()
    try:
        t0 = time.monotonic()
        with pytest.raises(PushError, match="keeps its previous table") as err:
            link.push(tables[0], version=1, timeout_s=0.3)
        assert err.value.reason == "timeout" and time.monotonic() - t0 < 1.0
    finally:
        link.close()


def test_heartbeat_loss_is_reported_as_safe_mode_and_a_command_resumes(tables):
    node, link = pair(FirmwareConfig(heartbeat_timeout_s=0.1))
    try:
        link.push(tables[0], version=1)
        wait_for(lambda: link.status is not None and link.status.mode == Mode.ACTIVE)
        link.pause_heartbeat(True)
        wait_for(lambda: link.status.mode == Mode.SAFE)
        entered = node.snapshot().safe_mode_entered_s
        assert entered - node.snapshot().last_heartbeat_s == pytest.approx(0.1, abs=0.02)
        link.pause_heartbeat(False)
        time.sleep(0.05)
        assert link.status.mode == Mode.SAFE
        link.command(Command.LEAVE_SAFE_MODE)
        wait_for(lambda: link.status.mode == Mode.ACTIVE)
    finally:
        link.close()
        node.close()


def test_the_walking_simulated_leg_streams_telemetry_without_gaps(tables):
    walker = SimWalker()
    got: list[TelemetrySample] = []
    lock = threading.Lock()

    def on_telemetry(sample: TelemetrySample) -> None:
        with lock:
            got.append(sample)

    node, link = pair(leg=walker, on_telemetry=on_telemetry)
    try:
        link.push(tables[0], version=3)
        walker.start(level_walking_reference(1.2), 75.0)
        wait_for(lambda: len(got) >= 150, timeout_s=10.0)
    finally:
        link.close()
        node.close()
    seqs = [s.seq for s in got]
    assert seqs == list(range(seqs[0], seqs[0] + len(seqs)))
    knee = [s.knee_angle_rad for s in got]
    assert max(knee) - min(knee) > 0.2   # the knee moves (about 11° or more of swing in 1.5 s of walking)
    assert {s.mode for s in got} == {Mode.ACTIVE} and {s.fsm_state for s in got} >= {0, 1}


def test_a_failing_callback_does_not_stop_the_link(tables):
    def broken(_status) -> None:
        raise RuntimeError("dashboard bug")

    node, link = pair(on_status=broken)
    try:
        wait_for(lambda: link.callback_errors > 0)
        assert link.push(tables[0], version=5).crc32 == WireTable.from_table(tables[0]).crc32()
    finally:
        link.close()
        node.close()
