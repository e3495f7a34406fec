"""The learning model, loaded (or fitted) in a background thread so the server answers at once.

Requests that need the model wait for it up to ``Settings.model_wait_s`` and then get a 503 with a
``Retry-After``; ``/api/health`` reports ``loading``, ``ready`` or ``failed``.
"""

from __future__ import annotations

import gc
import logging
import threading
from collections.abc import Callable

from backend.errors import ServiceUnavailableError
from controller_core import QuasiStiffnessModel

log = logging.getLogger("quasitune.model")


def freeze_long_lived_objects() -> None:
    """Take every object alive now (the model, the imported modules) out of the cyclic garbage collector's walks;
    they live as long as the process.

    A full collection walks every tracked object, and with the model loaded that stalls every request in flight
    (``python -m benchmarks api`` shows the tail). ``gc.freeze()`` is the standard library's remedy for long-lived
    heaps; collecting first keeps garbage from being frozen with them. Objects created later are collected as usual.
    """
    gc.collect()
    gc.freeze()


class ModelService:
    def __init__(self, loader: Callable[[], QuasiStiffnessModel]) -> None:
        self._loader = loader
        self._ready = threading.Event()
        self._model: QuasiStiffnessModel | None = None
        self._error: str | None = None
        self._thread = threading.Thread(target=self._load, name="model-loader", daemon=True)

    def start(self) -> ModelService:
        self._thread.start()
        return self

    def _load(self) -> None:
        try:
            self._model = self._loader()
            log.info("model %s ready", self._model.model_version)
            freeze_long_lived_objects()
        except Exception as exc:  # reported by /api/health and by every request that needs the model
            log.exception("model failed to load")
            self._error = f"{type(exc).__name__}: {exc}"
        finally:
            self._ready.set()

    @property
    def status(self) -> str:
        if not self._ready.is_set():
            return "loading"
        return "ready" if self._model is not None else "failed"

    @property
    def version(self) -> str | None:
        return None if self._model is None else self._model.model_version

    def get(self, timeout_s: float) -> QuasiStiffnessModel:
        """The model, waiting up to ``timeout_s`` for it to load."""
        if not self._ready.wait(timeout_s):
            raise ServiceUnavailableError("the model is still loading; try again in a few seconds", retry_after_s=5)
        if self._model is None:
            raise ServiceUnavailableError(f"the model failed to load: {self._error}")
        return self._model
