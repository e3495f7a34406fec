"""What the bench's commands (the product's and the lab's) read from their command line and how they write results."""

from __future__ import annotations

import json

import pytest

from device_bridge.bench.command_line import leg_named, write_json


def test_json_is_written_into_a_new_folder_and_said_so(tmp_path, capsys):
    write_json(tmp_path / "a" / "b.json", {"x": [1, 2]})
    assert json.loads((tmp_path / "a" / "b.json").read_text()) == {"x": [1, 2]}
    assert "wrote" in capsys.readouterr().out


def test_a_leg_is_named_by_file_or_repository_name_and_none_is_the_nominal_bench():
    assert leg_named(None) is None
    assert leg_named("short_person").body_height_m == 1.58
    with pytest.raises(ValueError, match="nope"):
        leg_named("nope")
