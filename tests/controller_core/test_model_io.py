"""Saved models: what an older QuasiTune wrote is refused with a reason; the default model is fitted once."""

from __future__ import annotations

import copy
import threading
import time

import pytest

from controller_core import model_io


def test_a_saved_model_from_before_the_swing_settings_is_refused_with_a_reason(model, tmp_path):
    from controller_core.model_io import load_model, save_model

    old = copy.copy(model)
    old.table_rules_ = copy.copy(model.table_rules_)
    del old.table_rules_.swing_rule         # what a model pickled by an older QuasiTune looks like
    save_model(old, tmp_path / "old")
    with pytest.raises(ValueError, match=r"older QuasiTune.*swing_rule.*quasitune train"):
        load_model(tmp_path / "old")
    save_model(model, tmp_path / "new")
    assert load_model(tmp_path / "new").propose(1.2, 0.0, 75.0).table == model.propose(1.2, 0.0, 75.0).table


def test_a_saved_model_from_before_the_model_was_split_in_parts_is_refused_with_a_reason(model, tmp_path):
    from controller_core.model_io import load_model, save_model

    old = copy.copy(model)
    del old.feature_model_                  # one class held everything before the feature model was a part
    save_model(old, tmp_path / "old")
    with pytest.raises(ValueError, match=r"older QuasiTune.*feature_model_.*quasitune train"):
        load_model(tmp_path / "old")


def test_two_threads_asking_for_the_default_model_at_once_fit_it_once(model, tmp_path, monkeypatch):
    fits: list[int] = []
    started = threading.Barrier(2)

    def counting_fit():
        fits.append(threading.get_ident())
        time.sleep(0.2)          # a fit takes a while: the other thread asks meanwhile
        return model

    monkeypatch.setenv("QUASITUNE_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(model_io, "train_default", counting_fit)
    got: list[object] = []

    def ask() -> None:
        started.wait()
        got.append(model_io.load_default_model())

    threads = [threading.Thread(target=ask) for _ in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(60)
    assert len(fits) == 1 and len(got) == 2          # the second read what the first fitted and cached
    assert all(m.model_version == model.model_version for m in got)


# a process that asks for the default model; its fit (train_default) is counted in the file it is given and stands
# in for the real one by a model saved before (a fit takes seconds: the other process asks meanwhile)
_ASK = """
import sys, time
from controller_core import model_io
def counting():
    with open(sys.argv[1], "a") as f:
        f.write("fit\\n")
    time.sleep(1.0)
    return model_io.load_model(sys.argv[2])
model_io.train_default = counting
model_io.load_default_model()
"""


def test_two_processes_asking_for_the_default_model_at_once_on_an_empty_cache_fit_it_once(model, tmp_path):
    import os
    import subprocess
    import sys

    fits, saved = tmp_path / "fits.txt", model_io.save_model(model, tmp_path / "saved")
    env = {**os.environ, "QUASITUNE_CACHE_DIR": str(tmp_path / "cache")}
    procs = [subprocess.Popen([sys.executable, "-c", _ASK, str(fits), str(saved)], env=env) for _ in range(2)]
    assert [p.wait(120) for p in procs] == [0, 0]
    assert fits.read_text().splitlines() == ["fit"]          # the other waited and read the one fitted
