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


GEOMETRY = {"thigh_length_m": 0.45, "shank_length_m": 0.41, "forefoot_m": 0.12}
BASE = {"knee": {"actuator": "knee", "gear_ratio": 41.5}, "ankle": {"actuator": "ankle", "gear_ratio": 41.5}}


def test_a_leg_with_a_thigh_sensor_needs_its_lengths_and_the_firmware_runs_the_files():
    """With a thigh sensor the leg estimates its task, from the thigh's and the shank's lengths and the foot's
    forefoot: the file must give them (the firmware's defaults are the simulated bench's leg, not the patient's), and
    the firmware `quasitune leg` starts is given the file's (its adaptive controller's estimator is built from them);
    without a thigh it keeps its defaults (no task estimate). The ankle drive's friction goes to the firmware too."""
    from device_bridge.firmware import FirmwareConfig
    from device_bridge.osl.cli import firmware_config

    with pytest.raises(LegConfigError, match=r"geometry: a leg with a thigh sensor .* thigh_length_m"):
        parse_config({**BASE, "thigh": "imu"})
    cfg = parse_config({**BASE, "thigh": "imu", "geometry": GEOMETRY})
    fw = firmware_config(cfg)
    assert (fw.thigh_length_m, fw.shank_length_m, fw.forefoot_m) == (0.45, 0.41, 0.12)
    plain = firmware_config(parse_config(BASE))
    assert plain.thigh_length_m == FirmwareConfig().thigh_length_m != 0.45 and plain.actuator.ankle_friction_Nm == 0.0
    assert firmware_config(parse_config({**BASE, "ankle_friction_Nm": 2.5})).actuator.ankle_friction_Nm == 2.5
    with pytest.raises(LegConfigError, match="ankle_friction_Nm"):
        parse_config({**BASE, "ankle_friction_Nm": -1.0})


@pytest.mark.parametrize(("field", "value"), [
    ("thigh_length_m", 1.2), ("shank_length_m", 0.0), ("forefoot_m", -0.1), ("forefoot_m", float("nan")),
])
def test_an_impossible_length_is_refused_by_name(field, value):
    with pytest.raises(LegConfigError, match=rf"geometry\.{field}"):
        parse_config({**BASE, "thigh": "imu", "geometry": {**GEOMETRY, field: value}})


def test_the_shipped_leg_files_load_and_the_bench_file_has_the_benchs_lengths():
    from pathlib import Path

    from device_bridge.sim.leg_model import LegGeometry

    docs = Path(__file__).parents[3] / "docs"
    assert load_config(docs / "leg.example.toml").geometry is None           # no thigh sensor: no task estimate
    g, bench = load_config(docs / "leg.bench.toml").geometry, LegGeometry()
    assert g.thigh_length_m == pytest.approx(bench.thigh_m) and g.shank_length_m == pytest.approx(bench.shank_m)
    assert g.forefoot_m == pytest.approx(bench.toe_forward_m)
