"""The kernels made ready ahead of need: ``sensorplan compile``, and the warm-up before a
run's first timed decision.

* :func:`compile_kernels` (``sensorplan compile``, run by ``make`` after installing): fills
  numba's on-disk cache with the listed kernels (:mod:`sensorplan._compiled.aot_signatures`)
  and builds the ahead-of-time module (:mod:`sensorplan._compiled.aot`) when ``numba.pycc``
  is there. Without ``numba.pycc`` (numba lists it under its deprecation notices; a future
  numba may not ship it) numba's cache is the build: the kernels are numba's, loaded from
  the disk cache (a plan then starts in about 1.5 s instead of 0.4 s). A second call with
  everything current does nothing and says so.
* :func:`warm_listed`: numba loaded and every listed kernel compiled (or loaded from the
  disk cache) for every listed argument type, once per process. The planners call it
  before starting their clock in a process that runs numba's kernels, so that no decision
  counts loading or compiling a kernel.
* :func:`warm_for_runs`: what a process that runs closed loops calls before its first
  timed decision (a study's worker before its first task): the tracker needs numba anyway,
  so numba's kernels are loaded now, not between two decisions.
"""

from __future__ import annotations

import importlib
import os
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

_WARM = False
_LOCK = threading.Lock()


def _stderr(line: str) -> None:
    sys.stderr.write(line + "\n")
    sys.stderr.flush()


def warm_listed() -> tuple[int, int]:
    """Load numba and give each listed kernel its compiled version for each listed argument
    type (:data:`~sensorplan._compiled.aot_signatures.SIGNATURES`), from numba's disk cache
    or compiled (and then cached); once per process.

    Returns
    -------
    (loaded, compiled) : versions found in the disk cache, and compiled because they were
    not (both 0 when this process did it before)
    """
    global _WARM
    if _WARM:
        return 0, 0
    with _LOCK:
        if _WARM:
            return 0, 0
        from .aot import _numba_type
        from .aot_signatures import SIGNATURES
        from .jit import Kernel, activate

        for mod, _, _ in SIGNATURES:
            importlib.import_module(mod)
        activate()
        hits = misses = 0
        for mod, fname, key in SIGNATURES:
            # The module holds numba's dispatcher now (activate() swapped it in), or still
            # the kernel if it was not patched.
            dispatcher = getattr(sys.modules[mod], fname)
            if isinstance(dispatcher, Kernel):
                dispatcher = dispatcher._dispatcher
            sig = tuple(_numba_type(item) for item in key)
            if sig in dispatcher.overloads:
                hits += 1                       # loaded by this process already
                continue
            before = sum(dispatcher.stats.cache_misses.values())
            dispatcher.compile(sig)
            if sum(dispatcher.stats.cache_misses.values()) > before:
                misses += 1
            else:
                hits += 1
        _WARM = True
        return hits, misses


def warm_for_runs() -> None:
    """Make this process's kernels what they will be for a whole closed-loop run, before its
    first timed decision: numba loaded (the tracker's kernels are numba's only, so a run
    loads it at its first step anyway; once loaded it runs every kernel) and every listed
    planning kernel compiled or loaded (:func:`warm_listed`). Idempotent and cheap after
    the first call.

    Without it, a process that found the ahead-of-time module planned its first decision
    with it, loaded numba at the tracker's first step, and its second decision waited for
    numba's cached kernels (0.05-0.5 s against a few ms).
    """
    warm_listed()


def before_workers() -> None:
    """Before starting worker processes that each load numba's kernels (a study's pool):
    the "first run" note is said here, once, and the workers stay quiet (they inherit
    ``SENSORPLAN_FIRST_RUN_NOTED``); when numba's cache holds no kernel of this package,
    the listed kernels are compiled here, once, and the workers load them instead of each
    compiling them at the same time. When numba's usual cache places cannot be written,
    the private one is chosen (and said) here, for the same reasons.
    """
    from .cache import _writable, cache_places, first_run_notice

    if first_run_notice() is not None or not any(_writable(p) for p in cache_places()):
        warm_listed()


# ------------------------------------------------------------------ sensorplan compile


@dataclass(frozen=True)
class Compiled:
    """What :func:`compile_kernels` did.

    Attributes
    ----------
    cached, compiled : int     listed kernel versions found in numba's disk cache / compiled
    module : Path or None      the ahead-of-time module (None: none is used, see ``why_not``)
    built : bool               whether this call built the module (False: it was current)
    why_not : str              why there is no ahead-of-time module ("" when there is)
    seconds : float            wall time of the call
    """

    cached: int
    compiled: int
    module: Path | None
    built: bool
    why_not: str
    seconds: float

    @property
    def did_nothing(self) -> bool:
        """Everything was current: nothing was compiled or built."""
        return self.compiled == 0 and not self.built


def compile_kernels(say: Callable[[str], None] = _stderr) -> Compiled:
    """Compile every listed kernel into numba's disk cache and build the ahead-of-time
    module of this code and machine, unless they are current (``sensorplan compile``).

    Each step is said in one line (``say``, stderr by default). Both results are written
    atomically: numba writes each cache file under a temporary name and renames it, and the
    module is built in a temporary directory beside its place and renamed into it, so an
    interrupted call leaves complete files or none (the next call does the rest).

    Returns
    -------
    Compiled
    """
    from . import aot
    from .cache import NOTICE

    start = time.perf_counter()
    # The ahead-of-time build of this call says its own note; a command's "first run" note
    # would repeat it.
    os.environ.setdefault("SENSORPLAN_FIRST_RUN_NOTED", "1")
    say(f"{NOTICE}compile: numba's kernels (disk cache)...")
    t0 = time.perf_counter()
    cached, compiled = warm_listed()
    say(f"{NOTICE}compile: numba's kernels: {compiled} compiled, {cached} already cached "
        f"({time.perf_counter() - t0:.0f} s)")
    module, built, why_not = None, False, ""
    if not aot.enabled():
        why_not = "SENSORPLAN_AOT=0"
    elif (missing := aot.pycc_missing()) is not None:
        why_not = missing
    else:
        tag = aot.tag()
        module = aot.find(tag)
        if module is None:
            aot.forget_failure(tag)           # asked for explicitly: try again
            say(f"{NOTICE}compile: the ahead-of-time module (about half a minute)...")
            t0 = time.perf_counter()
            module, error = aot.build_in_child()
            if module is None:
                why_not = f"the build failed ({error})"
            else:
                built = True
                say(f"{NOTICE}compile: built {module} ({time.perf_counter() - t0:.0f} s)")
    if why_not:
        say(f"{NOTICE}compile: no ahead-of-time module ({why_not}): the kernels are numba's, "
            "from its disk cache (a plan starts in about 1.5 s instead of 0.4 s)")
    result = Compiled(cached, compiled, module, built, why_not, time.perf_counter() - start)
    if result.did_nothing:
        say(f"{NOTICE}compile: everything is current"
            + (f" ({module})" if module is not None else "") + "; nothing to do")
    return result


def status_line(result: Compiled) -> str:
    """One line on what :func:`compile_kernels` left in place."""
    if result.module is not None:
        return f"compiled kernels: {result.module} and numba's disk cache"
    return f"compiled kernels: numba's disk cache ({result.why_not})"


__all__ = ["Compiled", "before_workers", "compile_kernels", "status_line", "warm_for_runs",
           "warm_listed"]
