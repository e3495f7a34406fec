"""The printed table of the stance-response study."""

from __future__ import annotations

from lab.stance_response import format_stance_response


def _walk(peak, stay, torque, falls=0):
    return {"stance_knee_flexion_peak_deg": peak, "stance_flexion_stay_ms": stay,
            "knee_torque_leaving_stance_flexion_Nm": torque, "falls": falls, "hip_sink_max_mm": 12.0,
            "support_deficit_max_bw": 0.5}


def test_each_row_shows_both_walks_the_response_and_the_walk_without_knee_support_where_there_is_one():
    rows = [{"person": "p", "table": "learned", "response_deg": 2.04,
             "by_stance_flexion_k_Nm_per_rad": {"-50": _walk(24.0, 162.0, -12.6), "-300": _walk(22.0, 159.0, -56.3)},
             "no_knee_support": {**_walk(25.0, 170.0, -1.0, falls=1), "hip_sink_max_mm": 46.2}},
            {"person": "p", "table": "FSMIC", "response_deg": None,
             "by_stance_flexion_k_Nm_per_rad": {"-50": _walk(None, None, None), "-300": _walk(13.5, 369.0, -18.7)}}]
    text = format_stance_response(rows)
    assert "| p | learned | 24.0 | 22.0 | 2.0 | 162 / 159 | -13 / -56 | 0 / 0 | 1, 46, 0.50 |" in text
    assert "| p | FSMIC | — | 13.5 | — | — / 369 | — / -19 | 0 / 0 | — |" in text
