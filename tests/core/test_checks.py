"""`core.checks`: the plain-number checks every layer shares."""

import numpy as np
import pytest

from macrostate_mj.core.checks import check_count, check_positive, check_seed
from macrostate_mj.core.errors import UserError


@pytest.mark.parametrize("value", [0, 7, np.int64(3)])
def test_a_seed_is_a_whole_number_from_zero(value):
    check_seed(value)


@pytest.mark.parametrize("value", [-1, 1.5, True, "3", None, np.float64(2.0)])
def test_anything_else_is_refused_as_a_seed_naming_the_parameter(value):
    with pytest.raises(UserError, match="first_seed must be a whole number >= 0") as caught:
        check_seed(value, "first_seed")
    assert caught.value.param == "first_seed"


def test_counts_and_positive_numbers_refuse_their_bounds_and_what_is_not_a_number():
    check_count(1, "epochs")
    check_count(0, "retries", least=0)
    check_positive(2e-3, "lr")
    check_positive(0, "angle_weight", zero=True)
    for bad in (0, 2.5, False, "1"):
        with pytest.raises(UserError, match="epochs must be a whole number of at least 1"):
            check_count(bad, "epochs")
    for bad in (0, -1.0, float("nan"), float("inf"), True, "1"):
        with pytest.raises(UserError, match="lr must be a finite number above 0"):
            check_positive(bad, "lr")
    with pytest.raises(UserError, match=">= 0"):
        check_positive(-1e-9, "angle_weight", zero=True)
