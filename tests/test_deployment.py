"""docker-compose.yml describes the deployment: checked structurally here, and by `docker-compose config -q`
where that command exists (it does not on every CI machine)."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[1]


def test_compose_runs_the_api_with_its_database_on_a_volume():
    compose = yaml.safe_load((ROOT / "docker-compose.yml").read_text())
    api = compose["services"]["api"]
    data_volume = next(v for v in api["volumes"] if v.endswith(":/data"))
    assert data_volume.split(":")[0] in compose["volumes"]
    assert api["environment"]["QUASITUNE_DATA_DIR"] == "/data"
    assert (ROOT / api["environment"]["QUASITUNE_MIGRATIONS_DIR"].removeprefix("/src/")).is_dir()
    assert "quasitune serve" in api["command"] and any(p.startswith("127.0.0.1:") for p in api["ports"])


@pytest.mark.skipif(shutil.which("docker-compose") is None, reason="docker-compose is not installed here")
def test_docker_compose_config_is_valid():
    r = subprocess.run(["docker-compose", "config", "-q"], cwd=ROOT, capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
