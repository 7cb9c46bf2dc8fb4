"""Marker kinds by team size: colour teams keep their hues up to 5 robots, wear dimmer colours
beyond (no channel clips under the lights, so hues do not drift) and are refused over the count
the classifier separates; tag teams are bounded by their dictionary."""

import colorsys

import numpy as np
import pytest

from macrostate_mj.chain.markers import (
    LARGE_TEAM_VALUE,
    SEPARABLE_COLOURS,
    ColourMarkers,
    hue_tolerance,
    marker_colours,
    marker_hues,
)
from macrostate_mj.chain.scenarios import get_scenario
from macrostate_mj.chain.world import build_world
from macrostate_mj.core.errors import UserError


@pytest.mark.parametrize("n", [2, 3, 4, 5])
def test_small_colour_teams_keep_their_colours(n):
    legacy = np.array([colorsys.hsv_to_rgb(i / n, 1.0, 1.0) for i in range(n)])
    np.testing.assert_array_equal(marker_colours(n), legacy)


@pytest.mark.parametrize("n", [6, SEPARABLE_COLOURS])
def test_larger_colour_teams_are_dimmer_with_the_same_even_hues(n):
    colours = marker_colours(n)
    assert np.allclose(colours.max(axis=1), LARGE_TEAM_VALUE)
    spacing = np.diff(np.sort(marker_hues(colours)))
    assert spacing.min() > 2 * hue_tolerance(n)     # no pixel counts for two markers


def test_a_colour_team_over_the_separable_count_is_refused():
    ColourMarkers().check_team(SEPARABLE_COLOURS)
    n = SEPARABLE_COLOURS + 1
    with pytest.raises(UserError, match=f'{n} colour markers .* kind = "aruco" for teams over '
                                        f"{SEPARABLE_COLOURS}") as err:
        build_world(get_scenario("lab"), n)
    assert "\n" not in str(err.value)
