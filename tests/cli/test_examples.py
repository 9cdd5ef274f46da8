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


@pytest.mark.parametrize("path", sorted(EXAMPLES.glob("*.py")), ids=lambda p: p.name)
def test_an_example_with_options_describes_itself(path: Path) -> None:
    # `python examples/X.py --help` shows the module docstring; a file that starts with a
    # `# %%` cell has none unless a string is its first statement.
    import ast

    module = ast.parse(path.read_text())
    if "description=__doc__" in path.read_text():
        assert (ast.get_docstring(module) or "").strip(), f"{path.name} has no docstring"


def test_the_stonesoup_example_help_has_its_description() -> None:
    import subprocess
    import sys

    pytest.importorskip("stonesoup")
    res = subprocess.run([sys.executable, str(EXAMPLES / "stonesoup_loop.py"), "--help"],
                         capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr
    assert "A Stone Soup tracking loop steered by a sensorplan planner" in res.stdout
