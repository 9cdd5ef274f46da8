"""``sensorplan compile`` and the fallback to numba's disk cache where ``numba.pycc`` is
missing (numba lists it under its deprecation notices)."""

from __future__ import annotations

import json
import os
import re
import sys
import tomllib
from pathlib import Path

import pytest

from sensorplan._compiled import aot as _aot

ROOT = Path(__file__).resolve().parents[2]
SRC = ROOT / "src"
PROBLEM = ROOT / "examples" / "problem.json"


def _env(**extra: str) -> dict[str, str]:
    drop = ("SENSORPLAN_AOT", "SENSORPLAN_FIRST_RUN_NOTED")
    env = {k: v for k, v in os.environ.items() if k not in drop}
    return {**env, "PYTHONPATH": f"{SRC}{os.pathsep}{ROOT / 'tests'}", **extra}


def test_the_pinned_numba_ships_pycc() -> None:
    # The pin keeps numba below the first release that could drop numba.pycc.
    deps = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["dependencies"]
    pin = next(d for d in deps if d.startswith("numba"))
    upper = re.search(r"<\s*([\d.]+)", pin)
    assert upper is not None, f"numba is not pinned below a release: {pin}"
    import numba

    installed = tuple(int(p) for p in numba.__version__.split(".")[:2])
    assert installed < tuple(int(p) for p in upper.group(1).split(".")[:2])
    assert _aot.pycc_missing() is None


def test_a_numba_without_pycc_is_named(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "numba.pycc", None)      # the import fails
    why = _aot.pycc_missing()
    assert why is not None and "numba.pycc" in why


#: A numba without numba.pycc (its import fails), the ahead-of-time module's place in a
#: temporary directory; then ``sensorplan compile`` and two plans in the same process.
WITHOUT_PYCC = """
import io, json, sys
from contextlib import redirect_stderr, redirect_stdout
from pathlib import Path
sys.modules["numba.pycc"] = None
import sensorplan._compiled.aot as aot
aot.places = lambda: [Path(sys.argv[1])]
from sensorplan.cli.app import main
out = []
for args in (["compile"], ["plan", sys.argv[2]], ["plan", sys.argv[2]]):
    o, e = io.StringIO(), io.StringIO()
    with redirect_stdout(o), redirect_stderr(e):
        try:
            main(args)
        except SystemExit as exc:
            code = exc.code or 0
    out.append([code, o.getvalue(), e.getvalue()])
print(json.dumps({"runs": out, "numba": "numba" in sys.modules}))
"""


def test_without_pycc_compile_and_plan_fall_back_to_numbas_disk_cache(tmp_path: Path) -> None:
    import subprocess

    place = tmp_path / "aot"
    done = subprocess.run([sys.executable, "-c", WITHOUT_PYCC, str(place), str(PROBLEM)],
                          env=_env(), capture_output=True, text=True, timeout=600, cwd=ROOT)
    assert done.returncode == 0, done.stderr
    res = json.loads(done.stdout)
    (c_code, c_out, c_err), (p_code, p_out, p_err), (q_code, q_out, q_err) = res["runs"]
    assert c_code == 0, c_err
    assert "no ahead-of-time module (this numba has no numba.pycc" in c_err
    assert c_out.startswith("compiled kernels: numba's disk cache (this numba has no")
    assert "Traceback" not in c_err
    assert p_code == q_code == 0, (p_err, q_err)
    # The first plan says it once, the second says nothing; both plan with numba's kernels.
    assert p_err.splitlines() == [line for line in p_err.splitlines()
                                  if line.startswith("note: no ahead-of-time kernels (")]
    assert len(p_err.splitlines()) == 1 and q_err == ""
    assert res["numba"] is True
    assert not list(place.glob("sensorplan_aot_*"))           # nothing was built
    mine, theirs = json.loads(p_out), json.loads(q_out)
    mine.pop("seconds")
    theirs.pop("seconds")
    assert mine == theirs and mine["planner"] == "pg"
