"""Bad search input through ``sensorplan plan``: each key of a decision file that searches
(``search``, ``sensors[i].search_sectors``, every key of ``undetected``) and the run's
``elapsed_epochs`` has a case that exits 2 with one line naming it, and a plan whose search
look is malformed (a sector past the last, a target and a sector in one look, a search look
while search is off) is refused before anything of it is used."""

from __future__ import annotations

import copy
import json
import re
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from cli_helpers import SPEC7, assert_bad_input, run
from cli_helpers import set_path as _set
from sensorplan.config.decision import DecisionUndetected


def searching() -> dict[str, Any]:
    d = copy.deepcopy(SPEC7)
    d["horizon"] = 2
    d["search"] = "on"
    d["sensors"][0]["search_sectors"] = 6
    d["undetected"] = {"centres": [[450, 100], [100, 450], [300, 300]],
                       "weights": [0.2, 0.1, 0.05], "births": [0.01, 0.0, 0.0],
                       "survival": 0.98, "cell_size": [50, 40]}
    d["planner"] = {"name": "raster"}                 # fast: only the input is wrong
    return d




def _drop(path: str) -> Callable[[dict[str, Any]], None]:
    def mutate(d: dict[str, Any]) -> None:
        *head, last = path.split(".")
        for k in head:
            d = d[k]
        d.pop(last)
    return mutate


#: (id, mutation of a searching decision, field named in the error)
BAD_SEARCH = [
    ("unknown search mode", _set("search", "maybe"), "search"),
    ("search on without a grid", _drop("undetected"), "undetected"),
    ("grid not an object", _set("undetected", [1, 2]), "undetected"),
    ("unknown grid key", _set("undetected.colour", "red"), "undetected.colour"),
    ("no sector anywhere", _set("sensors.0.search_sectors", 0), "sensors[0].search_sectors"),
    ("negative sectors", _set("sensors.0.search_sectors", -2), "sensors[0].search_sectors"),
    ("fractional sectors", _set("sensors.0.search_sectors", 2.5), "sensors[0].search_sectors"),
    ("sectors as text", _set("sensors.0.search_sectors", "6"), "sensors[0].search_sectors"),
    ("sectors as a list", _set("sensors.0.search_sectors", [6, 6]),
     "sensors[0].search_sectors"),
    ("too many sectors", _set("sensors.0.search_sectors", 10**9), "sensors[0].search_sectors"),
    ("centre outside the map", _set("undetected.centres.0", [700, 100]),
     "undetected.centres[0]"),
    ("centre below the map", _set("undetected.centres.2", [300, -0.5]),
     "undetected.centres[2]"),
    ("centre of 3 numbers", _set("undetected.centres.1", [1, 2, 3]), "undetected.centres[1]"),
    ("no cells", lambda d: d["undetected"].update(centres=[], weights=[], births=[]),
     "undetected.centres"),
    ("too many cells", lambda d: d["undetected"].update(
        centres=[[1, 1]] * 10_001, weights=[0] * 10_001, births=None), "undetected.centres"),
    ("missing centres", _drop("undetected.centres"), "undetected.centres"),
    ("fewer weights than cells", _set("undetected.weights", [0.1, 0.2]), "undetected.weights"),
    ("negative weight", _set("undetected.weights.1", -0.2), "undetected.weights[1]"),
    ("non-finite weight", _set("undetected.weights.1", float("nan")), "undetected.weights[1]"),
    ("huge weight", _set("undetected.weights.0", 1e300), "undetected.weights[0]"),
    ("missing weights", _drop("undetected.weights"), "undetected.weights"),
    ("more births than cells", _set("undetected.births", [0, 0, 0, 0]), "undetected.births"),
    ("negative births", _set("undetected.births.2", -1e-3), "undetected.births[2]"),
    ("infinite births", _set("undetected.births.0", float("inf")), "undetected.births[0]"),
    ("survival above 1", _set("undetected.survival", 1.5), "undetected.survival"),
    ("negative survival", _set("undetected.survival", -0.1), "undetected.survival"),
    ("survival as text", _set("undetected.survival", "high"), "undetected.survival"),
    ("zero cell side", _set("undetected.cell_size", [0, 10]), "undetected.cell_size"),
    ("cell side too small", _set("undetected.cell_size", [1e-300, 10]), "undetected.cell_size"),
    ("cell side too large", _set("undetected.cell_size", [1e300, 10]), "undetected.cell_size"),
    ("one cell side", _set("undetected.cell_size", [10]), "undetected.cell_size"),
    ("missing cell size", _drop("undetected.cell_size"), "undetected.cell_size"),
    ("negative weight of a find", _set("undetected.weight", -1.0), "undetected.weight"),
    ("huge weight of a find", _set("undetected.weight", 1e300), "undetected.weight"),
    ("negative run epoch", _set("elapsed_epochs", -1), "elapsed_epochs"),
    ("fractional run epoch", _set("elapsed_epochs", 1.5), "elapsed_epochs"),
    ("run epoch as text", _set("elapsed_epochs", "3"), "elapsed_epochs"),
]


@pytest.mark.parametrize("mutate,field", [c[1:] for c in BAD_SEARCH],
                         ids=[c[0] for c in BAD_SEARCH])
def test_bad_search_input_is_one_line_naming_the_key(
        mutate: Callable[[dict[str, Any]], None], field: str, tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    data = searching()
    mutate(data)
    path = tmp_path / "problem.json"
    path.write_text(json.dumps(data))
    assert_bad_input(run(capsys, "plan", path), field)


def test_every_search_key_has_a_bad_input_case() -> None:
    """The keys a searching decision adds, each refused by a case above (indices dropped:
    ``undetected.weights[1]`` counts for ``undetected.weights``)."""
    keys = {"search", "undetected", "sensors.search_sectors", "elapsed_epochs"}
    keys |= {f"undetected.{k}" for k in DecisionUndetected.model_fields}
    named = {re.sub(r"\[\d+\]", "", field) for _, _, field in BAD_SEARCH}
    assert keys <= named, keys - named


def test_a_searching_decision_runs_and_follows_the_run_epoch(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The good file the cases spoil plans; one epoch later raster's sweep is one sector on
    (clockwise, a revisit every third look: looks 1, 2 sweep sectors 0 and 5)."""
    looks = []
    for elapsed in (0, 1):
        path = tmp_path / f"p{elapsed}.json"
        path.write_text(json.dumps({**searching(), "elapsed_epochs": elapsed}))
        code, out, err = run(capsys, "plan", path)
        assert (code, err) == (0, ""), err
        looks.append([look.get("sector", ("target", look.get("target")))
                      for look in json.loads(out)["plan"][0]])
    assert looks[0][0] == 0
    assert looks[0][1] == looks[1][0] != 0
    assert looks[1][1] == ("target", 0)


@pytest.mark.parametrize("planner,search,detail", [
    ("SectorOutOfRange", True, "sector 6 does not exist (sensor 0 has 6 search sectors)"),
    ("TargetAndSector", True, "a look has a target and a sector (it points at one)"),
    ("SectorOutOfRange", False, "a search look, but the problem's search is off"),
])
def test_a_malformed_search_look_is_refused(planner: str, search: bool, detail: str,
                                            tmp_path: Path,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    data = searching()
    if not search:
        data["search"] = "off"
    path = tmp_path / "problem.json"
    path.write_text(json.dumps(data))
    reference = f"broken_planners:{planner}"
    line = assert_bad_input(run(capsys, "plan", path, "--planner", reference), "planner")
    assert f"({reference}) broke the planner contract (sensor 0 epoch 1): {detail}" in line
