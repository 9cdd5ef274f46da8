"""scripts/traffic_lives.py's counts on a hand-made truth."""

from __future__ import annotations

import numpy as np
import pytest

from script_helpers import script_module


def test_ends_near_the_edge_are_exits_and_the_rest_land() -> None:
    lives = script_module("traffic_lives")
    S, side = 6, 10_000.0
    states = np.full((S + 1, 3, 4), np.nan)
    states[1:, 0] = [5000.0, 5000.0, 0.0, 0.0]           # alive from step 1 to the end
    states[1:4, 1] = [9500.0, 5000.0, 100.0, 0.0]        # ends at step 4, 500 m from the edge
    states[3:6, 2] = [4000.0, 3000.0, 0.0, 0.0]          # born at step 3, ends inside at 6
    birth, death = np.array([1, 1, 3]), np.array([-1, 4, 6])
    n = lives.lives(states, birth, death, side, 2000.0)
    assert (n.aircraft_steps, n.at_start, n.born, n.ends_at_edge, n.ends_inside, n.steps) == (
        6 + 3 + 3, 2, 1, 1, 1, 6)
    assert n.birth_rate == pytest.approx(1 / 5)
    assert n.survival == pytest.approx(1 - 1 / 12)
    # A wider margin takes the landing 3 km from the edge for an exit.
    assert lives.lives(states, birth, death, side, 3500.0).ends_inside == 0
