"""The examples run (smoke tests; the Stone Soup one is in test_stonesoup.py)."""

import runpy
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


def test_one_decision_example_runs(capsys: pytest.CaptureFixture[str]) -> None:
    runpy.run_path(str(EXAMPLES / "one_decision.py"), run_name="__main__")
    out = capsys.readouterr().out
    assert "brute-force" in out and "pg-refine" in out
    assert "sensor 1, epoch 2" in out
