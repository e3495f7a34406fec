"""The model service: background load, status, and the heap freeze once the model is in."""

from __future__ import annotations

import gc
import weakref

import pytest

from backend import model_service
from backend.errors import ServiceUnavailableError
from backend.model_service import ModelService, freeze_long_lived_objects


class _Node:
    pass


def test_freezing_collects_garbage_first_and_freezes_what_is_alive():
    garbage = _Node()
    garbage.me = garbage                     # a reference cycle that only the cyclic collector frees
    gone = weakref.ref(garbage)
    before = gc.get_freeze_count()
    del garbage
    freeze_long_lived_objects()
    assert gone() is None                    # collected, not frozen with the rest
    assert gc.get_freeze_count() > before


def test_the_service_freezes_the_heap_after_a_load_and_not_after_a_failed_one(model, monkeypatch):
    calls = []
    monkeypatch.setattr(model_service, "freeze_long_lived_objects", lambda: calls.append("freeze"))
    ok = ModelService(lambda: model).start()
    assert ok.get(30.0) is model and ok.status == "ready"
    ok._thread.join(30.0)                    # the freeze runs in the loader thread, after the model is set
    assert calls == ["freeze"]

    def broken():
        raise OSError("no model file")

    failed = ModelService(broken).start()
    with pytest.raises(ServiceUnavailableError, match="no model file"):
        failed.get(30.0)
    failed._thread.join(30.0)
    assert failed.status == "failed" and calls == ["freeze"]
