"""A planner that breaks its contract stops every command before its plan is executed:
one error line naming the planner, the decision, the sensor and the epoch, exit 2."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

from cli_helpers import SPEC7, assert_bad_input, run

ROOT = Path(__file__).resolve().parents[2]
QUICK = ROOT / "configs" / "quick.toml"
TELEPORT = "broken_planners:Teleport"
PREFIX = f"error: planner: 'teleport' ({TELEPORT}) broke the planner contract"


def test_plan_refuses_and_prints_no_plan(tmp_path: Path,
                                         capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "p.json"
    path.write_text(json.dumps(SPEC7))
    line = assert_bad_input(run(capsys, "plan", path, "--planner", TELEPORT), "planner")
    assert line.startswith(PREFIX + " (sensor 0 epoch 1): position [600. 600.] is not one "
                           "move from [100. 100.]; nothing of its plan was executed")


@pytest.mark.parametrize("reference,where", [
    (TELEPORT, "(decision 0, sensor 0 epoch 1): position"),
    ("broken_planners:TargetOutOfRange", "(decision 0, sensor 0 epoch 1): target 99 does "
                                         "not exist"),
    ("broken_planners:Incomplete", "(decision 0, sensor 1 epoch 1): no action"),
])
def test_simulate_refuses_before_the_first_step(reference: str, where: str, tmp_path: Path,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "out"
    line = assert_bad_input(run(capsys, "simulate", QUICK, "--planner",
                                reference, "--steps", "4", "--out", out), "planner")
    assert f"({reference}) broke the planner contract {where}" in line, line
    assert not (out / "episode.npz").exists()


STUDY = """\
runs = 2
steps = 4
seed = 3
[scenario]
file = "{quick}"
[[methods]]
name = "random"
planner = "random"
[[methods]]
name = "tele"
planner = "{planner}"
"""


def test_a_study_stops_naming_the_method_run_and_decision(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "s.toml"
    path.write_text(STUDY.format(quick=QUICK, planner=TELEPORT))
    out = tmp_path / "study"
    line = assert_bad_input(run(capsys, "study", path, "--out", out, "--workers", "1"),
                            "methods[1].planner")
    assert (f"'teleport' ({TELEPORT}) broke the planner contract (decision 0, sensor 0 "
            "epoch 1): ") in line
    assert line.endswith("nothing of its plan was executed (method 'tele', run 0)")
    # Nothing of the broken method is stored, and no tables are written.
    assert not list(out.glob("parts/*/m01*"))
    assert not (out / "steps.parquet").exists()


def test_agents_check_the_decentralized_plans(
        tmp_path: Path, capsys: pytest.CaptureFixture[str],
        monkeypatch: pytest.MonkeyPatch) -> None:
    from sensorplan.decentral.planners import DecentralJSFPPlanner

    honest = DecentralJSFPPlanner.plan

    def far_target(self, problem, rng=None):       # agents agreeing on a target that is not
        res = honest(self, problem, rng)
        targets = np.array(res.plan.targets)
        targets[1, 0] = problem.n_targets
        return dataclasses.replace(res, plan=dataclasses.replace(res.plan, targets=targets))

    monkeypatch.setattr(DecentralJSFPPlanner, "plan", far_target)
    out = tmp_path / "out"
    line = assert_bad_input(run(capsys, "agents", "--preset", "paper", "--steps", "2",
                                "--out", out), "planner")
    assert line.startswith("error: planner: 'dec-jsfp' broke the planner contract (decision "
                           "0, sensor 1 epoch 1): target 5 does not exist"), line
    assert not (out / "episode.npz").exists()
