"""The device-link commands: soak and drill."""

from __future__ import annotations

import json

import pytest

from backend.cli import main
from backend.cli.device import accepted_grids


def test_every_grid_the_api_accepts_is_listed_once():
    grids = accepted_grids()
    assert len(grids) == len(set(grids)) == 105
    assert (8, 8) in grids and (15, 4) in grids and (9, 8) not in grids and (1, 5) not in grids


def test_a_soak_on_a_clean_bus_commits_every_push(capsys):
    assert main(["device", "soak", "--trials", "6", "--drop", "0", "--corrupt", "0", "--reorder", "0",
                 "--format", "json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["trials"] == 6 and out["committed"] == 6 and out["mixed"] == out["crc_mismatch"] == 0


@pytest.mark.parametrize(("argv", "words"), [
    (["device", "soak", "--drop", "1.5"], "must be a probability in [0, 1)"),
    (["device", "soak", "--envelopes", "--grids", "16x4"], "not a grid the API accepts"),
    (["device", "soak", "--envelopes", "--grids", "five"], "expected 'every' or shapes like 5x5"),
])
def test_bad_options_are_refused_saying_why(argv, words, capsys):
    with pytest.raises(SystemExit) as exited:
        main(argv)
    assert exited.value.code == 2 and words in capsys.readouterr().err
