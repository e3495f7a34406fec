"""The session report's facts, in words a clinician reads."""

from __future__ import annotations

from backend.report import headline_words, local_time, report_facts

SESSION = {"summary": {"samples": 1000, "duration_s": 10.0, "missing_samples": 0, "strides": 9, "strides_scored": 8,
                       "cadence_steps_per_min": 104.0, "stride_time_s": 1.15, "reference_stride_time_s": 1.1,
                       "headline": {"strides_scored": 8, "enough_strides": True, "min_strides": 5,
                                    "knee_angle_rmse_deg": 6.04, "ankle_angle_rmse_deg": 10.2,
                                    "against": "its own task"},
                       "reference_kind": "measured"},
           "task_words": "1.20 m/s, incline +0.0°", "device_id": "sim-leg-1", "envelope_id": None,
           "table_label": "P-1 · table v2", "table_crc32": "00abc123", "table_version": 7,
           "approval_override": "checked by hand in the parallel bars", "extrapolation_reason": None,
           "started_at": "2026-01-01T10:00:00Z", "stopped_at": "2026-01-01T10:00:10Z", "started_by": "pat",
           "course": None, "id": 7}
PATIENT = {"code_name": "P-1", "body_mass_kg": 80.0, "side": "left"}


def test_the_facts_say_what_ran_how_it_went_and_any_override():
    facts = dict(report_facts(SESSION, PATIENT))
    assert facts["Patient"] == "P-1 · 80.0 kg · left side"
    assert facts["Table that ran"] == "P-1 · table v2 (CRC-32 00abc123, device version 7)"
    assert "checked by hand" in facts["Bench override"] and "Extrapolated" not in facts
    assert facts["Leg off its table"] == "never" and facts["Strides, table / all"].startswith("8 on the table of 9")
    assert facts["Angle error per stride"].startswith("knee 6.0 deg, ankle 10.2 deg")


def test_too_few_strides_are_said_so_and_times_read_locally():
    few = {"strides_scored": 3, "enough_strides": False, "min_strides": 5}
    assert headline_words(few) == "too few strides to judge (3 scored; at least 5 needed)"
    assert headline_words(None) == "—" and local_time(None) == "—"
    assert local_time("2026-01-01T10:00:00Z").startswith("2026-01-01")


def test_a_simulated_walk_says_so_first_and_a_persons_does_not():
    simulated = report_facts({**SESSION, "simulated": True}, PATIENT)
    assert simulated[0] == ("SIMULATED", "walked by the simulated patient on the simulated leg (the bench), not by a "
                                         "person")
    assert "SIMULATED" not in dict(report_facts({**SESSION, "simulated": False}, PATIENT))
    assert "SIMULATED" not in dict(report_facts(SESSION, PATIENT))       # recorded before it was kept: not claimed


def test_the_page_gives_one_knee_error_and_the_counts_agree():
    """The angles' error is the headline's alone (not also the mean stride's nor the envelope's per-stride figure);
    a headline scoring fewer strides than ran on the table says why; standing is counted apart from walking."""
    summary = {**SESSION["summary"], "walking_s": 7.5, "standing_s": 2.5, "knee_angle_rmse_deg": 5.1,
               "headline": {**SESSION["summary"]["headline"], "strides_scored": 6, "strides_on_table": 8,
                            "strides_without_task": 2}}
    facts = report_facts({**SESSION, "summary": summary}, PATIENT)
    said = " ".join(words for _label, words in facts)
    assert said.count("knee 6.0 deg") == 1 and "5.1" not in said and "knee angle" not in said
    assert "of the 8 strides on the table 2 are not scored, 2 without a task estimate" in dict(facts)[
        "Angle error per stride"]
    assert dict(facts)["Walking / standing"] == "7.5 s walking (the strides), 2.5 s standing or paused"


def test_a_course_is_drawn_without_one_tasks_reference_and_a_fixed_task_with_it():
    """A course's strides are at several tasks: the PDF draws their mean alone (no ramps averaged against a level
    reference) and prints no single reference's error over the angles."""
    from backend.report import report_figure

    grid = [i / 10 for i in range(11)]
    curves = {c: [float(i) for i in range(11)] for c in ("knee_angle_deg", "ankle_angle_deg", "knee_moment_Nm_per_kg",
                                                          "ankle_moment_Nm_per_kg")}
    summary = {**SESSION["summary"], "phase_grid": grid, "reference_curves": curves, "mean_curves": curves}

    def lines(session):
        fig = report_figure({**session, "summary": summary}, PATIENT)
        return [(ax.get_title(), len(ax.get_lines())) for ax in fig.axes if ax.get_lines()]

    fixed = lines(SESSION)
    course = lines({**SESSION, "course": "terrain", "task_words": "'terrain' course: 1.00 m/s, incline -8° to +8°"})
    assert [n for _, n in fixed] == [2, 2, 2, 2] and [n for _, n in course] == [1, 1, 1, 1]
    assert all("RMSE" not in title for title, _ in course)
    assert [("RMSE" in title) for title, _ in fixed] == [False, False, True, True]   # the angles' is the headline's


def test_a_long_chart_title_wraps_instead_of_running_over_the_next_chart():
    """A moment chart without its RMSE says why in its title; the words go on a second line, within the chart's width."""
    from backend.report import report_figure

    grid = [i / 10 for i in range(11)]
    curves = {c: [float(i) for i in range(11)] for c in ("knee_angle_deg", "ankle_angle_deg", "knee_moment_Nm_per_kg",
                                                          "ankle_moment_Nm_per_kg")}
    summary = {**SESSION["summary"], "phase_grid": grid, "reference_curves": curves, "mean_curves": curves}
    titles = [ax.get_title() for ax in report_figure({**SESSION, "summary": summary}, PATIENT).axes if ax.get_title()]
    moments = [t for t in titles if "moment" in t]
    assert len(moments) == 2 and all("fewer than two scored strides" in " ".join(t.split()) for t in moments)
    assert all(len(line) <= 48 for t in titles for line in t.splitlines())
