"""``sensorplan compile`` and the fallback to numba's disk cache where ``numba.pycc`` is
missing (numba lists it under its deprecation notices)."""

from __future__ import annotations

import json
import os
import re
import sys
import tomllib
from pathlib import Path
from typing import ClassVar

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


# ------------------------------------------------------------- a study's first run

STUDY = """
runs = 2
steps = 4
seed = 5
[[methods]]
name = "random"
planner = "random"
"""


def test_a_pool_study_says_the_first_run_note_once_and_compiles_before_its_workers(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capfd: pytest.CaptureFixture[str]) -> None:
    # Each worker said the note and compiled every kernel itself, at the same time.
    from sensorplan import study as studies
    from sensorplan._compiled import cache, prepare
    from sensorplan.study import execution, parse_study

    monkeypatch.delenv("SENSORPLAN_FIRST_RUN_NOTED", raising=False)
    # numba's cache holds no kernel of this package, as far as this process can tell (the
    # workers find the real one: they only load).
    monkeypatch.setattr(cache, "_has_kernels", lambda root, mine: False)
    order: list[str] = []
    warm = prepare.warm_listed
    monkeypatch.setattr(prepare, "warm_listed", lambda: (order.append("compiled"), warm())[1])
    pool = execution._process_pool

    def started(*args: object) -> object:
        order.append(f"workers (noted: {os.environ.get('SENSORPLAN_FIRST_RUN_NOTED')})")
        return pool(*args)                       # type: ignore[arg-type]

    monkeypatch.setattr(execution, "_process_pool", started)
    studies.run_study(parse_study(STUDY), tmp_path / "s", workers=2)
    notes = [line for line in capfd.readouterr().err.splitlines() if "first run" in line]
    assert notes == ["note: first run: compiling the numerical kernels once (about a minute); "
                     "they are cached for every later run"]
    assert order == ["compiled", "workers (noted: 1)"]


def test_a_task_that_loaded_kernels_gives_the_eta_no_time_to_extrapolate(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    # The first (run, method) of a worker counted its kernels' compilation and the ETA
    # extrapolated from it: 1,516 s for a study that took 137 s.
    import dataclasses

    import numpy as np

    from sensorplan import study as studies
    from sensorplan._compiled.jit import njit
    from sensorplan.planners import PLANNERS
    from sensorplan.planners.random_plan import RandomPlanner
    from sensorplan.study import parse_study

    fresh = njit(lambda x: x + 1.0)                    # compiled at its first call

    @dataclasses.dataclass(frozen=True)
    class CompilesOnce(RandomPlanner):
        name: ClassVar[str] = "compiles-once"

        def plan(self, problem, rng=None):              # type: ignore[no-untyped-def]
            fresh(np.zeros(1))
            return super().plan(problem, rng)

    monkeypatch.setitem(PLANNERS, "compiles-once", CompilesOnce)
    calls: list[tuple[int, float | None]] = []

    def progress(done: int, total: int, already: int, seconds: float | None = None) -> None:
        if done:
            calls.append((done, seconds))

    text = STUDY.replace('planner = "random"', 'planner = "compiles-once"')
    studies.run_study(parse_study(text), tmp_path / "s", workers=1, progress=progress)
    assert [done for done, _ in calls] == [1, 2]
    assert calls[0][1] is None                          # it compiled: not a unit of work
    assert isinstance(calls[1][1], float) and calls[1][1] > 0
