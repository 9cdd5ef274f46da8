"""A grid figure names each axis with what its values are: the town's 20, 30, 40 are the
half widths of blocks 40, 60, 80 m wide."""

from __future__ import annotations

from sensorplan.report.grid_figures import heatmap_panels
from sensorplan.study.features import AXIS_TITLES, SCENARIO_FEATURES, axis_title


def _axis(name: str, labels: list[str], base: int | None) -> dict:
    return {"name": name, "labels": labels, "base_index": base}


def test_every_scenario_feature_has_a_title_with_its_unit() -> None:
    assert set(AXIS_TITLES) == set(SCENARIO_FEATURES)
    assert all(t.startswith(name) for name, t in AXIS_TITLES.items())
    assert axis_title("town") == "town: half width of a block (m)"
    assert axis_title("planner_params.alpha") == "planner_params.alpha"   # a setting axis


def test_star_panels_are_titled_by_the_axis_title() -> None:
    axes = [_axis("sensor_speed", ["0.5", "1"], 1), _axis("town", ["0", "20", "40"], 0)]
    cells = [{"index": [1, 0], "slug": "base"}, {"index": [0, 0], "slug": "sensor_speed=0.5"},
             {"index": [1, 1], "slug": "town=20"}, {"index": [1, 2], "slug": "town=40"}]
    panels = heatmap_panels({"design": "star", "axes": axes, "cells": cells})
    assert [p.rows for p in panels] == [("sensor_speed (x the moves)",),
                                        ("town: half width of a block (m)",)]
    assert panels[1].cols == ("0", "20", "40")          # the values as the grid file has them


def test_full_panels_title_rows_and_columns_alike() -> None:
    axes = [_axis("town", ["0", "20"], 0), _axis("min_ground_range", ["150", "250"], 1)]
    cells = [{"index": [r, c], "slug": f"c{r}{c}"} for r in range(2) for c in range(2)]
    (panel,) = heatmap_panels({"design": "full", "axes": axes, "cells": cells})
    assert (panel.row_title, panel.col_title) == ("town: half width of a block (m)",
                                                  "min_ground_range (m)")
