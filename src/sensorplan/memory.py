"""The process's memory settings: numpy's huge pages and glibc's reuse of freed memory.

The command line makes both before numpy loads (:mod:`sensorplan.cli.launch`); a program that
imports the library can make the second with :func:`keep_freed_memory`.
"""

from __future__ import annotations

import os
from collections.abc import MutableMapping

from .errors import ConfigError

#: numpy's switch for transparent huge pages, read when numpy is imported.
HUGEPAGE = "NUMPY_MADVISE_HUGEPAGE"
#: glibc's environment variables for the settings :func:`malloc_defaults` changes.
MALLOC_VARS = ("MALLOC_MMAP_THRESHOLD_", "MALLOC_TRIM_THRESHOLD_")
#: mallopt's parameter numbers (glibc's malloc.h) and the command line's values: blocks up to
#: glibc's largest threshold (32 MiB) come from the heap, and up to 1 GiB of freed heap is
#: kept for reuse rather than given back to the system.
M_TRIM_THRESHOLD, M_MMAP_THRESHOLD = -1, -3
MMAP_THRESHOLD = 32 * 2**20
TRIM_THRESHOLD = 2**30
#: The same settings as glibc reads them from the environment when a process starts.
MALLOC_ENV = {"MALLOC_MMAP_THRESHOLD_": str(MMAP_THRESHOLD),
              "MALLOC_TRIM_THRESHOLD_": str(TRIM_THRESHOLD)}


def numpy_defaults(environ: MutableMapping[str, str]) -> None:
    """The command line's numpy settings, unless the user set them: no transparent huge
    pages for large arrays (``NUMPY_MADVISE_HUGEPAGE=0``).

    numpy asks the kernel for 2 MiB pages for every array of 4 MiB or more. On a virtual
    machine whose memory the host backs only when first touched, each such page stalled for
    milliseconds: a large decision's 50 MB of arrays took 0.2-0.35 s in some runs instead of
    0.01 s, with no gain in the others. Read by numpy when it is imported: set here first.

    Raises ConfigError naming the variable when the user's value is not a whole number
    (numpy would fail on import with a bare ValueError).
    """
    value = environ.setdefault(HUGEPAGE, "0")
    try:
        int(value)
    except ValueError:
        raise ConfigError(HUGEPAGE, f"must be 0 (off) or 1 (on), numpy's setting; got "
                          f"{value!r} (or unset it)") from None


def malloc_defaults(environ: MutableMapping[str, str]) -> bool:
    """The command line's memory allocator settings, unless the user set them: memory freed
    by one step of a decision is reused by the next instead of being returned to the system
    and asked for again (glibc only).

    A decision allocates and frees arrays of a few MiB hundreds of times, some on the
    planner's threads; glibc's defaults gave many of them back to the system and mapped
    them again: 14,000 page faults per decision at N = 20, about none with these settings
    (docs/benchmarks.md has the time they save). The process keeps what it once used until
    it ends. The settings are also put in ``environ`` (as ``MALLOC_MMAP_THRESHOLD_`` and
    ``MALLOC_TRIM_THRESHOLD_``) for the processes it starts. Either variable already there
    (or either setting in ``GLIBC_TUNABLES``) leaves glibc as the user set it.

    Returns
    -------
    Whether the settings were made.
    """
    tunables = environ.get("GLIBC_TUNABLES", "")
    if any(v in environ for v in MALLOC_VARS) or "_threshold" in tunables:
        return False
    try:
        if not os.confstr("CS_GNU_LIBC_VERSION"):
            return False
    except (ValueError, OSError, AttributeError):           # not glibc, or not Unix
        return False
    import ctypes

    try:
        mallopt = ctypes.CDLL(None).mallopt
    except (OSError, AttributeError):
        return False
    mallopt.argtypes = (ctypes.c_int, ctypes.c_int)
    if not (mallopt(M_MMAP_THRESHOLD, MMAP_THRESHOLD) and mallopt(M_TRIM_THRESHOLD,
                                                                  TRIM_THRESHOLD)):
        return False
    environ.update(MALLOC_ENV)        # read by the processes it starts (a study's workers)
    return True


def keep_freed_memory() -> bool:
    """Have glibc keep the memory a decision frees for the next one, as the command line does.

    For a program that imports the library and plans again and again (a sensor manager, a
    study of its own). With glibc's defaults an N = 20 decision gave arrays of a few MiB back
    to the system and mapped them again, about 14,000 page faults per decision and about 1.2x
    its time. Process-wide and lasting: blocks up to 32 MiB then come from the heap, and up to
    1 GiB of freed heap is kept, until the process ends. Nothing is changed (False) under
    another C library, or if ``MALLOC_MMAP_THRESHOLD_``, ``MALLOC_TRIM_THRESHOLD_`` or either
    threshold in ``GLIBC_TUNABLES`` is set: the user's settings stay. The environment is left
    as it is (the command line also puts the settings there for the processes it starts).

    Returns
    -------
    Whether the settings were made.
    """
    return malloc_defaults(dict(os.environ))
