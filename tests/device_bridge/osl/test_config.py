"""The leg's configuration file: read, checked field by field, refused with every bad field named."""

from __future__ import annotations

import pytest

from device_bridge.osl.config import LegConfigError, load_config, parse_config

GOOD = """
rate_hz = 500
link = "socketcan:can0"

[knee]
actuator = "knee"
encoder = "knee_joint"
gear_ratio = 41.4999

[ankle]
actuator = "ankle"
gear_ratio = 41.4999
"""


def test_a_leg_file_is_read_with_its_defaults(tmp_path):
    path = tmp_path / "leg.toml"
    path.write_text(GOOD)
    cfg = load_config(path)
    assert cfg.period_s == pytest.approx(0.002) and cfg.knee.encoder == "knee_joint" and cfg.ankle.encoder is None
    assert cfg.torque_mode == "current" and cfg.overruns_to_safe == 5
    assert not cfg.calibration.knee.calibrated and cfg.calibration.loadcell.fz_sign == 1


@pytest.mark.parametrize(("patch", "named"), [
    ({"rate_hz": 20_000}, "rate_hz"),
    ({"link": "can0"}, "link must be INTERFACE:CHANNEL"),
    ({"knee": {"actuator": "knee", "gear_ratio": -3}}, "knee.gear_ratio"),
    ({"torque_mode": "impedance"}, "torque_mode"),
    ({"calibration": {"knee": {"sign": 2}}}, "calibration.knee.sign"),
    ({"ankle": {"actuator": "ankle", "gear_ratio": 41.5, "speed": 3}}, "ankle.speed"),
])
def test_a_bad_field_is_refused_by_name(patch, named):
    base = {"knee": {"actuator": "knee", "gear_ratio": 41.5}, "ankle": {"actuator": "ankle", "gear_ratio": 41.5}}
    with pytest.raises(LegConfigError, match=named.replace(".", r"\.")):
        parse_config({**base, **patch})


def test_a_file_that_is_not_toml_says_where(tmp_path):
    path = tmp_path / "leg.toml"
    path.write_text("rate_hz = = 5\n")
    with pytest.raises(LegConfigError, match="not TOML"):
        load_config(path)


def test_a_calibration_is_kept_beside_the_leg_file_and_read_back_with_it(tmp_path):
    from device_bridge.osl.config import Calibration, JointCalibration, calibration_path, save_calibration

    path = tmp_path / "leg.toml"
    path.write_text(GOOD)
    cal = Calibration(knee=JointCalibration(sign=-1, zero_rad=0.52, torque_sign=1, calibrated=True))
    kept = save_calibration(path, cal)
    assert kept == calibration_path(path) == tmp_path / "leg.calibration.json"
    assert load_config(path).calibration == cal
    kept.write_text("{not json")
    with pytest.raises(LegConfigError, match="not JSON"):
        load_config(path)
