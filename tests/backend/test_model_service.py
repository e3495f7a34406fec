"""The model loaded in the background, kept out of the cyclic collector's walks once loaded."""

from __future__ import annotations

import gc
import weakref

import pytest

from backend.errors import ServiceUnavailableError
from backend.model_service import ModelService


class _Node:
    pass


def test_after_a_load_garbage_is_gone_and_the_model_is_no_longer_walked_by_the_collector(model):
    garbage = _Node()
    garbage.me = garbage                     # a reference cycle that only the cyclic collector frees
    gone = weakref.ref(garbage)
    del garbage
    service = ModelService(lambda: model).start()
    assert service.get(30.0) is model and service.status == "ready"
    service._thread.join(30.0)              # the loader thread finishes after handing the model over
    assert gone() is None                    # collected, not kept alive with the long-lived heap
    assert not any(o is model for o in gc.get_objects())    # a full collection no longer walks it


def test_a_failed_load_is_reported_to_every_request():
    def broken():
        raise OSError("no model file")

    failed = ModelService(broken).start()
    with pytest.raises(ServiceUnavailableError, match="no model file"):
        failed.get(30.0)
    assert failed.status == "failed" and failed.version is None
