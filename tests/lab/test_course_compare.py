"""The course comparison: three controllers over one course, the adaptive one against each."""

from __future__ import annotations

import pytest

from device_bridge.sim.course import Course, Segment
from lab.course_compare import COURSE_CONTROLLERS, compare_course, format_course_compare

SHORT = Course("short-ramp", (Segment(6.0, 1.0, 0.0), Segment(10.0, 1.0, 6.0)), transition_s=2.0)


@pytest.fixture(scope="module")
def result(model):
    return compare_course(model, SHORT, 75.0)


def test_every_controller_walks_the_course_and_the_adaptive_one_is_compared_with_each(result):
    assert [r["controller"] for r in result["rows"]] == list(COURSE_CONTROLLERS)
    assert set(result["adaptive_minus"]) == {"quasi-stiffness", "fsmic"}
    ankle = result["adaptive_minus"]["fsmic"]["ankle_angle_deg"]      # the FSMIC's fixed ankle: several degrees worse
    assert ankle["verdict"] == "adaptive lower" and ankle["ci95"][1] < -1.0
    assert result["envelope"]["wire_crc32"] > 0 and result["course"]["name"] == "short-ramp"


def test_the_tables_name_the_course_each_segment_and_the_estimate(result):
    text = format_course_compare(result)
    assert text.startswith("Course short-ramp: 1 m/s +0° → 1 m/s +6°")
    assert "| 1 m/s +6° |" in text and "Task estimation (adaptive)" in text and "| fsmic |" in text
    assert "| after a change |" in text and "adaptive − other, right after a change" in text
    assert "From the second stride after each change: speed within ±0.1 m/s on" in text
    assert set(result["adaptive_minus_after_change"]) == set(result["adaptive_minus_between_changes"]) == {
        "quasi-stiffness", "fsmic"}
