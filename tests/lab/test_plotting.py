"""The proposal figure."""

from __future__ import annotations


def test_the_figure_of_a_proposal_is_written_where_asked(model, tmp_path):
    from lab.plotting import plot_proposal  # matplotlib: imported by the process that runs this, not by every one

    out = plot_proposal(model, model.propose(1.2, 0.0, 75.0), tmp_path / "figs" / "proposal.png")
    assert out.exists() and out.stat().st_size > 10_000
