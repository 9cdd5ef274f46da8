"""The planners' kernels compiled ahead of time, so that a plan does not wait for numba.

Importing numba and loading its cached kernels takes about a second, most of a one-decision
process. The kernels the planners call from Python, for the argument types listed in
:mod:`sensorplan._compiled.aot_signatures`, are therefore also compiled by numba's ahead-of-time
compiler (``numba.pycc``: the same source, compiler and options, for this machine's CPU) into
one extension module that needs numpy only. :mod:`sensorplan._compiled.jit` calls it whenever it
holds a call's argument types, numba's dispatcher otherwise.

* **Where**: ``sensorplan-aot/`` in the first writable place of: ``NUMBA_CACHE_DIR``, the
  package's ``__pycache__`` directory, the user's cache directory (``~/.cache/numba``),
  a private directory under the system's temporary directory. A build deletes the modules
  beside it that no process has loaded for 30 days (:func:`prune`).
* **When**: ``sensorplan plan`` builds it the first time it is missing (about a minute, in a
  child process, said in one line on stderr); :func:`ensure_built` does the same for any
  caller. The module's name carries a hash of the kernels' source, the signature list, the
  Python, numpy and numba versions and the CPU, so a change of any of them builds a new
  one; an old one is never used.
* **When not**: ``SENSORPLAN_AOT=0`` turns it off (numba's kernels only). A build that fails
  (no C compiler, say) is said once and remembered; the kernels then stay numba's.
"""

from __future__ import annotations

import hashlib
import importlib.machinery
import importlib.util
import os
import platform
import shutil
import subprocess
import sys
import sysconfig
import tempfile
import time
from pathlib import Path
from typing import Any

from .cache import (NOTICE, _private_dir, _writable, cache_places, is_private,
                    private_path)

PACKAGE = Path(__file__).resolve().parents[1]
SUBDIR = "sensorplan-aot"
DAY = 86400.0
#: A built module not loaded for this many days is deleted by the next build beside it.
UNUSED_DAYS = 30
#: The child process that builds the module (numba's dispatchers first: the exported
#: kernels call others, which numba must see as its own). It reads numba's disk cache but
#: writes nothing to it: the kernels it compiles on the way are not all a later command
#: needs, and a cache holding some would hide that command's "first run" note.
BUILD = ("import sys; sys.path.insert(0, sys.argv[1]); from pathlib import Path; "
         "from numba.core.caching import Cache; "
         "Cache.save_overload = lambda self, sig, data: None; "
         "from sensorplan._compiled.jit import activate; activate(); "
         "from sensorplan._compiled.aot import build; print(build(Path(sys.argv[2])))")


def enabled() -> bool:
    """Whether ahead-of-time kernels may be used (``SENSORPLAN_AOT`` is not ``0``; the
    command line refuses any value but ``0`` and ``1``)."""
    return os.environ.get("SENSORPLAN_AOT", "1").strip() != "0"


def _cpu() -> str:
    """What identifies this CPU's instruction set (the build is for the host CPU)."""
    try:
        with open("/proc/cpuinfo", encoding="ascii", errors="replace") as f:
            lines = [ln for ln in f.read(65536).splitlines()
                     if ln.startswith(("model name", "flags", "Features", "CPU part"))]
        return "\n".join(sorted(set(lines)))
    except OSError:
        return platform.processor()


def _numba_version() -> bytes:
    """The installed numba and llvmlite versions, read without importing them."""
    out = b""
    for name in ("numba", "llvmlite"):
        spec = importlib.util.find_spec(name)
        if spec is None or spec.origin is None:
            return b"missing"
        version = Path(spec.origin).parent / "_version.py"
        out += version.read_bytes() if version.exists() else spec.origin.encode()
    return out


def tag() -> str:
    """A hash of everything the built module depends on (see the module docstring)."""
    import numpy as np

    h = hashlib.sha256()
    for path in sorted(PACKAGE.rglob("*.py")):
        text = path.read_bytes()
        if b"njit" in text or path.name == "aot_signatures.py":
            h.update(str(path.relative_to(PACKAGE)).encode() + b"\0" + text + b"\0")
    for part in (sys.version, np.__version__, platform.machine(), _cpu()):
        h.update(part.encode() + b"\0")
    h.update(_numba_version())
    return h.hexdigest()[:16]


def module_name(tag_: str) -> str:
    return f"sensorplan_aot_{tag_}"


def places() -> list[Path]:
    """The directories a built module may live in, in order of preference: numba's cache
    places, then this user's private directory under the temporary one, if it is private
    (anyone can make a directory of that name in ``/tmp``; a module found there is run)."""
    out = [Path(p) / SUBDIR for p in cache_places()]
    tmp = private_path(tempfile.gettempdir())
    if is_private(tmp):
        out.append(Path(tmp) / SUBDIR)
    return out


def _suffix() -> str:
    return sysconfig.get_config_var("EXT_SUFFIX") or importlib.machinery.EXTENSION_SUFFIXES[0]


def find(tag_: str | None = None) -> Path | None:
    """The built module of this code and machine, or None."""
    name = module_name(tag_ or tag()) + _suffix()
    for d in places():
        if (d / name).is_file():
            return d / name
    return None


def failed_marker(d: Path, tag_: str) -> Path:
    return d / f"failed-{tag_}.txt"


def _failed(tag_: str) -> bool:
    return any(failed_marker(d, tag_).is_file() for d in places())


def load() -> Any | None:
    """Import the built module (None when there is none, or ahead-of-time kernels are off)."""
    if not enabled():
        return None
    tag_ = tag()
    path = find(tag_)
    if path is None:
        return None
    name = module_name(tag_)
    if name in sys.modules:
        return sys.modules[name]
    try:
        spec = importlib.util.spec_from_file_location(name, path)
        assert spec is not None and spec.loader is not None
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
    except (ImportError, OSError, AssertionError):
        return None                          # a damaged file: numba's kernels do the work
    sys.modules[name] = module
    try:
        if time.time() - path.stat().st_mtime > DAY:
            os.utime(path)                   # in use: see prune()
    except OSError:
        pass
    return module


def prune(dest: Path, keep: Path, now: float | None = None) -> list[Path]:
    """Delete the built modules (and failure notes) in ``dest`` not used for
    :data:`UNUSED_DAYS` days, except ``keep``: each edit of a kernel or upgrade builds a
    new module, and the old ones would pile up (about 1 MB each); and the temporary
    directories of builds killed outright, a day old.

    Returns
    -------
    the files deleted
    """
    now = time.time() if now is None else now
    gone = []
    for d in dest.glob("tmp*"):
        # A build killed outright (SIGKILL, a power cut) left its directory: no build
        # runs for a day.
        try:
            if d.is_dir() and now - d.stat().st_mtime > DAY:
                shutil.rmtree(d)
                gone.append(d)
        except OSError:
            pass
    for f in [*dest.glob(f"{module_name('*')}{_suffix()}"), *dest.glob("failed-*.txt")]:
        try:
            if f != keep and now - f.stat().st_mtime > UNUSED_DAYS * DAY:
                f.unlink()
                gone.append(f)
        except OSError:
            pass
    return gone


def attach(kernels: list[Any]) -> None:
    """Give every kernel (:class:`sensorplan._compiled.jit.Kernel`) its ahead-of-time table
    (``{arg_key: function}``), or None."""
    from .aot_signatures import SIGNATURES

    module = load()
    tables: dict[tuple[str, str], dict] = {}
    if module is not None:
        for n, (mod, fname, key) in enumerate(SIGNATURES):
            fn = getattr(module, f"k{n}", None)
            if fn is not None:
                tables.setdefault((mod, fname), {})[key] = fn
    for kernel in kernels:
        table = tables.get((kernel.__module__, kernel.__name__))
        if kernel._aot is not None:           # not already given numba's dispatcher
            kernel._aot = table or None


# ------------------------------------------------------------------ building


def _numba_type(item: Any) -> Any:
    from numba import types

    scalars = {"b": types.boolean, "i": types.int64, "f": types.float64}
    if isinstance(item, str):
        return scalars[item]
    dtypes = {"d": types.float64, "l": types.int64, "q": types.int64, "?": types.boolean}
    return types.Array(dtypes[item[0]], item[1], "C", readonly=len(item) > 2)


def build(dest: Path | None = None) -> Path:
    """Compile the listed kernels into the extension module of this code and machine.

    Returns
    -------
    Path   the module's file (written atomically: a concurrent build wins or loses whole)
    """
    import importlib

    import llvmlite.binding as llvm
    import numba.pycc.compiler as pycc_compiler
    from numba.core.codegen import AOTCPUCodegen
    from numba.pycc import CC

    from .aot_signatures import SIGNATURES

    if "numba" not in sys.modules:
        raise RuntimeError("build() runs after sensorplan._compiled.jit.activate() (see BUILD)")
    tag_ = tag()
    if dest is None:
        dest = next(d for d in places() if _writable(str(d)))
    dest.mkdir(parents=True, exist_ok=True)
    kernels = {}
    for mod, fname, _ in SIGNATURES:
        kernel = getattr(importlib.import_module(mod), fname)
        kernels[(mod, fname)] = kernel
    # pycc compiles every exported function with one set of default flags; the kernels' own
    # numba options (numpy's error model for the radar's, releasing the GIL for those run on
    # threads) must hold as under numba's jit, each kernel its own.
    options = {k.py_func: k.targetoptions for k in kernels.values()}
    original = pycc_compiler.compile_extra

    def compile_extra(typing_ctx: Any, target_ctx: Any, func: Any, args: Any, return_type: Any,
                      flags: Any, locals: Any, library: Any = None, **kw: Any) -> Any:
        opts = options.get(func, {})
        flags.error_model = opts.get("error_model", "python")
        flags.release_gil = bool(opts.get("nogil", False))
        if opts.get("fastmath"):
            raise ValueError(f"{func.__name__}: fastmath kernels are not built ahead of time")
        return original(typing_ctx, target_ctx, func, args, return_type, flags,
                        locals=locals, library=library, **kw)

    # pycc gives LLVM the CPU's name only, and LLVM then assumes every feature of that
    # model; numba's jit passes the features this CPU reports (a virtual machine may mask
    # some). Use the latter: code that runs here, the same code numba's jit makes.
    original_features = AOTCPUCodegen._customize_tm_features
    with tempfile.TemporaryDirectory(dir=dest) as work:
        cc = CC(module_name(tag_))
        cc.output_dir = work
        cc.target_cpu = llvm.get_host_cpu_name()
        for n, (mod, fname, key) in enumerate(SIGNATURES):
            args = tuple(_numba_type(item) for item in key)
            cc.export(f"k{n}", args)(kernels[(mod, fname)].py_func)
        setattr(pycc_compiler, "compile_extra", compile_extra)  # noqa: B010 - untyped
        setattr(AOTCPUCodegen, "_customize_tm_features",  # noqa: B010
                lambda self: self._get_host_cpu_features())
        try:
            cc.compile()
        finally:
            setattr(pycc_compiler, "compile_extra", original)  # noqa: B010
            setattr(AOTCPUCodegen, "_customize_tm_features", original_features)  # noqa: B010
        built = Path(work) / (module_name(tag_) + _suffix())
        target = dest / built.name
        os.replace(built, target)
    prune(dest, target)
    return target


def pycc_missing() -> str | None:
    """Why ``numba.pycc`` cannot be used (None when it can): numba lists it under its
    deprecation notices, and a numba without it gets numba's kernels only."""
    import warnings

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")         # its pending-deprecation warning
            import numba.pycc  # noqa: F401
    except ImportError as exc:
        return f"this numba has no numba.pycc: {exc}" if str(exc) else "no numba.pycc"
    return None


def forget_failure(tag_: str) -> None:
    """Delete the notes of earlier failed builds of ``tag_`` (an explicit build tries again)."""
    for d in places():
        try:
            failed_marker(d, tag_).unlink(missing_ok=True)
        except OSError:
            pass


def _destination() -> Path | None:
    dest = next((d for d in places() if _writable(str(d))), None)
    if dest is None:
        fallback = _private_dir(tempfile.gettempdir())
        if fallback is None:
            return None
        dest = Path(fallback) / SUBDIR
    return dest


def _clean(dest: Path, keep: set[Path]) -> None:
    """Delete the temporary build directories in ``dest`` but those in ``keep`` (there
    before the interrupted build started: another process's)."""
    for leftover in set(dest.glob("tmp*")) - keep:
        shutil.rmtree(leftover, ignore_errors=True)


def build_in_child() -> tuple[Path | None, str]:
    """Build the module in a child process (:data:`BUILD`), atomically.

    Returns
    -------
    (module, error) : the module's file, or None and the last line of the child's output
    (then remembered in :func:`failed_marker`: later plans do not try again)

    An interruption (Ctrl-C, SIGTERM) ends the child and deletes its half-built files
    before it goes on.
    """
    tag_ = tag()
    dest = _destination()
    if dest is None:
        return None, "no writable directory"
    env = {**os.environ, "SENSORPLAN_FIRST_RUN_NOTED": "1"}
    others = set(dest.glob("tmp*"))
    try:
        done = subprocess.run([sys.executable, "-c", BUILD, str(PACKAGE.parent), str(dest)],
                              env=env, capture_output=True, text=True, check=False)
    except BaseException:
        # Interrupted: the child is gone (run() kills it); so is its half-built module.
        _clean(dest, others)
        raise
    found = find(tag_)
    if done.returncode == 0 and found is not None:
        return found, ""
    last = (done.stderr.strip().splitlines() or ["no output"])[-1]
    if done.returncode < 0 or last.startswith("KeyboardInterrupt"):
        # Ctrl-C reached the child (the whole process group gets it) before this process
        # saw it: an interruption, not a failure to remember.
        _clean(dest, others)
        raise KeyboardInterrupt
    try:
        failed_marker(dest, tag_).write_text(done.stderr)
    except OSError:
        pass
    return None, f"{last}; details: {failed_marker(dest, tag_)}"


def ensure_built() -> Path | None:
    """Build the module in a child process if it is missing (saying so on stderr).

    Does nothing when ahead-of-time kernels are off, a module exists, an earlier build
    failed for this code, or nowhere is writable. Without ``numba.pycc`` it says once that
    the kernels are numba's (remembered like a failure). A failure is said in one line and
    remembered; the caller goes on with numba's kernels either way.
    ``sensorplan compile`` (:func:`sensorplan._compiled.prepare.compile_kernels`) does the
    same ahead of need.
    """
    if not enabled():
        return None
    try:
        tag_ = tag()
    except OSError:
        return None                          # the package's sources cannot be read
    found = find(tag_)
    if found is not None or _failed(tag_):
        return found
    missing = pycc_missing()
    if missing is not None:
        dest = _destination()
        if dest is not None:
            try:
                dest.mkdir(parents=True, exist_ok=True)
                failed_marker(dest, tag_).write_text(missing + "\n")
            except OSError:
                pass
        sys.stderr.write(f"{NOTICE}no ahead-of-time kernels ({missing}): plans use numba's "
                         "kernels from its disk cache\n")
        sys.stderr.flush()
        return None
    # 25-37 s with numba's kernels cached, 55 s from nothing (2 cores, 2026-12).
    sys.stderr.write(f"{NOTICE}first plan: compiling the planning kernels ahead of time, once "
                     "(about half a minute; `sensorplan compile` does it ahead); later plans "
                     "start in under a second\n")
    sys.stderr.flush()
    found, error = build_in_child()
    if found is None:
        sys.stderr.write(f"{NOTICE}could not compile the planning kernels ahead of time "
                         f"({error}); numba's kernels are used instead\n")
        sys.stderr.flush()
    return found
