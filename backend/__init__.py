"""QuasiTune backend: command-line interface now, FastAPI application later (issue 4)."""
