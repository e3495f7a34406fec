"""A session as the clinic reads it: its task in words."""

from __future__ import annotations

from backend.services import sessions as session_views


def test_task_words_name_a_course_by_its_range_and_a_fixed_task_by_its_values():
    assert session_views.task_words(None, 1.234, -3.0) == "1.23 m/s, incline -3.0°"
    assert session_views.task_words("unknown", 1.0, 0.0) == "1.00 m/s, incline +0.0°"
    words = session_views.task_words("mixed", 1.0, 0.0)
    assert "0.85–1.60 m/s" in words and "incline -8° to +8°" in words
    assert session_views.task_words("terrain", 1.0, 0.0) == "'terrain' course: 1.00 m/s, incline -8° to +8°"   # one speed
