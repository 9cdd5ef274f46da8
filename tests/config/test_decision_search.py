"""A decision file that searches: ``search``, each sensor's ``search_sectors`` and the
``undetected`` grid, and one error naming the field for each bad input."""

from __future__ import annotations

import copy
import json
from typing import Any

import numpy as np
import pytest

from sensorplan.config import decision_from_dict
from sensorplan.config.decision import EXAMPLE_PROBLEM
from sensorplan.config.files import result_to_dict
from sensorplan.errors import ConfigError
from sensorplan.planners import search


def searching(**undetected: Any) -> dict[str, Any]:
    d: dict[str, Any] = json.loads(EXAMPLE_PROBLEM)
    d["search"] = "on"
    d["sensors"][0]["search_sectors"] = 6
    d["targets"][0]["existence"] = 0.4
    d["undetected"] = {"centres": [[450, 100], [100, 450], [300, 300]],
                       "weights": [0.2, 0.1, 0.05], "births": [0.01, 0.0, 0.0],
                       "survival": 0.98, "cell_size": [50, 40], **undetected}
    return d


def test_a_searching_file_builds_the_problem() -> None:
    dec = decision_from_dict(searching())
    p = dec.problem
    assert p.searching and p.sector_counts == (6,)
    assert p.existence.tolist() == [0.4]
    u = p.undetected
    assert u is not None
    assert u.centres.tolist() == [[450, 100], [100, 450], [300, 300]]
    assert u.weights.tolist() == [0.2, 0.1, 0.05] and u.births.tolist() == [0.01, 0, 0]
    assert u.survival == 0.98 and u.weight is None
    assert u.cell_cov.tolist() == [[2500 / 12, 0], [0, 1600 / 12]]
    res = dec.make_planner().plan(p)
    assert res.potential == search.evaluate(search.prepare(p), res.plan).potential


def test_without_search_the_file_is_as_before() -> None:
    d = json.loads(EXAMPLE_PROBLEM)
    p = decision_from_dict(d).problem
    assert not p.searching and p.undetected is None and p.sector_counts == (0,)
    births = searching()
    births.pop("search")                               # off: the grid is ignored
    births["targets"][0].pop("existence")
    q = decision_from_dict(births).problem
    assert not q.searching
    a, b = (decision_from_dict(x).make_planner().plan(y) for x, y in ((d, p), (births, q)))
    assert a.potential == b.potential
    assert np.array_equal(a.plan.positions, b.plan.positions)


@pytest.mark.parametrize(("change", "field"), [
    (lambda d: d.pop("undetected"), "undetected"),
    (lambda d: d.update(search="maybe"), "search"),
    (lambda d: d["sensors"][0].update(search_sectors=-2), r"sensors\[0\]\.search_sectors"),
    (lambda d: d["sensors"][0].update(search_sectors=2.5), r"sensors\[0\]\.search_sectors"),
    (lambda d: d["undetected"].update(weights=[0.1, 0.2]), "undetected.weights"),
    (lambda d: d["undetected"].update(weights=[0.1, -0.2, 0.0]), "undetected.weights"),
    (lambda d: d["undetected"].update(births=[0.0]), "undetected.births"),
    (lambda d: d["undetected"].update(survival=1.5), "undetected.survival"),
    (lambda d: d["undetected"].update(cell_size=[0, 10]), "undetected.cell_size"),
    (lambda d: d["undetected"].update(centres=[[700, 100], [1, 1], [2, 2]]),
     r"undetected\.centres\[0\]"),
    (lambda d: d["undetected"].update(weight=-1.0), "undetected.weight"),
    (lambda d: d["undetected"].update(colour="red"), "undetected.colour"),
    (lambda d: d["targets"][0].update(existence=1.2), r"targets\[0\]\.existence"),
])
def test_bad_search_input_names_the_field(change: Any, field: str) -> None:
    d = copy.deepcopy(searching())
    change(d)
    with pytest.raises(ConfigError) as err:
        decision_from_dict(d)
    assert err.value.field.startswith(field.replace("\\", "")), err.value
    assert "\n" not in str(err.value)


def test_a_look_in_the_output_has_a_target_or_a_sector() -> None:
    d = searching()
    d["planner"] = {"name": "random"}
    dec = decision_from_dict(d)
    kinds = set()
    for seed in range(8):
        res = dec.make_planner().plan(dec.problem, rng=seed)
        out = result_to_dict(res)
        looks = [look for row in out["plan"] for look in row]
        for look, t, s in zip(looks, res.plan.targets.ravel(), res.plan.sectors.ravel()):
            assert ("target" in look) != ("sector" in look)
            assert look.get("target", -1) == t and look.get("sector", -1) == s
            kinds |= set(look) & {"target", "sector"}
    assert kinds == {"target", "sector"}


def test_the_output_reports_the_search_term() -> None:
    dec = decision_from_dict(searching())
    res = dec.make_planner().plan(dec.problem)
    out = result_to_dict(res, dec.problem.existence)
    phi, info, mu = search.potential(dec.problem, res.plan)
    assert out["found"] == pytest.approx(mu, rel=1e-12) and mu > 0
    assert out["search_term"] == pytest.approx(phi - info.sum(), rel=1e-9)
    assert out["potential"] == pytest.approx(sum(out["information"]) + out["search_term"],
                                             rel=1e-12)
    keys = list(out)
    assert keys.index("existence") < keys.index("found") < keys.index("search_term") \
        < keys.index("seconds")
    off = decision_from_dict(json.loads(EXAMPLE_PROBLEM))
    plain = result_to_dict(off.make_planner().plan(off.problem))
    assert "found" not in plain and "search_term" not in plain
