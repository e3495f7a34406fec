"""A table from a file: what predict prints or the API returns, read back as the table it was."""

from __future__ import annotations

import json

import pytest

from device_bridge.bench.table_file import read_table_file


def test_predicts_json_reads_back_as_its_table(model, tmp_path):
    proposal = model.propose(1.2, 0.0, 75.0)
    path = tmp_path / "t.json"
    path.write_text(json.dumps(proposal.to_dict()))
    table = read_table_file(path)
    for row in proposal.table.rows:
        got = table.row(row.joint, row.subphase)
        # the JSON carries what the prosthetist reads (k to 0.01 N·m/rad, θe to 0.001°)
        assert got.k_Nm_per_rad == pytest.approx(row.k_Nm_per_rad, abs=0.01)
        assert got.theta_e_deg == pytest.approx(row.theta_e_deg, abs=0.001)
        assert got.b_Nm_s_per_rad == pytest.approx(row.b_Nm_s_per_rad, abs=0.01)
    assert table.thresholds.we_to_sf_load_N == pytest.approx(proposal.table.thresholds.we_to_sf_load_N)
    assert table.body_mass_kg == 75.0 and table.provenance.speed_mps == 1.2


@pytest.mark.parametrize(("content", "words"), [
    ("{", "not JSON"), ("[1, 2]", "JSON object"), ('{"task": {}}', "missing table, thresholds"),
    ('{"task": {"speed_mps": 1.2}, "table": [], "thresholds": {}}', "not a valid table"),
])
def test_a_bad_file_is_refused_saying_what_is_wrong(tmp_path, content, words):
    path = tmp_path / "bad.json"
    path.write_text(content)
    with pytest.raises(ValueError, match=words):
        read_table_file(path)
    with pytest.raises(ValueError, match="No such file"):
        read_table_file(tmp_path / "absent.json")
