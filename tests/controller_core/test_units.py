"""The units module: constants, conversions, and the one check of positive settings."""

from __future__ import annotations


def test_require_positive_names_the_first_setting_that_is_not_a_positive_number():
    import math
    from types import SimpleNamespace

    import pytest

    from controller_core.units import require_positive

    require_positive(SimpleNamespace(a=1.0, b=2))
    for bad in (0.0, -1.0, math.nan, math.inf, "1"):
        with pytest.raises(ValueError, match="b must be a positive finite number"):
            require_positive(SimpleNamespace(a=1.0, b=bad))
    require_positive(SimpleNamespace(a=1.0, b=-1.0), ("a",))     # only the names asked for
