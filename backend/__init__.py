"""QuasiTune backend: the FastAPI application (``backend.app``), its storage and the ``quasitune`` CLI."""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("quasitune")   # the one version string: pyproject.toml's
except PackageNotFoundError:             # a source tree that was never installed
    __version__ = "unknown"
