"""Which device a server talks to."""

from __future__ import annotations

import pytest

from backend.devices.specs import SIM_DEVICE_ID, parse_device_spec


def test_none_sim_and_a_real_bus():
    assert parse_device_spec(" none ") is None
    a, b = parse_device_spec("sim"), parse_device_spec("sim")
    assert a.device_id == SIM_DEVICE_ID and a.kind == "simulated" and a.interface == "virtual"
    assert a.channel != b.channel                            # each simulated leg on a bus of its own
    real = parse_device_spec("socketcan:can0")
    assert (real.device_id, real.kind, real.interface, real.channel) == ("socketcan-can0", "can", "socketcan", "can0")


def test_a_channel_becomes_a_safe_device_id():
    spec = parse_device_spec("pcan:PCAN USB/BUS1")
    assert spec.device_id == "pcan-PCAN-USB-BUS1" and spec.channel == "PCAN USB/BUS1"


@pytest.mark.parametrize("text", ["", "can0", "bogus:", ":can0"])
def test_a_bad_spec_says_what_is_expected(text):
    with pytest.raises(ValueError, match="device must be 'sim', 'none' or"):
        parse_device_spec(text)


def test_a_list_of_devices_one_instance_serves():
    from backend.devices.specs import parse_device_specs

    specs = parse_device_specs("mqtt:leg-1, mqtt:leg-2,socketcan:can0")
    assert [s.device_id for s in specs] == ["leg-1", "leg-2", "socketcan-can0"]
    assert parse_device_specs("none") == [] and [s.kind for s in parse_device_specs("sim")] == ["simulated"]
    for bad, why in (("mqtt:leg-1,mqtt:leg-1", "more than once"), ("none,mqtt:leg-1", "'none' is a device list"),
                     ("mqtt:leg-1,bogus", "device must be")):
        with pytest.raises(ValueError, match=why):
            parse_device_specs(bad)
