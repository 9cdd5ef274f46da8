"""Fast start and cold start: what ``import sensorplan`` and ``--help`` load, ``--version``,
and a read-only install (package, home and NUMBA_CACHE_DIR not writable)."""

from __future__ import annotations

import json
import os
import shutil
import stat
import subprocess
import sys
from pathlib import Path

import pytest

import sensorplan
from cli_helpers import run

ROOT = Path(__file__).resolve().parents[2]
SRC = ROOT / "src"
PROBLEM = ROOT / "examples" / "problem.json"
#: Modules that neither ``import sensorplan`` nor ``sensorplan --help`` may load: the
#: compiled kernels, the plotting and table stacks, and numpy itself (for a fast --help).
HEAVY = ("numpy", "numba", "llvmlite", "scipy", "matplotlib", "pandas", "pyarrow", "dask",
         "distributed", "zmq")

PROBE = """
import json, sys
{code}
loaded = sorted(m for m in {heavy!r} if m in sys.modules)
sys.stderr.write("LOADED " + json.dumps(loaded) + "\\n")
"""


def _loaded(code: str) -> list[str]:
    env = {**os.environ, "PYTHONPATH": str(SRC)}
    done = subprocess.run([sys.executable, "-c", PROBE.format(code=code, heavy=HEAVY)],
                          env=env, capture_output=True, text=True, timeout=120)
    line = next(ln for ln in done.stderr.splitlines() if ln.startswith("LOADED "))
    return json.loads(line.removeprefix("LOADED "))


def test_import_sensorplan_loads_nothing_heavy() -> None:
    assert _loaded("import sensorplan, sensorplan.planners, sensorplan.simulation.settings, "
                   "sensorplan.decentral.params") == []
    # ... and the lazy names still work.
    assert _loaded("from sensorplan.planners import PLANNERS; list(PLANNERS)") == []
    # The kernels load numba at their first call that needs it, not at import.
    assert _loaded("from sensorplan import potential") == ["numpy"]


def test_help_loads_nothing_heavy() -> None:
    code = ("from sensorplan.cli.app import main\n"
            "for args in (['--help'], ['simulate', '--help'], ['plan', '--help'],\n"
            "             ['agents', '--help']):\n"
            "    try:\n        main(args)\n    except SystemExit:\n        pass")
    assert _loaded(code) == []


def test_version(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = run(capsys, "--version")
    assert (code, out, err) == (0, f"sensorplan {sensorplan.__version__}\n", "")
    # The package's version is the distribution's (pyproject.toml), not a second number.
    assert f'\nversion = "{sensorplan.__version__}"\n' in (ROOT / "pyproject.toml").read_text()


def test_make_compiles_the_kernels_after_installing_and_before_its_stamp() -> None:
    # make demo and make test set up, then compile, then mark the set-up done: an
    # interrupted compile runs again at the next make.
    if shutil.which("make") is None:
        pytest.skip("no make")
    for target in ("demo", "test"):
        planned = subprocess.run(["make", "-n", "-B", target], cwd=ROOT, capture_output=True,
                                 text=True, timeout=60, check=True).stdout.splitlines()
        install = max(i for i, ln in enumerate(planned) if "pip install" in ln)
        compiled = [i for i, ln in enumerate(planned) if ln.endswith("sensorplan compile")]
        stamp = next(i for i, ln in enumerate(planned) if ln.startswith("touch "))
        assert len(compiled) == 1 and install < compiled[0] < stamp, planned


# --------------------------------------------------------------- read-only install


def _read_only_copy(tmp_path: Path) -> Path:
    """The package copied under tmp_path/pkg, read-only, with a plain file where each
    ``__pycache__`` directory would go (so that not even root can cache next to it)."""
    pkg = tmp_path / "pkg"
    shutil.copytree(SRC / "sensorplan", pkg / "sensorplan",
                    ignore=shutil.ignore_patterns("__pycache__"))
    for d in [pkg, *[p for p in pkg.rglob("*") if p.is_dir()]]:
        (d / "__pycache__").write_text("")
    for p in [pkg, *pkg.rglob("*")]:
        p.chmod(p.stat().st_mode & ~(stat.S_IWUSR | stat.S_IWGRP | stat.S_IWOTH))
    return pkg


def _seed_cache(pkg: Path, fallback: Path, leave_out: str) -> None:
    """Copy the warm kernel cache of this checkout, but the files whose names start with
    ``leave_out`` (a module and kernel), to where the read-only copy will look for it
    (numba names a cache directory after each source directory), so that the test does
    not compile every kernel again (two minutes). Without it the test is only slower."""
    from numba.core.caching import UserProvidedCacheLocator

    from sensorplan._compiled.prepare import warm_listed

    warm_listed()                       # every planning kernel is in this checkout's cache
    for cached in (SRC / "sensorplan").rglob("__pycache__"):
        files = [f for f in cached.iterdir() if f.suffix in (".nbi", ".nbc")
                 and not f.name.startswith(leave_out + ".")]
        if not files:
            continue
        source_dir = pkg / cached.parent.relative_to(SRC)
        sub = UserProvidedCacheLocator.get_suitable_cache_subpath(str(source_dir / "m.py"))
        (fallback / sub).mkdir(parents=True, exist_ok=True)
        for f in files:
            shutil.copy(f, fallback / sub)


def test_a_read_only_install_caches_the_kernels_in_a_temp_dir(tmp_path: Path) -> None:
    pkg = _read_only_copy(tmp_path)
    blocker = tmp_path / "blocker"                    # a file: nothing can be made under it
    blocker.write_text("")
    temp = tmp_path / "tmp"
    temp.mkdir()
    uid = os.getuid()
    _seed_cache(pkg, temp / f"sensorplan-numba-{uid}", leave_out="_chains_nb.sum_by_target_nb")
    env = {**os.environ, "PYTHONPATH": str(pkg), "PYTHONDONTWRITEBYTECODE": "1",
           "HOME": str(blocker / "home"), "XDG_CACHE_HOME": str(blocker / "cache"),
           "NUMBA_CACHE_DIR": str(blocker / "numba"), "TMPDIR": str(temp)}
    try:
        done = subprocess.run([sys.executable, "-m", "sensorplan", "plan", str(PROBLEM)],
                              env=env, capture_output=True, text=True, timeout=600,
                              cwd=tmp_path)
    finally:
        for p in [pkg, *pkg.rglob("*")]:
            p.chmod(p.stat().st_mode | stat.S_IWUSR)
    assert done.returncode == 0, done.stderr
    assert json.loads(done.stdout)["planner"] == "pg"
    lines = done.stderr.splitlines()
    assert len(lines) == 1 and "Traceback" not in done.stderr
    assert lines[0].startswith("note: cannot write numba's kernel cache (")
    assert f"caching the compiled kernels in {temp / f'sensorplan-numba-{uid}'}" in lines[0]
    # The kernel left out was compiled by the plan and cached there.
    assert any(temp.rglob("_chains_nb.sum_by_target_nb-*.nbi"))


def test_nowhere_writable_compiles_without_a_cache(tmp_path: Path,
                                                   monkeypatch: pytest.MonkeyPatch,
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    import numba
    from numba.core import dispatcher

    from sensorplan._compiled import cache as _kernel_cache
    blocker = tmp_path / "blocker"
    blocker.write_text("")
    monkeypatch.setattr(_kernel_cache, "cache_places",
                        lambda: [str(blocker / "a"), str(blocker / "b")])
    monkeypatch.setattr(_kernel_cache.tempfile, "gettempdir", lambda: str(blocker / "tmp"))
    monkeypatch.setattr(numba.config, "CACHE_DIR", numba.config.CACHE_DIR)
    monkeypatch.setattr(dispatcher.Dispatcher, "enable_caching",
                        dispatcher.Dispatcher.enable_caching)
    monkeypatch.delenv("NUMBA_CACHE_DIR", raising=False)
    notice = _kernel_cache.ensure_cache()
    assert notice is not None and "without a cache" in notice
    assert capsys.readouterr().err == notice + "\n"
    twice = numba.njit(cache=True)(lambda x: 2 * x)    # would raise if caching were on
    assert twice(21) == 42
    assert "NUMBA_CACHE_DIR" not in os.environ


def test_a_writable_place_changes_nothing(monkeypatch: pytest.MonkeyPatch,
                                          tmp_path: Path) -> None:
    from sensorplan._compiled import cache as _kernel_cache
    monkeypatch.setattr(_kernel_cache, "cache_places", lambda: [str(tmp_path / "cache")])
    assert _kernel_cache.ensure_cache() is None


def _import_jit(env_extra: dict[str, str]) -> str:
    env = {k: v for k, v in os.environ.items() if k != "SENSORPLAN_FIRST_RUN_NOTED"}
    done = subprocess.run([sys.executable, "-c",
                           "import sensorplan._compiled.jit as j; j.activate()"],
                          env={**env, "PYTHONPATH": str(SRC), **env_extra},
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    return done.stderr


def test_a_fresh_cache_says_once_that_the_kernels_are_being_compiled(tmp_path: Path) -> None:
    cold = tmp_path / "cold"
    err = _import_jit({"NUMBA_CACHE_DIR": str(cold)})
    assert err.splitlines() == ["note: first run: compiling the numerical kernels once (about "
                                "a minute); they are cached for every later run"]
    # Child processes (study workers, agents) inherit the note as given.
    assert _import_jit({"NUMBA_CACHE_DIR": str(cold), "SENSORPLAN_FIRST_RUN_NOTED": "1"}) == ""
    # Another package's cached kernels do not count; this package's do.
    other = tmp_path / "warm" / "elsewhere" / "otherpkg"
    other.mkdir(parents=True)
    (other / "mod.f-1.py311.nbi").write_bytes(b"")
    assert _import_jit({"NUMBA_CACHE_DIR": str(tmp_path / "warm")}) != ""
    ours = tmp_path / "warm" / "src" / "sensorplan"
    ours.mkdir(parents=True)
    (ours / "radar.f-1.py311.nbi").write_bytes(b"")
    assert _import_jit({"NUMBA_CACHE_DIR": str(tmp_path / "warm")}) == ""


def test_a_read_only_home_gives_matplotlib_a_private_directory_quietly(tmp_path: Path
                                                                       ) -> None:
    # matplotlib, left alone, prints two warning lines at every figure when it cannot
    # write its configuration and cache directories (a read-only home).
    blocker = tmp_path / "blocker"                    # a file: nothing can be made under it
    blocker.write_text("")
    temp = tmp_path / "tmp"
    temp.mkdir()
    env = {k: v for k, v in os.environ.items()
           if k not in ("MPLCONFIGDIR", "XDG_CONFIG_HOME", "XDG_CACHE_HOME")}
    env.update({"PYTHONPATH": str(SRC), "HOME": str(blocker / "home"), "TMPDIR": str(temp)})
    done = subprocess.run([sys.executable, "-m", "sensorplan", "simulate", "--preset", "paper",
                           "--steps", "2", "--out", str(tmp_path / "o")], env=env,
                          capture_output=True, text=True, timeout=600, cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert "matplotlib" not in done.stderr.lower() and "warning" not in done.stderr.lower()
    assert (tmp_path / "o" / "episode.png").stat().st_size > 0
    private = temp / f"sensorplan-matplotlib-{os.getuid()}"
    assert private.is_dir() and stat.S_IMODE(private.stat().st_mode) == 0o700


def test_a_writable_home_leaves_matplotlib_alone(monkeypatch: pytest.MonkeyPatch,
                                                 tmp_path: Path) -> None:
    from sensorplan.cli.guards import quiet_matplotlib_dirs

    monkeypatch.delenv("MPLCONFIGDIR", raising=False)
    monkeypatch.setenv("HOME", str(tmp_path / "home"))       # not there yet: can be made
    monkeypatch.delenv("XDG_CONFIG_HOME", raising=False)
    monkeypatch.delenv("XDG_CACHE_HOME", raising=False)
    quiet_matplotlib_dirs()
    assert "MPLCONFIGDIR" not in os.environ
    assert not (tmp_path / "home").exists()                  # nothing made by looking


def test_the_command_line_turns_numpys_huge_pages_off_unless_the_user_chose() -> None:
    from sensorplan.memory import numpy_defaults

    env: dict[str, str] = {}
    numpy_defaults(env)
    assert env == {"NUMPY_MADVISE_HUGEPAGE": "0"}
    env = {"NUMPY_MADVISE_HUGEPAGE": "1"}
    numpy_defaults(env)
    assert env == {"NUMPY_MADVISE_HUGEPAGE": "1"}             # the user's choice stands
    # numpy reads it when imported: what the command line's process gets.
    code = ("import os; from sensorplan.memory import numpy_defaults; "
            "numpy_defaults(os.environ); import numpy._core.multiarray as m; "
            "print(m._get_madvise_hugepage())")
    env_run = {k: v for k, v in os.environ.items() if k != "NUMPY_MADVISE_HUGEPAGE"}
    env_run["PYTHONPATH"] = str(SRC)
    out = subprocess.run([sys.executable, "-c", code], env=env_run, capture_output=True,
                         text=True, timeout=120, check=True)
    assert out.stdout.strip() == "False"


_GLIBC = bool(getattr(os, "confstr_names", {}).get("CS_GNU_LIBC_VERSION")) and bool(
    os.confstr("CS_GNU_LIBC_VERSION"))

_ALLOCATOR = """
import ctypes, os, sys
import sensorplan
from sensorplan.memory import malloc_defaults

class Mallinfo2(ctypes.Structure):
    _fields_ = [(f, ctypes.c_size_t) for f in ("arena", "ordblks", "smblks", "hblks", "hblkhd",
                                               "usmblks", "fsmblks", "uordblks", "fordblks",
                                               "keepcost")]

libc = ctypes.CDLL(None)
libc.mallinfo2.restype = Mallinfo2
libc.malloc.restype, libc.malloc.argtypes = ctypes.c_void_p, (ctypes.c_size_t,)
libc.free.argtypes = (ctypes.c_void_p,)
made = (None if sys.argv[1] == "0" else malloc_defaults(os.environ) if sys.argv[1] == "1"
        else sensorplan.keep_freed_memory())
print(made, os.environ.get("MALLOC_MMAP_THRESHOLD_"), os.environ.get("MALLOC_TRIM_THRESHOLD_"))
before = libc.mallinfo2()
block = libc.malloc(8 << 20)
held = libc.mallinfo2()
libc.free(block)
freed = libc.mallinfo2()
# mapped bytes gained by the block; heap bytes kept once it is freed
print(held.hblkhd - before.hblkhd, freed.arena - before.arena)
"""


def test_the_command_lines_allocator_settings_leave_the_users_alone(
        monkeypatch: pytest.MonkeyPatch) -> None:
    import sensorplan
    from sensorplan.memory import malloc_defaults

    assert not malloc_defaults({"MALLOC_TRIM_THRESHOLD_": "131072"})
    assert not malloc_defaults({"MALLOC_MMAP_THRESHOLD_": "131072"})
    assert not malloc_defaults({"GLIBC_TUNABLES": "glibc.malloc.trim_threshold=131072"})
    # The library's switch reads the process's environment the same way.
    for var, value in (("MALLOC_TRIM_THRESHOLD_", "131072"), ("MALLOC_MMAP_THRESHOLD_", "131072"),
                       ("GLIBC_TUNABLES", "glibc.malloc.mmap_threshold=131072")):
        with monkeypatch.context() as m:
            m.setenv(var, value)
            assert not sensorplan.keep_freed_memory()
            assert os.environ[var] == value


@pytest.mark.skipif(not _GLIBC, reason="glibc's allocator only")
def test_the_allocator_settings_keep_a_freed_block_for_reuse() -> None:
    # What the library controls is glibc's two thresholds; how many page faults that saves
    # depends on the host and its load (benchmarks/bench_memory.py measures it). An 8 MiB
    # block is above glibc's default mapping threshold (128 KiB to start with): mapped on
    # its own and unmapped when freed. With the settings it comes from the heap, which keeps
    # it after it is freed.
    env = {k: v for k, v in os.environ.items()
           if k not in ("MALLOC_MMAP_THRESHOLD_", "MALLOC_TRIM_THRESHOLD_", "GLIBC_TUNABLES")}
    env["PYTHONPATH"] = str(SRC)
    block = 8 << 20
    # "0": glibc's defaults; "1": the command line's call, which also puts the settings in
    # the environment for the processes it starts (a study's workers); "2": the library's
    # switch, which leaves the environment alone.
    expected = {"0": ["None", "None", "None"], "1": ["True", str(32 * 2**20), str(2**30)],
                "2": ["True", "None", "None"]}
    for on in ("0", "1", "2"):
        out = subprocess.run([sys.executable, "-c", _ALLOCATOR, on], env=env,
                             capture_output=True, text=True, timeout=120,
                             check=True).stdout.split()
        assert out[:3] == expected[on]
        mapped, kept = int(out[3]), int(out[4])
        if on == "0":
            assert mapped >= block and kept < block, out
        else:
            assert mapped == 0 and kept >= block, out


@pytest.mark.parametrize("bad", ["abc", "", "1.5"])
def test_a_huge_pages_value_numpy_cannot_read_is_refused_in_one_line(bad: str) -> None:
    env = {**os.environ, "PYTHONPATH": str(SRC), "NUMPY_MADVISE_HUGEPAGE": bad}
    done = subprocess.run([sys.executable, "-m", "sensorplan", "plan", str(PROBLEM)], env=env,
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 2, done.stderr
    assert done.stdout == ""
    assert done.stderr.splitlines() == [
        f"error: NUMPY_MADVISE_HUGEPAGE: must be 0 (off) or 1 (on), numpy's setting; got "
        f"{bad!r} (or unset it)"]
    env["NUMPY_MADVISE_HUGEPAGE"] = "1"                     # a value numpy reads: planned
    done = subprocess.run([sys.executable, "-m", "sensorplan", "plan", str(PROBLEM)], env=env,
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
