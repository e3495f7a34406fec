"""Training, saving and loading models; the default model trained on the shipped data.

A model directory holds ``model.joblib`` (the fitted estimator; a trusted local artifact: joblib files
execute code when loaded, so only load directories you produced) and ``model.json`` (version, data hash,
training records, for people). The default model is fitted from the shipped data on first use (a few
seconds) and cached per user, keyed by the data hash and a hash of this package's source code, so a code
change never reuses a stale model.
"""

from __future__ import annotations

import contextlib
import hashlib
import inspect
import json
import os
import shutil
import tempfile
import threading
from collections.abc import Iterator
from pathlib import Path

import joblib

from controller_core.model import QuasiStiffnessModel
from controller_core.phase_table import SHIPPED_RAMPS_CSV, load_phase_table, load_shipped_ramps
from controller_core.published_features import incline_table_sha256, published_points
from controller_core.reference import ReferenceSet, data_dir, load_shipped_reference, sha256_of

PACKAGE_VERSION = "0.1.0"
MODEL_FILE = "model.joblib"
META_FILE = "model.json"


def code_sha256() -> str:
    """Hash of the controller_core sources (part of the model version)."""
    h = hashlib.sha256()
    for p in sorted(Path(__file__).resolve().parent.glob("*.py")):
        h.update(p.name.encode())
        h.update(p.read_bytes())
    return h.hexdigest()


def self_selected_knee_extensor(reference: ReferenceSet) -> tuple[float, float] | None:
    """(speed, level knee extensor peak) of the record labelled self-selected, for the Kuster ratio."""
    from controller_core.features import FEATURES_BY_NAME, find_extremum

    for rec in reference.records:
        if "self-selected" in rec.name.lower() and rec.task.get("incline_deg", 0.0) == 0.0:
            spec = FEATURES_BY_NAME["knee_extensor_moment_peak"]
            return rec.task["speed_mps"], find_extremum(rec.phase, rec.mean["knee_moment"], spec)[1]
    return None


def train(reference: ReferenceSet, use_published: bool, ramps: ReferenceSet | None = None,
          **params) -> QuasiStiffnessModel:
    """Fit a model on a reference set, plus the shipped published incline features if asked, plus one person's
    ramp walking (the change a slope makes) if given. ``params``: :class:`QuasiStiffnessModel`'s settings."""
    published = published_points(self_selected_knee_extensor(reference)) if use_published else None
    version = f"quasitune-{PACKAGE_VERSION}+{code_sha256()[:8]}"
    return QuasiStiffnessModel(**({"model_version": version} | params)).fit(reference, published, ramps)


def train_default() -> QuasiStiffnessModel:
    """The default model: Bovi 2011 adult level walking, the published incline features and the Vielemeyer 2025
    ramp curves."""
    return train(load_shipped_reference(), use_published=True, ramps=load_shipped_ramps())


def train_from_file(path: str | Path, use_published: bool = False, ramps: str | Path | None = None
                    ) -> QuasiStiffnessModel:
    """Fit a model from a standard-format table (CSV/Parquet), and optionally one person's ramp walking in the
    same format (level and sloped conditions)."""
    return train(load_phase_table(path), use_published=use_published,
                 ramps=None if ramps is None else load_phase_table(ramps))


def save_model(model: QuasiStiffnessModel, directory: str | Path) -> Path:
    """Write a model directory atomically (a temporary directory renamed into place)."""
    target = Path(directory)
    target.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=".model-", dir=target.parent))
    try:
        joblib.dump(model, tmp / MODEL_FILE)
        meta = {
            "model_version": model.model_version, "data_sha256": model.data_sha256_,
            "records": [r.name for r in model.reference_.records],
            "tasks": model.train_tasks_.tolist(),
            "published_points": [{"feature": p.feature, "source": p.source, "speed_mps": p.speed_mps,
                                  "incline_deg": p.incline_deg} for p in model.published_],
            "provenance": {k: v for k, v in model.reference_.provenance.items() if k != "conventions"},
        }
        (tmp / META_FILE).write_text(json.dumps(meta, indent=2, default=str))
        if target.exists():
            shutil.rmtree(target)
        os.replace(tmp, target)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return target


def load_model(directory: str | Path) -> QuasiStiffnessModel:
    """Load a model directory written by :func:`save_model`."""
    path = Path(directory) / MODEL_FILE
    if not path.exists():
        raise FileNotFoundError(f"no model at {directory!s} (expected {MODEL_FILE}); "
                                "create one with 'quasitune train'")
    model = joblib.load(path)
    if not isinstance(model, QuasiStiffnessModel):
        raise ValueError(f"{path} does not hold a QuasiStiffnessModel")
    parts = [model, *(getattr(model, name, None) for name in ("feature_model_", "joint_reference_", "table_rules_"))]
    missing = [p for part in parts for p in _settings(part) if not hasattr(part, p)]
    if missing:
        raise ValueError(f"the model at {directory!s} was trained by an older QuasiTune and lacks the settings "
                         f"{', '.join(missing)}; re-train it with 'quasitune train'")
    return model


def _settings(estimator: object) -> list[str]:
    """The constructor settings an estimator must carry (every one, for a part the model lacks altogether)."""
    if estimator is None:
        return ["feature_model_", "joint_reference_", "table_rules_"]
    return [p for p in inspect.signature(type(estimator).__init__).parameters if p not in ("self", "args", "kwargs")]


def cache_dir() -> Path:
    """Per-user cache directory (``QUASITUNE_CACHE_DIR`` overrides)."""
    env = os.environ.get("QUASITUNE_CACHE_DIR")
    if env:
        return Path(env)
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "quasitune"


# one fit of the default model at a time in a process: a server's background loader and a command (or a test) asking at
# once would each fit it (5-15 s on a 2-core machine); the second now finds the first's in the cache
_DEFAULT_FIT = threading.Lock()


@contextlib.contextmanager
def _fit_lock(directory: Path) -> Iterator[None]:
    """One fit at a time across processes too (an advisory ``flock`` beside the cache entry, the standard library's):
    servers, commands and test processes started together on an empty cache each fitted the same model at once. Where
    the lock file cannot be made (a read-only cache) or ``fcntl`` does not exist, the fit goes on unlocked."""
    try:
        import fcntl
        directory.parent.mkdir(parents=True, exist_ok=True)
        handle = open(directory.with_name(directory.name + ".lock"), "a")  # noqa: SIM115 (held until the fit ends)
    except (ImportError, OSError):
        yield
        return
    with handle:
        fcntl.flock(handle, fcntl.LOCK_EX)
        yield


def load_default_model(refit: bool = False) -> QuasiStiffnessModel:
    """The default model, from the per-user cache or fitted now (and cached) from the shipped data."""
    ref_hash = load_shipped_reference().data_sha256
    ramps_hash = sha256_of(data_dir() / SHIPPED_RAMPS_CSV)
    key = hashlib.sha256((ref_hash + incline_table_sha256() + ramps_hash + code_sha256()).encode()).hexdigest()[:16]
    directory = cache_dir() / "models" / key
    with _DEFAULT_FIT, _fit_lock(directory):
        if not refit and (directory / MODEL_FILE).exists():
            try:
                return load_model(directory)
            except Exception:  # a corrupt cache entry is rebuilt, never trusted
                shutil.rmtree(directory, ignore_errors=True)
        model = train_default()
        with contextlib.suppress(OSError):  # a read-only home still gets a working (uncached) model
            save_model(model, directory)
        return model
