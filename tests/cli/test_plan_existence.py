"""``sensorplan plan`` with the targets' probabilities of existence (``targets[j].existence``)."""

from __future__ import annotations

import copy
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from cli_helpers import SPEC7, assert_bad_input, run
from sensorplan.config import decision_from_dict


def two_targets(**planner: Any) -> dict[str, Any]:
    """The documented example with a second target beside the first."""
    d = copy.deepcopy(SPEC7)
    d["targets"].append(copy.deepcopy(d["targets"][0]))
    d["targets"][1]["mean"] = [320, 220, 4, 1]
    d["planner"] = {"name": "random", "seed": 4, **planner}
    return d


def plan(capsys: pytest.CaptureFixture[str], tmp_path: Path, d: dict[str, Any]
         ) -> dict[str, Any]:
    path = tmp_path / "p.json"
    path.write_text(json.dumps(d))
    code, out, err = run(capsys, "plan", path)
    assert (code, err) == (0, "")
    return json.loads(out)


def test_existence_weights_the_terms_and_is_reported(capsys, tmp_path) -> None:
    d = two_targets()
    plain = plan(capsys, tmp_path, d)
    assert "existence" not in plain                    # not given: the output as before
    d["targets"][0]["existence"] = 0.25
    res = plan(capsys, tmp_path, d)
    assert list(res)[:5] == ["planner", "plan", "potential", "information", "existence"]
    assert res["existence"] == [0.25, 1.0]
    assert res["plan"] == plain["plan"]                # the random planner ignores Phi
    np.testing.assert_allclose(res["information"],
                               [0.25 * plain["information"][0], plain["information"][1]],
                               rtol=1e-12)
    assert res["potential"] == pytest.approx(sum(res["information"]), rel=1e-12)


def test_existence_one_is_no_weight(capsys, tmp_path) -> None:
    d = two_targets()
    d["planner"] = {"name": "pg", "seed": 0}
    plain = plan(capsys, tmp_path, d)
    for t in d["targets"]:
        t["existence"] = 1
    res = plan(capsys, tmp_path, d)
    assert res.pop("existence") == [1.0, 1.0]
    for r in (res, plain):
        r.pop("seconds")
    assert res == plain


@pytest.mark.parametrize(("value", "message"), [
    (1.5, "must be in [0, 1], got 1.5"), (-0.1, "must be in [0, 1], got -0.1"),
    ("0.5", ""), (True, ""), (None, "")])
def test_bad_existence_is_refused_naming_the_key(capsys, tmp_path, value, message) -> None:
    d = two_targets()
    d["targets"][1]["existence"] = value
    path = tmp_path / "p.json"
    path.write_text(json.dumps(d))
    line = assert_bad_input(run(capsys, "plan", path), "targets[1].existence")
    assert message in line


def test_the_decision_knows_whether_existence_was_given() -> None:
    d = two_targets()
    assert not decision_from_dict(d).existence_given
    d["targets"][1]["existence"] = 0.0
    decision = decision_from_dict(d)
    assert decision.existence_given
    np.testing.assert_array_equal(decision.problem.existence, [1.0, 0.0])
