"""The reward setting through the command line: ``reward`` and ``gospa_c`` of a decision
file, ``--reward`` of simulate and agents and ``planning.reward`` of a scenario file each
refuse bad input with one line naming the key (exit 2); a gospa decision plans, and its
potential is its tracks' terms plus its search term; a gospa run says so."""

from __future__ import annotations

import copy
import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from cli_helpers import SPEC7, assert_bad_input, run
from cli_helpers import set_path as _set


def gospa_decision() -> dict[str, Any]:
    d = copy.deepcopy(SPEC7)
    d["horizon"] = 2
    d["search"] = "on"
    d["reward"] = "gospa"
    d["gospa_c"] = 30.0
    d["sensors"][0]["search_sectors"] = 6
    d["undetected"] = {"centres": [[450, 100], [100, 450], [300, 300]],
                       "weights": [0.2, 0.1, 0.05], "births": [0.01, 0.0, 0.0],
                       "survival": 0.98, "cell_size": [50, 40]}
    d["planner"] = {"name": "sequential-greedy"}
    return d


BAD_REWARD = [
    ("unknown reward", _set("reward", "entropy"), "reward"),
    ("reward as a number", _set("reward", 1), "reward"),
    ("gospa with search off", _set("search", "off"), "reward"),
    ("zero cut-off", _set("gospa_c", 0), "gospa_c"),
    ("negative cut-off", _set("gospa_c", -5.0), "gospa_c"),
    ("cut-off as text", _set("gospa_c", "50"), "gospa_c"),
    ("infinite cut-off", _set("gospa_c", float("inf")), "gospa_c"),
    ("a find's nats with gospa", _set("undetected.weight", 1.0), "undetected.weight"),
    ("reported as text", _set("targets.0.reported", "no"), "targets[0].reported"),
    ("not reported with information", lambda d: (_set("targets.0.reported", False)(d),
                                                 d.pop("reward")), "targets[0].reported"),
]


@pytest.mark.parametrize("mutate,field", [c[1:] for c in BAD_REWARD],
                         ids=[c[0] for c in BAD_REWARD])
def test_bad_reward_input_is_one_line_naming_the_key(
        mutate: Callable[[dict[str, Any]], None], field: str, tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    data = gospa_decision()
    mutate(data)
    path = tmp_path / "problem.json"
    path.write_text(json.dumps(data))
    assert_bad_input(run(capsys, "plan", path), field)


def test_a_gospa_decision_plans(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "problem.json"
    path.write_text(json.dumps(gospa_decision()))
    code, out, err = run(capsys, "plan", path)
    assert (code, err) == (0, ""), err
    res = json.loads(out)
    assert res["potential"] == pytest.approx(sum(res["information"]) + res["search_term"],
                                             rel=1e-12)
    assert res["potential"] > 0
    # The same file with the information reward plans Phi in nats: another number.
    info = {k: v for k, v in gospa_decision().items() if k not in ("reward", "gospa_c")}
    path.write_text(json.dumps(info))
    code, out, err = run(capsys, "plan", path)
    assert code == 0, err
    assert json.loads(out)["potential"] != res["potential"]


def test_a_track_not_reported_is_found(tmp_path: Path,
                                       capsys: pytest.CaptureFixture[str]) -> None:
    """The same decision with a target not reported: its term of Phi is 0 and the plan's
    search term includes finding it."""
    path = tmp_path / "problem.json"
    out = {}
    for reported in (True, False):
        d = gospa_decision()
        d["targets"][0]["reported"] = reported
        path.write_text(json.dumps(d))
        code, text, err = run(capsys, "plan", path)
        assert (code, err) == (0, ""), err
        out[reported] = json.loads(text)
    hidden = out[False]
    assert hidden["information"][0] == 0.0
    assert hidden["potential"] == pytest.approx(sum(hidden["information"])
                                                + hidden["search_term"], rel=1e-12)
    assert hidden["potential"] != out[True]["potential"]


@pytest.mark.parametrize(("args", "field"), [
    (("--preset", "search", "--search", "on", "--reward", "entropy"), "--reward"),
    (("--preset", "search", "--unreported", "maybe"), "--unreported"),
    (("--preset", "search", "--search", "off", "--reward", "gospa"), "--reward"),
    (("--preset", "search", "--search", "on", "--reward", "gospa", "--gospa-c", "0"),
     "--gospa-c"),
])
def test_bad_reward_options_are_one_line(capsys: pytest.CaptureFixture[str], tmp_path: Path,
                                         args: tuple[str, ...], field: str) -> None:
    assert_bad_input(run(capsys, "simulate", *args, "--out", tmp_path), field)


def test_bad_rewards_in_files_name_the_key(capsys: pytest.CaptureFixture[str],
                                           tmp_path: Path) -> None:
    quick = (Path(__file__).resolve().parents[2] / "configs" / "quick.toml").read_text()
    path = tmp_path / "s.toml"
    path.write_text(quick.replace("[planning]\n", '[planning]\nreward = "entropy"\n'))
    assert_bad_input(run(capsys, "simulate", path, "--out", tmp_path), "planning.reward")
    path.write_text(quick.replace("[planning]\n", '[planning]\nreward = "gospa"\n'))
    line = assert_bad_input(run(capsys, "simulate", path, "--out", tmp_path),
                            "planning.reward")
    assert "needs search = 'on'" in line


def test_agents_refuse_the_gospa_reward_without_search(capsys: pytest.CaptureFixture[str],
                                                      tmp_path: Path) -> None:
    assert_bad_input(run(capsys, "agents", "--preset", "search", "--search", "off",
                         "--reward", "gospa", "--out", tmp_path), "--reward")


def test_a_gospa_run_names_its_reward(capsys: pytest.CaptureFixture[str],
                                     tmp_path: Path) -> None:
    code, out, err = run(capsys, "simulate", "--preset", "search", "--search", "on",
                         "--reward", "gospa", "--planner", "sequential-greedy", "--steps", "2",
                         "--out", tmp_path)
    assert code == 0, err
    text = " ".join(out.split())
    assert "reward gospa (c = 50 m, unreported tracks confirmed)" in text
    code, out, err = run(capsys, "simulate", "--preset", "search", "--unreported", "localise",
                         "--planner", "sequential-greedy", "--steps", "2", "--out", tmp_path)
    assert code == 0, err
    assert "reward gospa (c = 50 m)," in " ".join(out.split())
    assert "m^2 (mu, the undetected targets" in text
