"""Helpers shared by the API tests: an in-process app with one user per role on a temporary database."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from fastapi.testclient import TestClient

from backend.app import create_app
from backend.db import connect
from backend.settings import Settings
from backend.store.users import ROLES, create_user

PASSWORD = "correct-horse-battery"


@dataclass
class Api:
    client: TestClient
    data_dir: Path
    headers: dict[str, dict[str, str]] = field(default_factory=dict)

    def as_(self, role: str) -> dict[str, str]:
        return self.headers[role]

    def db(self):
        return connect(self.data_dir / "quasitune.sqlite")

    def new_patient(self, code: str = "P-001", mass: float = 80.0) -> dict:
        r = self.client.post("/api/patients", headers=self.as_("prosthetist"),
                             json={"code_name": code, "body_mass_kg": mass, "side": "left", "height_m": 1.78,
                                   "k_level": 3})
        assert r.status_code == 201, r.text
        return r.json()

    def propose(self, patient_id: int, speed: float = 1.2, incline: float = 0.0) -> dict:
        r = self.client.post(f"/api/patients/{patient_id}/proposals", headers=self.as_("prosthetist"),
                             json={"speed_mps": speed, "incline_deg": incline})
        assert r.status_code == 201, r.text
        return r.json()


def make_api(data_dir: Path, model_loader, **settings) -> tuple[Api, TestClient]:
    """App on ``data_dir`` loading its model with ``model_loader``, with users prosthetist/viewer/admin
    (password :data:`PASSWORD`), signed in."""
    app = create_app(Settings(data_dir=data_dir, **settings), model_loader=model_loader)
    conn = connect(data_dir / "quasitune.sqlite")
    for role in ROLES:
        create_user(conn, role, role, PASSWORD)
    conn.close()
    client = TestClient(app)
    api = Api(client=client, data_dir=data_dir)
    for role in ROLES:
        r = client.post("/api/auth/token", data={"username": role, "password": PASSWORD})
        assert r.status_code == 200, r.text
        api.headers[role] = {"Authorization": f"Bearer {r.json()['access_token']}"}
    return api, client
