"""QuasiTune backend: the FastAPI application (``backend.app``), its storage and the ``quasitune`` CLI."""

__version__ = "0.1.0"
