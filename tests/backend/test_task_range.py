"""A task beyond what the model knows is refused unless a reason is written."""

from __future__ import annotations

import pytest

from backend.errors import InvalidError
from backend.task_range import extrapolation_reason

REASON = "the patient walks fast on the track daily"


def test_within_the_known_range_no_reason_is_kept(model):
    assert extrapolation_reason(model, [(1.2, 0.0), (0.6, -10.0)], False, None) is None
    assert extrapolation_reason(model, [(1.2, 0.0)], True, REASON) is None


def test_beyond_it_the_reason_is_kept_or_the_request_is_refused_saying_the_range(model):
    assert extrapolation_reason(model, [(1.2, 0.0), (2.8, 0.0)], True, REASON) == REASON
    with pytest.raises(InvalidError, match="refused, nothing stored") as caught:
        extrapolation_reason(model, [(2.8, 0.0)], False, None)
    assert caught.value.extra["known_range"]["speed_mps"] == [0.49, 2.3]
    with pytest.raises(InvalidError):
        extrapolation_reason(model, [(1.2, 19.0)], True, None)
