"""The model service: background load, status, and the heap freeze once the model is in."""

from __future__ import annotations

import gc
import weakref

import pytest

from backend.errors import ServiceUnavailableError
from backend.model_service import ModelService


class _Node:
    pass


def test_the_loaded_model_and_everything_alive_then_are_frozen_out_of_the_cyclic_collector(model):
    garbage = _Node()
    garbage.me = garbage                     # a reference cycle that only the cyclic collector frees
    gone = weakref.ref(garbage)
    before = gc.get_freeze_count()
    del garbage
    service = ModelService(lambda: model).start()
    assert service.get(30.0) is model and service.status == "ready"
    # the freeze happens after the load, in the loader thread: wait for it through the thread
    service._thread.join(30.0)
    assert gc.get_freeze_count() > before
    assert gone() is None                    # garbage is collected first, not frozen with the model


def test_a_model_that_fails_to_load_is_reported_and_nothing_is_frozen():
    before = gc.get_freeze_count()

    def broken():
        raise OSError("no model file")

    service = ModelService(broken).start()
    with pytest.raises(ServiceUnavailableError, match="no model file"):
        service.get(30.0)
    assert service.status == "failed" and gc.get_freeze_count() == before
