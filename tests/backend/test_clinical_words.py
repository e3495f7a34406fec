"""Settings and limits in the words a prosthetist uses."""

from __future__ import annotations

from backend.clinical_words import field_words, unit_of, violation_words
from controller_core.table import LimitViolation


def test_every_field_key_has_words_and_a_unit():
    assert field_words("knee.stance_flexion.k_Nm_per_rad") == \
        "knee stance flexion resistance (loading response): resistance K"
    assert field_words("thresholds.we_to_sf_load_N") == "heel strike: load above"
    assert field_words("not.a.field") == "not.a.field"
    assert [unit_of(f) for f in ("knee.swing_flexion.b_Nm_s_per_rad", "ankle.stance_extension.theta_e_deg",
                                 "thresholds.sf_to_se_ankle_moment_Nm", "thresholds.min_state_time_s",
                                 "thresholds.sf_to_se_knee_extension_deg_per_s")] == ["N·m·s/rad", "°", "N·m", "s",
                                                                                     "deg/s"]


def test_a_violation_reads_without_field_keys():
    v = LimitViolation(field="knee.stance_flexion.k_Nm_per_rad", value=12.0, low=-1200.0, high=0.0,
                       message="knee.stance_flexion.k_Nm_per_rad = 12 is outside [-1200, 0]")
    words = violation_words(v)
    assert "knee stance flexion resistance" in words and "12" in words and "k_Nm_per_rad" not in words
    rule = LimitViolation(field="neighbours[1.2 m/s, 0 deg | 1.2 m/s, 5 deg].knee.stance_flexion.k_Nm_per_rad",
                          value=350.0, low=0.0, high=300.0, message="too far apart")
    words = violation_words(rule)
    assert "between the neighbouring tasks 1.2 m/s, 0° and 1.2 m/s, 5°" in words and "at most 300 N·m/rad" in words


def test_the_page_reads_the_servers_words_and_keeps_no_copy_of_its_own(tmp_path):
    """One copy of the words (issue 57): the dashboard imports the server's file as it serves it, and no script of
    the dashboard spells a setting's name itself."""
    import json
    from pathlib import Path

    from fastapi import FastAPI
    from fastapi.testclient import TestClient

    from backend.clinical_words import ROW_WORDS, THRESHOLD_WORDS, WORDS_PATH
    from backend.frontend import mount_frontend

    frontend = Path(__file__).resolve().parents[2] / "frontend"
    app = FastAPI()
    mount_frontend(app, frontend)
    served = TestClient(app).get("/clinical_words.json")
    assert served.status_code == 200 and served.headers["content-type"].startswith("application/json")
    assert served.json() == json.loads(WORDS_PATH.read_text(encoding="utf-8"))
    scripts = {p: p.read_text(encoding="utf-8") for p in (frontend / "app").rglob("*.js")}
    assert 'import CLINICAL_WORDS from "/clinical_words.json" with { type: "json" }' in scripts[frontend / "app/ui.js"]
    for words in (*ROW_WORDS.values(), *THRESHOLD_WORDS.values()):
        spelled = [p.name for p, text in scripts.items() if words in text]
        assert not spelled, f"{words!r} is spelled in {spelled}: the page takes it from the server's words"
