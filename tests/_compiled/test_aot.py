"""The planners' kernels compiled ahead of time: same plans bit for bit, no numba in a plan.

The module is built once (``sensorplan._compiled.aot.ensure_built``, about a minute, then cached
with
numba's kernels) by the ``built`` fixture; the rest of the suite runs numba's kernels
(``conftest.py`` sets ``SENSORPLAN_AOT=0``), so each comparison here is between the two.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sensorplan._compiled import aot as _aot, jit as _jit

ROOT = Path(__file__).resolve().parents[2]
SRC = ROOT / "src"
PROBLEM = ROOT / "examples" / "problem.json"


def _env(**extra: str) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k != "SENSORPLAN_AOT"}
    return {**env, "PYTHONPATH": f"{SRC}{os.pathsep}{ROOT / 'tests'}", **extra}


@pytest.fixture(scope="module")
def built() -> Path:
    if shutil.which("cc") is None and shutil.which("gcc") is None:
        pytest.skip("no C compiler: the ahead-of-time build needs one to link")
    old = os.environ.pop("SENSORPLAN_AOT", None)
    try:
        path = _aot.ensure_built()
    finally:
        if old is not None:
            os.environ["SENSORPLAN_AOT"] = old
    assert path is not None and path.is_file(), "the ahead-of-time build failed"
    return path


# ------------------------------------------------------------------ argument types

_ARRAYS = st.sampled_from([np.float64, np.int64, np.bool_, np.float32, np.int32])


@st.composite
def _args(draw: st.DrawFn) -> object:
    kind = draw(st.sampled_from(["array", "view", "readonly", "bool", "int", "float",
                                 "npint", "npfloat", "npbool", "tuple", "bigint"]))
    if kind in ("array", "view", "readonly"):
        shape = tuple(draw(st.lists(st.integers(1, 3), min_size=1, max_size=4)))
        a = np.zeros(shape, dtype=draw(_ARRAYS))
        if kind == "view":
            a = np.zeros(shape + (2,), dtype=a.dtype)[..., 0]
        if kind == "readonly":
            a.flags.writeable = False
        return a
    return {"bool": True, "int": 3, "float": 2.5, "npint": np.int64(4),
            "npfloat": np.float64(1.5), "npbool": np.bool_(False), "tuple": (1, 2),
            "bigint": 2 ** 70}[kind]


@settings(max_examples=200, deadline=None)
@given(st.lists(_args(), min_size=1, max_size=5))
def test_argument_keys_name_the_types_numba_gives(args: list) -> None:
    import numba

    key = _jit.arg_key(tuple(args))
    supported = (np.float64, np.int64, np.bool_)
    typable = all(
        (isinstance(a, np.ndarray) and a.dtype.type in supported and a.flags.c_contiguous)
        or isinstance(a, bool | float | np.bool_ | np.float64 | np.int64)
        or (type(a) is int and abs(a) < 2 ** 62) for a in args)
    if not typable:
        return                                  # a key may or may not exist; numba decides
    assert key is not None
    for a, item in zip(args, key, strict=True):
        assert _aot._numba_type(item) == numba.typeof(a)


def test_other_layouts_and_types_go_to_numba() -> None:
    a = np.zeros((3, 4))
    assert _jit.arg_key((a.T,)) is None                # Fortran order
    assert _jit.arg_key((a[:, ::2],)) is None          # strided
    assert _jit.arg_key(((1, 2),)) is None
    assert _jit.arg_key((2 ** 70,)) is None
    assert _jit.arg_key((a.astype(">f8"),)) is None    # byte-swapped


# ------------------------------------------------------------------ the build


def test_the_tag_follows_the_kernels_source_only(tmp_path: Path,
                                                 monkeypatch: pytest.MonkeyPatch) -> None:
    copy = tmp_path / "sensorplan"
    shutil.copytree(SRC / "sensorplan", copy, ignore=shutil.ignore_patterns("__pycache__"))
    monkeypatch.setattr(_aot, "PACKAGE", copy)
    before = _aot.tag()
    colors = copy / "figures" / "colors.py"
    colors.write_text(colors.read_text() + "\n# a comment\n")
    assert _aot.tag() == before                 # no kernel there: the build still holds
    kernel = copy / "planners" / "_gains_nb.py"
    kernel.write_text(kernel.read_text() + "\n# a comment\n")
    assert _aot.tag() != before                 # a kernel's source: a new build


def test_a_failed_build_is_said_once_and_numba_does_the_work(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.delenv("SENSORPLAN_AOT")
    monkeypatch.setattr(_aot, "places", lambda: [tmp_path / "aot"])
    monkeypatch.setattr(_aot, "tag", lambda: "0123456789abcdef")
    monkeypatch.setattr(sys, "executable", shutil.which("false") or "/bin/false")
    assert _aot.ensure_built() is None
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 2 and err[0].startswith("note: first plan: compiling")
    assert "`sensorplan compile` does it ahead" in err[0]
    assert err[1].startswith("note: could not compile the planning kernels ahead of time")
    assert (tmp_path / "aot" / "failed-0123456789abcdef.txt").is_file()
    assert _aot.ensure_built() is None          # remembered: no second try, no second word
    assert capsys.readouterr().err == ""
    monkeypatch.setenv("SENSORPLAN_AOT", "0")
    assert _aot.load() is None


def test_the_plans_are_those_of_numba_bit_for_bit(built: Path) -> None:
    from planner_reference import CASES
    from sensorplan.planners import make_planner

    code = """
import json, sys
from planner_reference import CASES
from sensorplan.planners import make_planner
out = {}
for case, (build, names, seed) in CASES.items():
    problem = build()
    for name in names:
        r = make_planner(name).plan(problem, rng=seed)
        out[f"{case}/{name}"] = [r.plan.targets.tolist(), r.plan.positions.tolist(),
                                 float(r.potential).hex(), r.sweeps, r.converged]
print(json.dumps({"plans": out, "numba": "numba" in sys.modules}))
"""
    done = subprocess.run([sys.executable, "-c", code], env=_env(), capture_output=True,
                          text=True, timeout=600, cwd=ROOT)
    assert done.returncode == 0, done.stderr
    ahead = json.loads(done.stdout)
    assert ahead["numba"] is False              # every call found its compiled kernel
    for case, (build, names, seed) in CASES.items():
        problem = build()
        for name in names:
            r = make_planner(name).plan(problem, rng=seed)
            targets, positions, phi, sweeps, converged = ahead["plans"][f"{case}/{name}"]
            np.testing.assert_array_equal(np.array(targets), r.plan.targets)
            np.testing.assert_array_equal(np.array(positions, dtype=float), r.plan.positions)
            assert phi == float(r.potential).hex(), f"{case}/{name}"
            assert (sweeps, converged) == (r.sweeps, r.converged)


def test_the_plan_command_does_not_load_numba(built: Path) -> None:
    code = ("import sys\nfrom sensorplan.cli.app import main\ntry:\n    main(sys.argv[1:])\n"
            "except SystemExit as e:\n    assert not e.code, e.code\n"
            "sys.stderr.write('NUMBA %s\\n' % ('numba' in sys.modules))")
    outs = []
    for aot in ("1", "0"):
        done = subprocess.run([sys.executable, "-c", code, "plan", str(PROBLEM)],
                              env=_env(SENSORPLAN_AOT=aot), capture_output=True, text=True,
                              timeout=600, cwd=ROOT)
        assert done.returncode == 0, done.stderr
        assert done.stderr.splitlines()[-1] == f"NUMBA {aot == '0'}"
        result = json.loads(done.stdout)
        result.pop("seconds")
        outs.append(result)
    assert outs[0] == outs[1]


def test_threads_that_load_numba_together_all_get_a_kernel() -> None:
    # The first calls of a process race to load numba: none may see a half-made dispatcher.
    code = """
import threading
import numpy as np
from sensorplan.models.radar import wrap
from sensorplan.planners._chains_nb import sum_by_target_nb
out, errors = [], []
def call():
    try:
        W, tgt = np.ones((1, 1, 1, 2, 2)), np.zeros((1, 1), dtype=np.int64)
        out.append((float(wrap(4.0)), sum_by_target_nb(W, tgt, 1).sum()))
    except Exception as e:
        errors.append(repr(e))
threads = [threading.Thread(target=call) for _ in range(8)]
for t in threads: t.start()
for t in threads: t.join()
assert not errors, errors
assert out == [(4.0 - 2 * np.pi, 4.0)] * 8, out
"""
    done = subprocess.run([sys.executable, "-c", code], env=_env(SENSORPLAN_AOT="0"),
                          capture_output=True, text=True, timeout=600, cwd=ROOT)
    assert done.returncode == 0, done.stderr


def test_a_read_only_install_finds_them_in_its_private_temp_dir(built: Path,
                                                                 tmp_path: Path) -> None:
    from cli.test_startup import _read_only_copy    # tests/ is on the path

    pkg = _read_only_copy(tmp_path)
    blocker = tmp_path / "blocker"                    # a file: nothing can be made under it
    blocker.write_text("")
    temp = tmp_path / "tmp"
    place = temp / f"sensorplan-numba-{os.getuid()}" / "sensorplan-aot"
    place.mkdir(parents=True)
    shutil.copy(built, place)          # the same sources, so the same name (tag)
    env = {**_env(), "PYTHONPATH": str(pkg), "PYTHONDONTWRITEBYTECODE": "1",
           "HOME": str(blocker / "home"), "XDG_CACHE_HOME": str(blocker / "cache"),
           "NUMBA_CACHE_DIR": str(blocker / "numba"), "TMPDIR": str(temp)}
    code = ("import sys\nfrom sensorplan.cli.app import main\ntry:\n    main(sys.argv[1:])\n"
            "except SystemExit as e:\n    assert not e.code, e.code\n"
            "assert 'numba' not in sys.modules")
    try:
        done = subprocess.run([sys.executable, "-c", code, "plan", str(PROBLEM)], env=env,
                              capture_output=True, text=True, timeout=600, cwd=tmp_path)
    finally:
        for p in [pkg, *pkg.rglob("*")]:
            p.chmod(p.stat().st_mode | 0o200)
    assert done.returncode == 0, done.stderr
    assert done.stderr == ""                          # found: nothing to build, nothing to say
    assert json.loads(done.stdout)["planner"] == "pg"


def test_old_builds_are_pruned_and_used_ones_kept(tmp_path: Path) -> None:
    import time

    now = time.time()
    suffix = _aot._suffix()
    files = {name: tmp_path / name for name in (
        f"sensorplan_aot_{'a' * 16}{suffix}", f"sensorplan_aot_{'b' * 16}{suffix}",
        f"sensorplan_aot_{'c' * 16}{suffix}", "failed-dddddddddddddddd.txt", "other.txt")}
    for f in files.values():
        f.write_text("")
    old = now - (_aot.UNUSED_DAYS + 1) * _aot.DAY
    a, b, c, failed, other = files.values()
    for f in (a, c, failed, other):
        os.utime(f, (old, old))
    stale, running = tmp_path / "tmpstale", tmp_path / "tmprunning"   # builds' directories
    for d in (stale, running):
        (d / "part").mkdir(parents=True)
    os.utime(stale, (now - 2 * _aot.DAY, now - 2 * _aot.DAY))
    gone = _aot.prune(tmp_path, keep=c, now=now)
    # b is recent, c is the new build; a build killed outright a day ago left its directory
    assert sorted(gone) == sorted([a, failed, stale])
    assert b.exists() and c.exists() and other.exists() and running.exists()


def test_a_temp_dir_others_can_write_in_is_not_searched(tmp_path: Path,
                                                        monkeypatch: pytest.MonkeyPatch) -> None:
    from sensorplan._compiled import cache as _kernel_cache
    monkeypatch.setattr(_aot.tempfile, "gettempdir", lambda: str(tmp_path))
    private = Path(_kernel_cache.private_path(str(tmp_path)))
    private.mkdir(mode=0o700)
    assert _aot.places()[-1] == private / _aot.SUBDIR
    private.chmod(0o777)                # anyone could have put a module there
    assert private / _aot.SUBDIR not in _aot.places()
    assert _kernel_cache._private_dir(str(tmp_path)) != str(private)   # a fresh one instead


# ------------------------------------------------------------------ sensorplan compile


def test_a_second_compile_with_a_current_build_does_nothing_and_says_so(built: Path) -> None:
    before = built.stat().st_mtime_ns
    done = subprocess.run([sys.executable, "-m", "sensorplan", "compile"], env=_env(),
                          capture_output=True, text=True, timeout=600, cwd=ROOT)
    assert done.returncode == 0, done.stderr
    assert done.stderr.splitlines()[-1] == (f"note: compile: everything is current ({built}); "
                                            "nothing to do")
    assert done.stdout == f"compiled kernels: {built} and numba's disk cache\n"
    assert built.stat().st_mtime_ns == before
    assert not list(built.parent.glob("tmp*"))


#: ``sensorplan compile`` with the module's place in a temporary directory (so it builds).
COMPILE_ELSEWHERE = """
import sys
from pathlib import Path
import sensorplan._compiled.aot as aot
place = Path(sys.argv[1])
aot.places = lambda: [place]
sys.argv = ["sensorplan", "compile"]
from sensorplan.cli.launch import main
main()
"""


def _descendants(pid: int) -> set[int]:
    """The processes below ``pid`` (Linux /proc)."""
    parents: dict[int, int] = {}
    for stat_file in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat_file.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        parents[int(stat_file.parent.name)] = int(fields[1])
    out: set[int] = set()
    todo = [pid]
    while todo:
        p = todo.pop()
        kids = {c for c, parent in parents.items() if parent == p}
        todo.extend(kids - out)
        out |= kids
    return out


def _alive(pid: int) -> bool:
    """Whether process ``pid`` runs (a zombie has ended; its reaper collects it)."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except (OSError, IndexError):
        return False


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads /proc")
def test_an_interrupted_compile_leaves_nothing_half_built(tmp_path: Path) -> None:
    if shutil.which("cc") is None and shutil.which("gcc") is None:
        pytest.skip("no C compiler: the ahead-of-time build needs one to link")
    place = tmp_path / "aot"
    proc = subprocess.Popen([sys.executable, "-c", COMPILE_ELSEWHERE, str(place)], env=_env(),
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            cwd=ROOT, start_new_session=True)
    try:
        deadline = time.monotonic() + 300
        while not list(place.glob("tmp*")):        # the child is building
            assert proc.poll() is None, proc.communicate()
            assert time.monotonic() < deadline, "the build did not start"
            time.sleep(0.05)
        builders = _descendants(proc.pid)
        assert builders
        os.killpg(proc.pid, signal.SIGINT)         # Ctrl-C in a terminal: the whole group
        out, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert proc.returncode == 130, err
    assert err.splitlines()[-1] == "error: interrupted" and "Traceback" not in err
    assert out == ""
    # No module, no half-built directory, no note of a failure that would stop a retry.
    assert sorted(p.name for p in place.iterdir()) == []
    assert not {p for p in builders if _alive(p)}


# --------------------------------------------------------- planning times without warm-up

#: Runs a study's method (by index) for a few decisions as a study's worker does, and
#: records at every reading of the planners' clock whether numba is loaded and how many
#: compiled kernel versions this process holds.
TIMED_DECISIONS = """
import dataclasses, json, sys
from sensorplan._compiled import jit
from sensorplan.planners import PLANNERS, anytime
from sensorplan.study import load_study
from sensorplan.study.execution import _pool_init, run_task

study = load_study(sys.argv[1])
m = int(sys.argv[2])
short = tuple(dataclasses.replace(x, settings=dataclasses.replace(x.settings, steps=6))
              for x in study.methods)
study = dataclasses.replace(study, steps=6, methods=short)
readings, decisions = [], []
clock = anytime.clock
def reading():
    readings.append((jit.is_active(), jit.loaded()))
    return clock()
anytime.clock = reading
cls = PLANNERS[study.methods[m].settings.planner]
plan = cls.plan
def timed(self, problem, rng=None):
    readings.clear()
    result = plan(self, problem, rng)
    decisions.append(list(readings))
    return result
cls.plan = timed
_pool_init(study)                     # a worker's start
run_task(study, 0, m)
print(json.dumps(decisions))
"""


@pytest.mark.parametrize("method", [0, 2, 3, 5, 6])   # random, myopic (detection
# ignored), OLF pg K=3, pg-refine, sequential-greedy
def test_no_decision_of_a_fresh_worker_includes_loading_a_kernel(built: Path,
                                                                 method: int) -> None:
    # A study's worker found the ahead-of-time module: its first decision ran it, the
    # tracker's first step loaded numba, and the second decision waited for numba's
    # cached kernels (0.05-1.5 s against a few ms).
    done = subprocess.run([sys.executable, "-c", TIMED_DECISIONS,
                           str(ROOT / "studies" / "radar.toml"), str(method)],
                          env=_env(), capture_output=True, text=True, timeout=600, cwd=ROOT)
    assert done.returncode == 0, done.stderr
    decisions = json.loads(done.stdout)
    assert len(decisions) == 3
    for d in decisions:
        # While the planner's clock runs: numba's kernels, none loaded or compiled. (The
        # tracker loads its own between decisions.)
        assert {tuple(r) for r in d} == {(True, d[0][1])}, decisions
